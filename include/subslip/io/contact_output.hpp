// Running a contact scene into a result file (layout in docs/scenes.md, "Output"):
//
//   /                  format, format_version, program_version, scene_kind = "contact", ...
//   /scene             the scene YAML, verbatim
//   /units             attributes stress, length, time
//   /cases/<name>/     one group per case: the requested time series, and attributes for the
//                      swept values, the resolved parameters (each with a sibling "<name>.unit")
//                      and the summary (peak_ratio, bottom_ratio, ...)
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "subslip/contact/contact_point.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/h5_writer.hpp"

namespace subslip::io {

struct ContactSummary {
  static constexpr double kNone = std::numeric_limits<double>::quiet_NaN();
  double peak_ratio = kNone;    // max f_t/f_n over the output states
  double slip_at_peak = kNone;  // slip_path at that state
  double bottom_ratio = kNone;  // min f_t/f_n after the peak (NaN when the peak is the last state)
  double final_ratio = kNone;
  double steady_ratio_analytical = kNone;  // steady state at the last sliding segment's speed
  double steady_speed = 0.0;               // that speed
  contact::RunStats stats;
};

// Peak, bottom and final ratio, updated state by state without storing the history.
class SummaryTracker {
 public:
  void add(const contact::ContactState& s);
  // Completes the summary with the run's statistics and the analytical steady state.
  ContactSummary result(const ContactCase& c, const contact::RunStats& stats) const;

 private:
  double peak_ = -1.0, slip_at_peak_ = ContactSummary::kNone;
  double bottom_ = ContactSummary::kNone, final_ = ContactSummary::kNone;
};

// The steady f_t/f_n of the case's law at the last sliding segment's speed (NaN if none slides).
double steady_ratio_analytical(const ContactCase& c);

// One /cases/<name> group: datasets for the requested fields and the case's attributes.
class ContactCaseWriter {
 public:
  ContactCaseWriter(const h5::Group& cases, const ContactCase& c, int index, const Units& units);
  // One row in every dataset (no heap allocation on our side).
  void append(const contact::ContactState& s, int segment);
  // Writes the rows gathered so far (call before File::flush()).
  void commit();
  // Commits, and writes the summary attributes.
  void finish(const ContactSummary& summary);
  // Commits, and records why the case stopped.
  void mark_failed(const std::string& why);
  const SummaryTracker& tracker() const { return tracker_; }

 private:
  h5::Group group_;
  Units units_;
  std::array<std::optional<h5::Series>, kAllContactFields.size()> series_;
  SummaryTracker tracker_;
};

struct ContactRunOptions {
  int threads = 0;  // cases run in parallel on this many threads (0: OpenMP's default)
  // Flush at most this often while streaming (0: after every output step).
  std::chrono::duration<double> flush_interval{0.25};
  // Called (serially, in case order) as each case is written.
  std::function<void(std::size_t index, const ContactCase&, const ContactSummary&)> on_case_done;
};

struct ContactCaseResult {
  std::string name;
  ContactSummary summary;
  std::string failure;  // non-empty when the case stopped on a contact::StepFailure
};

// Writes the result header, runs every case into /cases and, when all succeeded, sets
// completed = 1. One thread streams each output step to the file; several threads compute
// cases in memory and write them in case order, so the file's data do not depend on the thread
// count. A case that fails numerically (contact::StepFailure) keeps the rows it reached, gets a
// `failed` attribute and a result with `failure` set; the other cases still run, and the file
// then stays completed = 0. Other errors (HDF5) are thrown.
std::vector<ContactCaseResult> run_contact_scene(const ContactScene& scene, h5::File& file,
                                                 const ContactRunOptions& options = {});

}  // namespace subslip::io
