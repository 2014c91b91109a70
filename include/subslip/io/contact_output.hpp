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
#include "subslip/io/run_size.hpp"

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
// A group left by an earlier (killed) run under the same name is replaced.
class ContactCaseWriter {
 public:
  // Creates the case's group with everything the run will write into (the layout, before any
  // computation): attributes, summary placeholders, the series with the rows the case's
  // increments give reserved.
  static void lay_out(const h5::Group& cases, const ContactCase& c, int index, const Units& units);
  // The group lay_out made, written from row 0 (a case that starts, or starts again after a
  // kill: contact cases take milliseconds).
  ContactCaseWriter(const h5::Group& cases, const ContactCase& c, int index, const Units& units,
                    h5::CaseProgress& progress);
  // One row in every dataset (no heap allocation on our side).
  void append(const contact::ContactState& s, int segment);
  // Writes the rows gathered so far and then their number to /progress.
  void commit();
  // Commits and writes the summary attributes (in place).
  void finish(const ContactSummary& summary);
  // finish(), and records why the case stopped in the reserved `failed` attribute.
  void mark_failed(const ContactSummary& summary, const std::string& why);
  const SummaryTracker& tracker() const { return tracker_; }

 private:
  void close_series();

  h5::Group group_;
  Units units_;
  h5::CaseProgress& progress_;
  std::size_t index_;
  std::array<std::optional<h5::Series>, kAllContactFields.size()> series_;
  SummaryTracker tracker_;
};

struct ContactCaseResult {
  std::string name;
  ContactSummary summary;
  std::string failure;  // non-empty when the case stopped on a contact::StepFailure
};

struct ContactRunOptions {
  int threads = 0;  // cases run in parallel on this many threads (0: OpenMP's default)
  // Rows are committed after every output step unless that costs more than ~5 % (WritePacer);
  // never more often than this.
  std::chrono::duration<double> flush_interval{0.0};
  double write_cost_ratio = h5::WritePacer::kCostRatio;  // 0: every output step (benchmarks)
  // Continue the run whose file this is (header, /cases and /progress exist): cases marked
  // completed or failed are kept, every other case is run again from its start.
  bool restart = false;
  // Called once the file holds its whole layout (not on a restart): the
  // command line writes to a temporary name and renames it here, so that the result path never
  // names a file that is not a readable result file.
  std::function<void()> on_header_written;
  // Called (serially, in case order) as each case is written or found done.
  std::function<void(std::size_t index, const ContactCase&, const ContactCaseResult&)> on_case_done;
};

// Writes the result header and runs every case into /cases; the file stays a working file
// (completed = 0, rows reserved), which the caller closes and, when every case ended, finishes
// (io/result_file.hpp, finish_result). One thread streams each output step to the file;
// several threads compute cases in memory and write them in case order, so the file's data do
// not depend on the thread count. /progress records each case's valid rows and state as the
// run goes. A case that fails numerically (contact::StepFailure) keeps the rows it reached,
// writes its `failed` attribute and gets a result with `failure` set; the other cases still
// run (the finished file then says completed = 0). Other errors (HDF5) are thrown.
// The result size of the scene's layout (adaptive cases: their planned rows).
RunSize estimate_contact_run(const ContactScene& scene);

std::vector<ContactCaseResult> run_contact_scene(const ContactScene& scene, h5::File& file,
                                                 const ContactRunOptions& options = {});

}  // namespace subslip::io
