#include "subslip/study/work_precision.hpp"

#include "work_precision_detail.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <utility>

#include "subslip/study/cvode_peer.hpp"

namespace subslip::study {

using namespace work_precision_detail;

namespace {

// round(n f) increments (at least 1). Graded: growth' = growth^(n / n'), which for an integer f
// puts exactly f new increments in each old one (the geometric sums nest).
template <class Segment>
void refine_segment(Segment& s, double factor, bool uniform, bool every_step) {
  const long n = s.increments;
  const long refined = std::max(1L, std::lround(static_cast<double>(n) * factor));
  if (uniform) {
    s.growth = 1.0;
  } else if (s.growth != 1.0 && refined > 1) {
    s.growth = std::pow(s.growth, static_cast<double>(n) / static_cast<double>(refined));
  }
  if (every_step) {
    s.output_every = 1;
    s.output_at_times = false;  // (output.at: the errors are measured at every step instead)
    s.output_times.clear();
  } else {
    // Keep the scene's output points: every (output_every f)-th refined increment.
    s.output_every = static_cast<int>(
        std::max(1L, std::lround(static_cast<double>(s.output_every) *
                                 static_cast<double>(refined) / static_cast<double>(n))));
  }
  s.increments = static_cast<int>(refined);
}

std::string format_setting(const Setting& s) {
  char buf[64];
  if (is_fixed_step(s.integrator)) {
    std::snprintf(buf, sizeof buf, "x%g%s", s.value, s.uniform ? " uniform" : "");
  } else {
    std::snprintf(buf, sizeof buf, "%s %.0e", std::string(setting_kind(s.integrator)).c_str(),
                  s.value);
  }
  return buf;
}

// The rows of a ladder (describe_point) come under a header naming the integrator, so that a row
// needs only the setting and fits 80 columns with the two spaces the command line puts before.
// The header's column widths are the row's. Where a problem's times are times into each
// segment (`into_segments`), the max error's time is given as "segment:time", since the time
// alone reads as an absolute one.
std::string ladder_header(Integrator integrator, bool into_segments) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "%-17s  %8s  %9s  %9s  %9s  %9s  %4s",
                std::string(to_string(integrator)).c_str(), "steps", "max error",
                into_segments ? "seg:t" : "at t", "end error", "time[s]", "runs");
  return buf;
}

std::string describe_point(const PointResult& p, bool into_segments) {
  const std::string setting = format_setting(p.setting);
  if (!p.ok) return setting + ": failed: " + p.failure;
  char at[48];
  if (into_segments && p.error.max_error_segment >= 0)
    std::snprintf(at, sizeof at, "%d:%.3g", p.error.max_error_segment, p.error.max_error_time);
  else
    std::snprintf(at, sizeof at, "%.3g", p.error.max_error_time);
  char buf[256];
  std::snprintf(buf, sizeof buf, "%-17s  %8ld  %9.3e  %9s  %9.3e  %9.4g  %4d", setting.c_str(),
                p.counters.steps, p.error.max_error, at, p.error.end_error, p.median_seconds,
                p.repeats);
  return buf;
}

void say(const StudyOptions& o, const std::string& line) {
  if (o.progress) o.progress(line);
}

// Thrown from an observer to stop a run that takes too long. Every driver calls its observer
// from C++ code between steps (CVODE's too: between CVode calls), so the exception unwinds
// through C++ frames only.
struct OverBudget {
  double time;
};
constexpr long kBudgetCheckInterval = 16;  // points between clock reads

std::string stopped_message(double time, double seconds) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "stopped at t = %.4g after %.3g s (over the run-time budget)",
                time, seconds);
  return buf;
}

}  // namespace

std::string_view to_string(Integrator integrator) {
  switch (integrator) {
    case Integrator::forward_euler:
      return "forward_euler";
    case Integrator::implicit:
      return "implicit";
    case Integrator::implicit_adaptive:
      return "implicit_adaptive";
    case Integrator::extrapolated_2:
      return "extrapolated_2";
    case Integrator::extrapolated_3:
      return "extrapolated_3";
    case Integrator::extrapolated_4:
      return "extrapolated_4";
    case Integrator::cvode:
      return "cvode";
  }
  return "?";
}

std::string_view setting_kind(Integrator integrator) {
  switch (integrator) {
    case Integrator::forward_euler:
    case Integrator::implicit:
      return "increment factor";
    case Integrator::implicit_adaptive:
    case Integrator::extrapolated_2:
    case Integrator::extrapolated_3:
    case Integrator::extrapolated_4:
      return "tolerance";
    case Integrator::cvode:
      return "rtol";
  }
  return "?";
}

