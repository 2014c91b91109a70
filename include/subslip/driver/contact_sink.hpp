// What a contact run hands to whatever keeps its results (the HDF5 result file:
// io/contact_output.hpp). The driver (driver/contact_run.hpp) decides which cases run and in
// what order their states are handed over; a sink only stores them.
#pragma once

#include <cstddef>
#include <limits>
#include <span>
#include <string>

#include "subslip/contact/contact_point.hpp"
#include "subslip/driver/case_status.hpp"
#include "subslip/history/contact_history.hpp"

namespace subslip::driver {

struct ContactSummary {
  static constexpr double kNone = std::numeric_limits<double>::quiet_NaN();
  double peak_ratio = kNone;    // max f_t/f_n over the output states
  double slip_at_peak = kNone;  // slip_path at that state
  double bottom_ratio = kNone;  // min f_t/f_n after the peak (NaN when the peak is the last state)
  double final_ratio = kNone;
  double steady_ratio_analytical = kNone;  // steady state at the last sliding segment's speed
  double steady_speed = 0.0;               // that speed
  history::RunStats stats;
};

struct ContactCaseResult {
  std::string name;
  ContactSummary summary;
  std::string failure;  // non-empty when the case stopped on a history::StepFailure
};

// One output state of a contact case.
struct ContactRow {
  contact::ContactState state;
  int segment;  // loading segment of the state (-1: the initial state)
};

// What an earlier session stored of a case it ended.
struct StoredContactCase {
  ContactSummary summary;
  std::string failure;  // why it stopped, as fail_case stored it; empty: it completed
};

// Cases are handed over one at a time, in case order (the driver serialises them when it
// computes several at once).
class ContactSink {
 public:
  virtual ~ContactSink() = default;

  // --- what an earlier session left (a new run: every case pending, nothing stored)
  virtual CaseStatus status(std::size_t index) const = 0;
  // A case whose status is completed or failed.
  virtual StoredContactCase stored_case(std::size_t index) const = 0;

  // --- one case at a time, always from its start (a contact case takes milliseconds)
  virtual void begin_case(std::size_t index) = 0;
  // One output state as it is computed: the sink paces its writes.
  virtual void write_state(const contact::ContactState& state, int segment) = 0;
  // The states of a case computed in memory, all at once.
  virtual void write_states(std::span<const ContactRow> rows) = 0;
  // The running case ended: every state written, then its summary, then its status.
  virtual void complete_case(const ContactSummary& summary) = 0;
  virtual void fail_case(const ContactSummary& summary, const std::string& why) = 0;
};

}  // namespace subslip::driver
