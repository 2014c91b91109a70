#include "subslip/driver/contact_run.hpp"

#include <omp.h>

#include <exception>
#include <optional>
#include <string>
#include <utility>

namespace subslip::driver {

// ---------------------------------------------------------------- summary

void SummaryTracker::add(const contact::ContactState& s) {
  const double ratio = s.traction_ratio();
  if (ratio > peak_) {
    peak_ = ratio;
    slip_at_peak_ = s.slip_path;
    bottom_ = ContactSummary::kNone;  // the bottom is looked for after the peak only
  } else if (!(ratio >= bottom_)) {   // also true while bottom_ is NaN
    bottom_ = ratio;
  }
  final_ = ratio;
}

ContactSummary SummaryTracker::result(const io::ContactCase& c,
                                      const contact::RunStats& stats) const {
  ContactSummary out;
  if (peak_ >= 0.0) {
    out.peak_ratio = peak_;
    out.slip_at_peak = slip_at_peak_;
  }
  out.bottom_ratio = bottom_;
  out.final_ratio = final_;
  out.steady_speed = io::last_sliding_speed(c.segments);
  out.steady_ratio_analytical = steady_ratio_analytical(c);
  out.stats = stats;
  return out;
}

double steady_ratio_analytical(const io::ContactCase& c) {
  const double v = io::last_sliding_speed(c.segments);
  if (!(v > 0.0)) return ContactSummary::kNone;
  return law::SubloadingFrictionLaw(c.model.law).steady_state(v).ratio;
}

// ---------------------------------------------------------------- the two ways of running cases

namespace {

struct Recording {
  std::vector<ContactRow> rows;
  contact::RunStats stats;
  std::string failure;       // a numerical failure (why): recorded, the case is written as failed
  std::exception_ptr error;  // anything else: rethrown when the case is written
};

// What a result says of a failed case; its sink stores only `why` (in the case's own group), as
// a crystal sink does, so that a restart that reads it back names the case once.
std::string case_failure(const io::ContactCase& c, const std::string& why) {
  return "case '" + c.name + "': " + why;
}

struct RunContext {
  const io::ContactScene& scene;
  ContactSink& sink;
  const ContactRunOptions& options;
};

// Ends a case that ran to its end (or failed for `why`).
ContactCaseResult close_case(RunContext& run, std::size_t index, const SummaryTracker& tracker,
                             const contact::RunStats& stats, const std::string& why) {
  const io::ContactCase& c = run.scene.cases[index];
  ContactCaseResult result{c.name, tracker.result(c, stats), {}};
  if (why.empty()) {
    run.sink.complete_case(result.summary);
  } else {
    result.failure = case_failure(c, why);
    run.sink.fail_case(result.summary, why);
  }
  return result;
}

// Streams one case: every output state goes to the sink as it is computed.
ContactCaseResult stream_case(RunContext& run, std::size_t index) {
  const io::ContactCase& c = run.scene.cases[index];
  run.sink.begin_case(index);
  SummaryTracker tracker;
  contact::RunStats stats;
  std::string failure;
  try {
    stats = contact::run_history(c.model, c.segments, c.integrator,
                                 [&](const contact::ContactState& s, int segment) {
                                   tracker.add(s);
                                   run.sink.write_state(s, segment);
                                 });
  } catch (const contact::StepFailure& e) {
    failure = e.what();
    stats = {};
  }
  return close_case(run, index, tracker, stats, failure);
}

Recording record_case(const io::ContactCase& c) {
  Recording rec;
  rec.rows.reserve(io::output_count(c.segments));
  try {
    rec.stats = contact::run_history(c.model, c.segments, c.integrator,
                                     [&](const contact::ContactState& s, int segment) {
                                       rec.rows.push_back({s, segment});
                                     });
  } catch (const contact::StepFailure& e) {
    rec.failure = e.what();
  } catch (...) {
    // Exceptions must not leave an OpenMP region; the writer rethrows it in case order.
    rec.error = std::current_exception();
  }
  return rec;
}

ContactCaseResult write_recorded(RunContext& run, std::size_t index, const Recording& rec) {
  if (rec.error) std::rethrow_exception(rec.error);
  run.sink.begin_case(index);
  SummaryTracker tracker;
  for (const auto& row : rec.rows) tracker.add(row.state);
  run.sink.write_states(rec.rows);
  return close_case(run, index, tracker, rec.stats, rec.failure);
}

void report_done(const RunContext& run, std::size_t index, const ContactCaseResult& result) {
  if (run.options.on_case_done) run.options.on_case_done(index, run.scene.cases[index], result);
}

void run_serial(RunContext& run, const std::vector<std::size_t>& todo,
                std::vector<ContactCaseResult>& results) {
  for (std::size_t k : todo) {
    results[k] = stream_case(run, k);
    report_done(run, k, results[k]);
  }
}

// Cases are computed in parallel and handed to the sink by whichever thread completes the next
// case in order, so the sink sees exactly what a serial run gives it. Sink calls never
// overlap: they all happen inside the one critical section.
void run_parallel(RunContext& run, const std::vector<std::size_t>& todo,
                  std::vector<ContactCaseResult>& results, int threads) {
  const std::size_t n = todo.size();
  std::vector<std::optional<Recording>> pending(n);
  std::exception_ptr write_error;
  std::size_t next = 0;
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
  for (std::size_t k = 0; k < n; ++k) {
    Recording rec = record_case(run.scene.cases[todo[k]]);
#pragma omp critical(subslip_contact_sink)
    {
      pending[k] = std::move(rec);
      try {
        while (!write_error && next < n && pending[next]) {
          const std::size_t index = todo[next];
          results[index] = write_recorded(run, index, *pending[next]);
          report_done(run, index, results[index]);
          pending[next].reset();
          ++next;
        }
      } catch (...) {
        write_error = std::current_exception();
      }
    }
  }
  if (write_error) std::rethrow_exception(write_error);
}

ContactCaseResult stored_result(const io::ContactCase& c, const StoredContactCase& stored) {
  ContactCaseResult r{c.name, stored.summary, {}};
  if (!stored.failure.empty()) r.failure = case_failure(c, stored.failure);
  return r;
}

}  // namespace

std::vector<ContactCaseResult> run_contact_scene(const io::ContactScene& scene, ContactSink& sink,
                                                 const ContactRunOptions& options) {
  RunContext run{scene, sink, options};
  std::vector<ContactCaseResult> results(scene.cases.size());
  // Cases an earlier session ended are kept (reported first, in order); the others run from
  // their start.
  std::vector<std::size_t> todo;
  for (std::size_t k = 0; k < scene.cases.size(); ++k) {
    const CaseStatus status = sink.status(k);
    if (status == CaseStatus::completed || status == CaseStatus::failed) {
      results[k] = stored_result(scene.cases[k], sink.stored_case(k));
      report_done(run, k, results[k]);
    } else {
      todo.push_back(k);
    }
  }
  const int threads = options.threads > 0 ? options.threads : omp_get_max_threads();
  if (threads > 1 && todo.size() > 1) {
    run_parallel(run, todo, results, threads);
  } else {
    run_serial(run, todo, results);
  }
  return results;
}

}  // namespace subslip::driver