int extrapolation_order(Integrator integrator) {
  switch (integrator) {
    case Integrator::extrapolated_2:
      return 2;
    case Integrator::extrapolated_3:
      return 3;
    case Integrator::extrapolated_4:
      return 4;
    default:
      return 1;
  }
}

bool is_fixed_step(Integrator integrator) {
  return integrator == Integrator::forward_euler || integrator == Integrator::implicit;
}

void Trajectory::add(double t, double v, int seg) {
  add(t, std::span<const double>(&v, 1), seg);
}

void Trajectory::add(double t, std::span<const double> v, int seg) {
  if (time.empty()) width = static_cast<int>(v.size());
  if (v.size() != static_cast<std::size_t>(width)) {
    throw std::invalid_argument("a trajectory point has " + std::to_string(v.size()) +
                                " channels, the path " + std::to_string(width));
  }
  time.push_back(t);
  value.insert(value.end(), v.begin(), v.end());
  segment.push_back(seg);
}

std::vector<double> Trajectory::headline() const {
  std::vector<double> out(size());
  for (std::size_t k = 0; k < size(); ++k) out[k] = at(k)[0];
  return out;
}

RunResult record(const Problem& problem, const Setting& setting, Report report, Trajectory& path,
                 double budget_seconds) {
  path = {};
  path.times_into_segments = problem.times_into_segments();
  const auto start = Clock::now();
  long reported = 0;
  try {
    return problem.run(setting, report, [&](double t, std::span<const double> v, int seg) {
      path.add(t, v, seg);
      if (++reported % kBudgetCheckInterval == 0 && seconds_since(start) > budget_seconds)
        throw OverBudget{t};
    });
  } catch (const OverBudget& stop) {
    RunResult r;
    r.failure = stopped_message(stop.time, seconds_since(start));
    r.seconds = seconds_since(start);
    r.last_time = stop.time;
    return r;
  }
}

std::vector<contact::Segment> refine(std::vector<contact::Segment> segments, double factor,
                                     bool uniform, bool every_step) {
  for (auto& s : segments) refine_segment(s, factor, uniform, every_step);
  return segments;
}

std::vector<crystal::LoadSegment> refine(std::vector<crystal::LoadSegment> segments, double factor,
                                         bool uniform, bool every_step) {
  for (auto& s : segments) refine_segment(s, factor, uniform, every_step);
  return segments;
}

bool cvode_available() {
  return cvode::available();
}

// ---- the study

namespace {

// The (segment, time) of every point of a run.
StopTimes stops_of(const Trajectory& run) {
  StopTimes stops;
  stops.reserve(run.size());
  for (std::size_t k = 0; k < run.size(); ++k) stops.emplace_back(run.segment[k], run.time[k]);
  return stops;
}

// Runs `run(setting)`; where an adaptive setting is refused at its error estimate's noise floor,
// runs it again at the tolerance the refusal names, as long as each refusal names a looser one
// (each names the resolution of the estimate where it stopped, so a rerun that stops again has
// met a coarser resolution further along the path). A reference is then as tight as the case
// resolves. `setting` ends as the one that ran last; `notes` gets one line per refusal.
template <class Run>
RunResult at_resolved_tolerance(Setting& setting, Run&& run, std::vector<std::string>& notes) {
  RunResult r = run(setting);
  while (!r.ok && !is_fixed_step(setting.integrator) && r.smallest_tolerance > setting.value) {
    char buf[200];
    std::snprintf(buf, sizeof buf, "reference %s %s refused at its noise floor; run at %.3g",
                  std::string(to_string(setting.integrator)).c_str(),
                  format_setting(setting).c_str(), r.smallest_tolerance);
    notes.emplace_back(buf);
    setting.value = r.smallest_tolerance;
    r = run(setting);
  }
  return r;
}

// The reference (options.reference, adaptive) and its 10x looser companion at a run's times;
// throws ReferenceFailure when either fails. A reference refused at its noise floor runs at the
// tolerance it names (at_resolved_tolerance), its companion at 10 times that.
void reference_at(const Problem& problem, const StudyOptions& options, const StopTimes& stops,
                  Trajectory& reference, Trajectory& companion, std::vector<std::string>& notes) {
  const auto run_into = [&](Trajectory& path) {
    return [&problem, &stops, &path](const Setting& setting) {
      path = {};
      path.times_into_segments = problem.times_into_segments();
      return problem.run(
          setting, Report::every_step,
          [&path](double t, std::span<const double> v, int seg) { path.add(t, v, seg); }, stops);
    };
  };
  const auto fail = [](const Setting& setting, const RunResult& r) {
    throw ReferenceFailure("the reference (" + std::string(to_string(setting.integrator)) + " " +
                           format_setting(setting) + ") at a run's times failed: " + r.failure);
  };
  Setting setting = options.reference;
  const RunResult r = at_resolved_tolerance(setting, run_into(reference), notes);
  if (!r.ok) fail(setting, r);
  const Setting looser{setting.integrator, 10.0 * setting.value};
  const RunResult c = run_into(companion)(looser);
  if (!c.ok) fail(looser, c);
}

}  // namespace

