// The result file of a contact run (layout in docs/scenes.md, "Output"):
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
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "subslip/contact/contact_point.hpp"
#include "subslip/driver/contact_sink.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/result_protocol.hpp"
#include "subslip/io/run_size.hpp"

namespace subslip::io {

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
  void finish(const driver::ContactSummary& summary);
  // finish(), and records why the case stopped in the reserved `failed` attribute.
  void mark_failed(const driver::ContactSummary& summary, const std::string& why);

 private:
  void close_series();

  h5::Group group_;
  Units units_;
  h5::CaseProgress& progress_;
  std::size_t index_;
  std::array<std::optional<h5::Series>, kAllContactFields.size()> series_;
};

struct ContactSinkOptions {
  // Rows are committed after every output step unless that costs more than ~5 % (WritePacer);
  // never more often than this.
  std::chrono::duration<double> flush_interval{0.0};
  double write_cost_ratio = h5::WritePacer::kCostRatio;  // 0: every output step (benchmarks)
  // Continue the run whose file this is (header, /cases and /progress exist) instead of laying
  // out a new one.
  bool restart = false;
};

// The groups a contact run writes into, laid out or reopened by ContactResultSink.
struct ContactRunFiles {
  h5::Group cases;
  h5::CaseProgress progress;
};

// The result file of a contact run, as the driver's sink (driver/contact_sink.hpp). States
// handed over one by one are streamed (committed as WritePacer says); a case handed over whole
// is written at once. /progress records each case's valid rows and state as the run goes. The
// file stays a working file (completed = 0, rows reserved), which the caller closes and, when
// every case ended, finishes (io/result_file.hpp, finish_result). Errors (HDF5) are thrown.
class ContactResultSink final : public driver::ContactSink {
 public:
  // A new run: writes the result header and the whole layout before anything is computed; the
  // file then says layout_complete. A restart: marks the file running.
  ContactResultSink(const ContactScene& scene, h5::File& file, const ContactSinkOptions& options);
  ContactResultSink(const ContactResultSink&) = delete;  // the case writer refers to run_
  ContactResultSink& operator=(const ContactResultSink&) = delete;

  driver::CaseStatus status(std::size_t index) const override;
  driver::StoredContactCase stored_case(std::size_t index) const override;
  void begin_case(std::size_t index) override;
  void write_state(const contact::ContactState& state, int segment) override;
  void write_states(std::span<const driver::ContactRow> rows) override;
  void complete_case(const driver::ContactSummary& summary) override;
  void fail_case(const driver::ContactSummary& summary, const std::string& why) override;

 private:
  void end_case(h5::CaseState state);

  const ContactScene& scene_;
  h5::File& file_;
  ContactSinkOptions options_;
  ContactRunFiles run_;
  // The running case.
  std::size_t index_ = 0;
  std::optional<ContactCaseWriter> writer_;
  std::optional<h5::WritePacer> pacer_;
};

// The result size of the scene's layout (adaptive cases: their planned rows).
RunSize estimate_contact_run(const ContactScene& scene);

}  // namespace subslip::io
