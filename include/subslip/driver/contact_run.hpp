// How a contact scene runs: its cases from their start (a restart keeps the ones an earlier
// session ended and runs the others again: they take milliseconds), streamed to the sink as
// computed on one thread, or computed in parallel in memory and handed over in case order, so
// that the sink sees the same states in the same order whatever the thread count. No file is
// touched here: the sink (driver/contact_sink.hpp) does that.
#pragma once

#include <cstddef>
#include <functional>
#include <vector>

#include "subslip/driver/contact_sink.hpp"
#include "subslip/history/contact_history.hpp"
#include "subslip/model/contact_case.hpp"
#include "subslip/parallel/team.hpp"

namespace subslip::driver {

// Peak, bottom and final ratio, updated state by state without storing the history.
class SummaryTracker {
 public:
  void add(const contact::ContactState& s);
  // Completes the summary with the run's statistics and the analytical steady state.
  ContactSummary result(const model::ContactCase& c, const history::RunStats& stats) const;

 private:
  double peak_ = -1.0, slip_at_peak_ = ContactSummary::kNone;
  double bottom_ = ContactSummary::kNone, final_ = ContactSummary::kNone;
};

// The steady f_t/f_n of the case's law at the last sliding segment's speed (NaN if none slides).
double steady_ratio_analytical(const model::ContactCase& c);

struct ContactRunOptions {
  int threads = 0;  // cases run in parallel on this many threads (0: OpenMP's default)
  // Called (serially, in case order) as each case is written or found ended.
  std::function<void(std::size_t index, const model::ContactCase&, const ContactCaseResult&)>
      on_case_done;
};

// Runs the cases of `scene` into `sink`. A case that fails numerically (history::StepFailure)
// keeps the states it reached, is ended with fail_case and gets a result with `failure` set;
// the other cases still run. Other errors (the sink's) are thrown.
std::vector<ContactCaseResult> run_contact_scene(const model::ContactScene& scene,
                                                 ContactSink& sink,
                                                 const ContactRunOptions& options = {});

// The cases of `scene` over the ranks of `team` (every rank calls it; `root_sink`: the result
// file's sink on the root, null elsewhere): round by round each rank computes `threads` cases
// with its threads (options.threads, or OpenMP's), and the root writes the round's cases in case
// order, so the file is the serial run's. Results on every rank (the summaries on the root).
std::vector<ContactCaseResult> run_contact_scene_on_team(const model::ContactScene& scene,
                                                         const parallel::Team& team,
                                                         ContactSink* root_sink,
                                                         const ContactRunOptions& options = {});

}  // namespace subslip::driver