PointResult measure_point(const Problem& problem, const Setting& setting,
                          const PathInterpolant& reference, const ErrorScales& scales,
                          const StudyOptions& options) {
  PointResult p;
  p.setting = setting;
  const bool own_reference = options.reference_at_run_times && problem.supports_stops() &&
                             !is_fixed_step(options.reference.integrator);
  ErrorAccumulator error(reference, scales);
  Trajectory path;  // kept only when the run gets its own reference
  path.times_into_segments = problem.times_into_segments();
  long reported = 0;
  // A run that overruns the budget is stopped from its observer.
  const auto start = Clock::now();
  RunResult measured;
  try {
    measured =
        problem.run(setting, Report::every_step, [&](double t, std::span<const double> v, int seg) {
          own_reference ? path.add(t, v, seg) : error.add(t, v, seg);
          if (++reported % kBudgetCheckInterval == 0 &&
              seconds_since(start) > options.max_run_seconds)
            throw OverBudget{t};
        });
  } catch (const OverBudget& stop) {
    p.failure = stopped_message(stop.time, seconds_since(start));
    p.reached_time = stop.time;
    p.measured_seconds = seconds_since(start);
    p.reported_points = reported;
    p.over_budget = true;
    return p;
  }
  p.measured_seconds = measured.seconds;
  p.reported_points = reported;
  p.counters = measured.counters;
  p.ok = measured.ok;
  p.failure = measured.failure;
  p.reached_time = measured.last_time;
  if (own_reference && measured.ok) {
    Trajectory at_run, companion;
    reference_at(problem, options, stops_of(path), at_run, companion, p.reference_notes);
    const PathInterpolant exact(at_run);
    p.error = measure_error(path, exact, scales, true);
    p.reference_error = measure_error(companion, exact, scales, true).max_error;
  } else {
    p.error = error.result(measured.ok);
  }
  if (measured.ok && !std::isfinite(p.error.max_error)) {
    p.ok = false;
    p.failure = "non-finite value in the path";
  }
  if (!p.ok) return p;  // the time to failure is no result
  // The timed runs report only the scene's output points, so that the time is the
  // integrator's, not the error measurement's.
  const PointObserver nothing = [](double, std::span<const double>, int) {};
  std::vector<double> times;
  double spent = 0.0;
  do {
    const RunResult timed = problem.run(setting, Report::scene_points, nothing);
    times.push_back(timed.seconds);
    spent += timed.seconds;
  } while (static_cast<int>(times.size()) < options.repeat &&
           spent + times.front() <= options.repeat_budget_seconds);
  p.median_seconds = median(times);
  p.repeats = static_cast<int>(times.size());
  return p;
}

