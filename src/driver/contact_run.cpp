#include "subslip/driver/contact_run.hpp"

#include <omp.h>

#include <algorithm>
#include <exception>
#include <optional>
#include <stdexcept>
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

ContactSummary SummaryTracker::result(const model::ContactCase& c,
                                      const history::RunStats& stats) const {
  ContactSummary out;
  if (peak_ >= 0.0) {
    out.peak_ratio = peak_;
    out.slip_at_peak = slip_at_peak_;
  }
  out.bottom_ratio = bottom_;
  out.final_ratio = final_;
  out.steady_speed = model::last_sliding_speed(c.segments);
  out.steady_ratio_analytical = steady_ratio_analytical(c);
  out.stats = stats;
  return out;
}

double steady_ratio_analytical(const model::ContactCase& c) {
  const double v = model::last_sliding_speed(c.segments);
  if (!(v > 0.0)) return ContactSummary::kNone;
  return law::SubloadingFrictionLaw(c.model.law).steady_state(v).ratio;
}

// ---------------------------------------------------------------- the two ways of running cases

namespace {

struct Recording {
  std::vector<ContactRow> rows;
  history::RunStats stats;
  std::string failure;       // a numerical failure (why): recorded, the case is written as failed
  std::exception_ptr error;  // anything else: rethrown when the case is written
};

// What a result says of a failed case; its sink stores only `why` (in the case's own group), as
// a crystal sink does, so that a restart that reads it back names the case once.
std::string case_failure(const model::ContactCase& c, const std::string& why) {
  return "case '" + c.name + "': " + why;
}

struct RunContext {
  const model::ContactScene& scene;
  ContactSink& sink;
  const ContactRunOptions& options;
};

// Ends a case that ran to its end (or failed for `why`).
ContactCaseResult close_case(RunContext& run, std::size_t index, const SummaryTracker& tracker,
                             const history::RunStats& stats, const std::string& why) {
  const model::ContactCase& c = run.scene.cases[index];
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
  const model::ContactCase& c = run.scene.cases[index];
  run.sink.begin_case(index);
  SummaryTracker tracker;
  history::RunStats stats;
  std::string failure;
  try {
    stats = history::run_history(c.model, c.segments, c.integrator,
                                 [&](const contact::ContactState& s, int segment) {
                                   tracker.add(s);
                                   run.sink.write_state(s, segment);
                                 });
  } catch (const history::StepFailure& e) {
    failure = e.what();
    stats = {};
  }
  return close_case(run, index, tracker, stats, failure);
}

Recording record_case(const model::ContactCase& c) {
  Recording rec;
  rec.rows.reserve(model::output_count(c.segments));
  try {
    rec.stats = history::run_history(c.model, c.segments, c.integrator,
                                     [&](const contact::ContactState& s, int segment) {
                                       rec.rows.push_back({s, segment});
                                     });
  } catch (const history::StepFailure& e) {
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

ContactCaseResult stored_result(const model::ContactCase& c, const StoredContactCase& stored) {
  ContactCaseResult r{c.name, stored.summary, {}};
  if (!stored.failure.empty()) r.failure = case_failure(c, stored.failure);
  return r;
}

// ---------------------------------------------------------------- cases over MPI ranks

constexpr std::size_t kRowValues = 13;

void pack_row(const ContactRow& row, std::vector<double>& out) {
  const contact::ContactState& s = row.state;
  out.insert(out.end(), {s.time, s.slip.x(), s.slip.y(), s.slip_path, s.vp_slip, s.vp_rate,
                         s.traction_t.x(), s.traction_t.y(), s.traction_n, s.law.mu, s.law.r_s, s.r,
                         static_cast<double>(row.segment)});
}

ContactRow unpack_row(const double* v) {
  ContactRow row;
  contact::ContactState& s = row.state;
  s.time = v[0];
  s.slip = {v[1], v[2]};
  s.slip_path = v[3];
  s.vp_slip = v[4];
  s.vp_rate = v[5];
  s.traction_t = {v[6], v[7]};
  s.traction_n = v[8];
  s.law.mu = v[9];
  s.law.r_s = v[10];
  s.r = v[11];
  row.segment = static_cast<int>(v[12]);
  return row;
}

// A recording as the root receives it: the run's counters, then the rows.
std::vector<double> message_of(const Recording& rec) {
  const history::RunStats& st = rec.stats;
  std::vector<double> out{static_cast<double>(st.increments), static_cast<double>(st.substeps),
                          static_cast<double>(st.rejected),   static_cast<double>(st.iterations),
                          static_cast<double>(st.cutbacks),   st.wall_seconds};
  out.reserve(out.size() + rec.rows.size() * kRowValues);
  for (const auto& row : rec.rows) pack_row(row, out);
  return out;
}

Recording recording_of(const std::vector<double>& message, const std::string& failure) {
  Recording rec;
  history::RunStats& st = rec.stats;
  st.increments = static_cast<long>(message.at(0));
  st.substeps = static_cast<long>(message.at(1));
  st.rejected = static_cast<long>(message.at(2));
  st.iterations = static_cast<long>(message.at(3));
  st.cutbacks = static_cast<long>(message.at(4));
  st.wall_seconds = message.at(5);
  for (std::size_t at = 6; at + kRowValues <= message.size(); at += kRowValues)
    rec.rows.push_back(unpack_row(message.data() + at));
  rec.failure = failure;
  return rec;
}

std::string what_of(const std::exception_ptr& error) {
  try {
    std::rethrow_exception(error);
  } catch (const std::exception& e) {
    return e.what();
  } catch (...) {
    return "unknown error";
  }
}

// Case `index`, recorded by rank `owner` (`mine` there): the root writes it; every rank gets
// its result (the summary on the root only: the others print nothing).
ContactCaseResult write_case_of(const parallel::Team& team, ContactSink* root_sink,
                                const model::ContactScene& scene, const ContactRunOptions& options,
                                std::size_t index, int owner, const Recording* mine) {
  std::string failure, error;
  if (mine != nullptr) {
    failure = mine->failure;
    if (mine->error) error = what_of(mine->error);
  }
  team.broadcast(failure, owner);
  team.broadcast(error, owner);
  const model::ContactCase& c = scene.cases[index];
  if (!error.empty()) parallel::stop_every_rank(team, case_failure(c, error), owner);
  std::vector<double> message;
  if (mine != nullptr) {
    if (owner != 0) team.send(message_of(*mine), 0);
    if (team.is_root()) message = message_of(*mine);
  } else if (team.is_root()) {
    message = team.receive(owner);
  }
  ContactCaseResult result{c.name, {}, failure.empty() ? "" : case_failure(c, failure)};
  parallel::on_root(team, [&] {
    RunContext run{scene, *root_sink, options};
    result = write_recorded(run, index, recording_of(message, failure));
  });
  return result;
}

}  // namespace

std::vector<ContactCaseResult> run_contact_scene_on_team(const model::ContactScene& scene,
                                                         const parallel::Team& team,
                                                         ContactSink* root_sink,
                                                         const ContactRunOptions& options) {
  if (team.size() == 1) return run_contact_scene(scene, *root_sink, options);
  const std::size_t n = scene.cases.size();
  // The root's statuses and stored failures, on every rank.
  std::vector<double> status(n, 0.0);
  std::vector<ContactCaseResult> results(n);
  parallel::on_root(team, [&] {
    for (std::size_t k = 0; k < n; ++k) status[k] = static_cast<double>(root_sink->status(k));
  });
  team.broadcast(status, 0);
  std::vector<std::size_t> todo;
  for (std::size_t k = 0; k < n; ++k) {
    const auto s = static_cast<CaseStatus>(static_cast<int>(status[k]));
    if (s != CaseStatus::completed && s != CaseStatus::failed) {
      todo.push_back(k);
      continue;
    }
    parallel::on_root(
        team, [&] { results[k] = stored_result(scene.cases[k], root_sink->stored_case(k)); });
    team.broadcast(results[k].failure, 0);
    results[k].name = scene.cases[k].name;
    if (options.on_case_done) options.on_case_done(k, scene.cases[k], results[k]);
  }
  // Rounds: each rank computes `per_rank` cases with its threads, then the root writes the
  // round in case order.
  const int threads = options.threads > 0 ? options.threads : omp_get_max_threads();
  const auto per_rank = static_cast<std::size_t>(std::max(1, threads));
  const std::size_t round = per_rank * static_cast<std::size_t>(team.size());
  for (std::size_t first = 0; first < todo.size(); first += round) {
    const std::size_t last = std::min(todo.size(), first + round);
    const std::size_t mine_first = first + per_rank * static_cast<std::size_t>(team.rank());
    const std::size_t mine_count = mine_first < last ? std::min(per_rank, last - mine_first) : 0;
    std::vector<Recording> mine(mine_count);
#pragma omp parallel for schedule(dynamic, 1) num_threads(threads)
    for (std::size_t j = 0; j < mine_count; ++j)
      mine[j] = record_case(scene.cases[todo[mine_first + j]]);
    for (std::size_t i = first; i < last; ++i) {
      const int owner = static_cast<int>((i - first) / per_rank);
      const Recording* rec = owner == team.rank() ? &mine[i - mine_first] : nullptr;
      const std::size_t k = todo[i];
      results[k] = write_case_of(team, root_sink, scene, options, k, owner, rec);
      if (options.on_case_done) options.on_case_done(k, scene.cases[k], results[k]);
    }
  }
  return results;
}

std::vector<ContactCaseResult> run_contact_scene(const model::ContactScene& scene,
                                                 ContactSink& sink,
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