namespace {

// The run time of a fixed-step point at factor `next`. From a successful point: its time per
// increment times the increments planned. From a failed one (it stopped early, after costly
// cutbacks, so its rate says little): its time scaled by the factor.
double predicted_seconds(const PointResult& previous, double next, long base_increments) {
  if (!previous.ok) return previous.measured_seconds * next / previous.setting.value;
  const double per_increment =
      previous.measured_seconds / static_cast<double>(std::max(1L, previous.reported_points));
  return per_increment * static_cast<double>(base_increments) * next;
}

// Runs the reference (or one of its companions); a failure stops the study. An adaptive
// reference refused at its noise floor runs at the tolerance it names (at_resolved_tolerance):
// `setting` is then that one.
RunResult run_reference_setting(const Problem& problem, Setting& setting, Trajectory& path,
                                std::vector<std::string>& notes) {
  const RunResult r = at_resolved_tolerance(
      setting, [&](const Setting& s) { return record(problem, s, Report::every_step, path); },
      notes);
  if (!r.ok) {
    throw ReferenceFailure("the reference run (" + std::string(to_string(setting.integrator)) +
                           " " + format_setting(setting) + ") failed: " + r.failure);
  }
  return r;
}

// A fixed-step reference: the runs at R, R/2 and R/4 increment factors give the extrapolated
// path at R (from R and R/2) and its coarser companion (from R/2 and R/4).
void fixed_reference(const Problem& problem, const StudyOptions& options, ReferenceResult& ref,
                     std::optional<Trajectory>& check) {
  const double r = ref.setting.value;
  ref.run = run_reference_setting(problem, ref.setting, ref.path, ref.notes);
  ref.check = {ref.setting.integrator, 0.5 * r, ref.setting.uniform};
  Trajectory half;
  const RunResult half_run = run_reference_setting(problem, ref.check, half, ref.notes);
  if (!options.richardson) {
    check = std::move(half);
    return;
  }
  ref.extrapolated = true;
  Trajectory quarter;
  if (record(problem, {ref.setting.integrator, 0.25 * r, ref.setting.uniform}, Report::every_step,
             quarter)
          .ok) {
    check = richardson(half, quarter);
  }
  ref.path = richardson(ref.path, half);
  ref.run.seconds += half_run.seconds;
}

ReferenceResult run_reference(const Problem& problem, const StudyOptions& options) {
  ReferenceResult ref;
  ref.setting = options.reference;
  std::optional<Trajectory> check;
  if (is_fixed_step(ref.setting.integrator)) {
    fixed_reference(problem, options, ref, check);
  } else {
    ref.run = run_reference_setting(problem, ref.setting, ref.path, ref.notes);
    ref.check = {ref.setting.integrator, 10.0 * ref.setting.value};
    Trajectory looser;
    if (record(problem, ref.check, Report::every_step, looser).ok) check = std::move(looser);
  }
  ref.scales = problem.error_scales(ref.path);
  ref.scale = ref.scales.front().value;
  const PathInterpolant interpolant(ref.path);
  ref.interpolation_error = interpolant.estimated_error(ref.scales);
  if (check) ref.self_convergence = measure_error(*check, interpolant, ref.scales, true).max_error;
  if (problem.supports(Integrator::cvode)) {
    const Setting check{Integrator::cvode, options.cvode_check_rtol, false, 1.0};
    ref.cvode =
        record(problem, check, Report::every_step, ref.cvode_path, options.cvode_check_seconds);
    if (ref.cvode->ok) {
      ref.cvode_difference = measure_error(ref.cvode_path, interpolant, ref.scales, true).max_error;
    }
  }
  return ref;
}

std::string describe_reference(const Problem& problem, const ReferenceResult& ref) {
  char buf[512];
  std::snprintf(buf, sizeof buf,
                "reference: %s %s%s, %ld steps, %.3g s; self-convergence (%s) %.2e, "
                "interpolation %.2e, CVODE difference %.2e (errors relative to %s)",
                std::string(to_string(ref.setting.integrator)).c_str(),
                format_setting(ref.setting).c_str(), ref.extrapolated ? " extrapolated" : "",
                ref.run.counters.steps, ref.run.seconds, format_setting(ref.check).c_str(),
                ref.self_convergence, ref.interpolation_error, ref.cvode_difference,
                problem.error_scale_description().c_str());
  return buf;
}

}  // namespace

StudyResult run_study(const Problem& problem, const StudyOptions& options) {
  StudyResult out;
  out.quantity = problem.quantity();
  out.measured = problem.measured();
  out.scale_description = problem.error_scale_description();
  out.base_increments = problem.base_increments();
  out.reference = run_reference(problem, options);
  for (const auto& note : out.reference.notes) {
    out.notes.push_back(note);
    say(options, note);
  }
  say(options, describe_reference(problem, out.reference));
  const PathInterpolant reference(out.reference.path);
  for (const Ladder& ladder : options.ladders) {
    if (!problem.supports(ladder.integrator)) {
      out.notes.push_back(std::string(to_string(ladder.integrator)) + ": not available");
      say(options, out.notes.back());
      continue;
    }
    say(options, ladder_header(ladder.integrator, problem.times_into_segments()));
    std::vector<double> values = ladder.values;
    std::optional<std::size_t> previous;  // index into out.points
    for (std::size_t k = 0;; ++k) {
      if (k == values.size()) {
        if (!ladder.extend_until_budget || !previous) break;
        values.push_back(4.0 * values.back());
      }
      const Setting setting{ladder.integrator, values[k], ladder.uniform, ladder.atol_scale};
      if (previous) {
        const PointResult& last = out.points[*previous];
        const double expected = is_fixed_step(ladder.integrator)
                                    ? predicted_seconds(last, setting.value, out.base_increments)
                                    : last.median_seconds;
        if (expected > options.max_run_seconds) {
          char buf[160];
          std::snprintf(buf, sizeof buf, " and finer: skipped (expected %.3g s > %.3g s a run)",
                        expected, options.max_run_seconds);
          out.notes.push_back(std::string(to_string(ladder.integrator)) + " " +
                              format_setting(setting) + buf);
          say(options, out.notes.back());
          break;
        }
      }
      out.points.push_back(
          measure_point(problem, setting, reference, out.reference.scales, options));
      for (const auto& note : out.points.back().reference_notes) {
        out.notes.push_back(std::string(to_string(setting.integrator)) + " " +
                            format_setting(setting) + ": " + note);
        say(options, out.notes.back());
      }
      if (const ErrorMeasure& e = out.points.back().error; e.max_error_channel >= 0) {
        // Times into segments name their segment (the time alone is ambiguous).
        out.points.back().max_error_on = problem.channel_name(e.max_error_channel) +
                                         (problem.times_into_segments() && e.max_error_segment >= 0
                                              ? " in segment " + std::to_string(e.max_error_segment)
                                              : "");
      }
      say(options, describe_point(out.points.back(), problem.times_into_segments()));
      previous = out.points.size() - 1;
      if (out.points.back().over_budget) break;  // finer points only take longer
    }
  }
  return out;
}

double cheapest_time(const StudyResult& study, Integrator integrator, double error) {
  double best = kNaN;
  for (const auto& p : study.points) {
    if (p.setting.integrator != integrator || !p.ok || !(p.error.max_error <= error)) continue;
    if (!(p.median_seconds >= best)) best = p.median_seconds;
  }
  return best;
}

double fitted_slope(const std::vector<double>& x, const std::vector<double>& y) {
  const auto n = static_cast<double>(x.size());
  if (x.size() < 2 || x.size() != y.size()) return kNaN;
  double mx = 0.0, my = 0.0;
  for (std::size_t k = 0; k < x.size(); ++k) mx += x[k], my += y[k];
  mx /= n, my /= n;
  double sxx = 0.0, sxy = 0.0;
  for (std::size_t k = 0; k < x.size(); ++k) {
    sxx += (x[k] - mx) * (x[k] - mx);
    sxy += (x[k] - mx) * (y[k] - my);
  }
  return sxx > 0.0 ? sxy / sxx : kNaN;
}

std::vector<LadderSummary> ladder_summaries(const StudyResult& study) {
  const auto& r = study.reference;
  const double resolution =
      10.0 * std::max(std::isnan(r.self_convergence) ? 0.0 : r.self_convergence,
                      std::isnan(r.interpolation_error) ? 0.0 : r.interpolation_error);
  std::vector<LadderSummary> out;
  for (const auto& p : study.points) {
    const bool known = std::any_of(out.begin(), out.end(), [&](const LadderSummary& s) {
      return s.integrator == p.setting.integrator && s.uniform == p.setting.uniform;
    });
    if (known) continue;
    LadderSummary s;
    s.integrator = p.setting.integrator;
    s.uniform = p.setting.uniform;
    std::vector<double> log_steps, log_error, log_tolerance;
    for (const auto& q : study.points) {
      if (q.setting.integrator != s.integrator || q.setting.uniform != s.uniform || !q.ok) continue;
      const double e = q.error.max_error;
      // A run compared with its own reference (at its times, no interpolation): that one's
      // resolution.
      const double floor = std::isnan(q.reference_error) ? resolution : 10.0 * q.reference_error;
      if (!(e > floor) || !std::isfinite(e) || q.counters.steps <= 0) continue;
      ++s.points;
      log_steps.push_back(std::log(static_cast<double>(q.counters.steps)));
      log_error.push_back(std::log(e));
      if (is_fixed_step(s.integrator)) continue;
      log_tolerance.push_back(std::log(q.setting.value));
      const double ratio = e / q.setting.value;
      s.least_ratio = std::isnan(s.least_ratio) ? ratio : std::min(s.least_ratio, ratio);
      s.greatest_ratio = std::isnan(s.greatest_ratio) ? ratio : std::max(s.greatest_ratio, ratio);
    }
    s.order = -fitted_slope(log_steps, log_error);
    if (!is_fixed_step(s.integrator)) s.exponent = fitted_slope(log_tolerance, log_error);
    out.push_back(s);
  }
  return out;
}

std::vector<Integrator> measured_integrators(const StudyResult& study) {
  std::vector<Integrator> out;
  for (const auto& p : study.points) {
    if (p.ok && std::find(out.begin(), out.end(), p.setting.integrator) == out.end())
      out.push_back(p.setting.integrator);
  }
  return out;
}

}  // namespace subslip::study
