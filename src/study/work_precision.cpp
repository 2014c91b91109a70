#include "subslip/study/work_precision.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <utility>

#include "subslip/study/cvode_peer.hpp"

namespace subslip::study {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

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

// Adaptive integrators and CVODE: the scene's increments set the first step (adaptive) or the
// output points (CVODE); measured runs report every one.
template <class Segment>
std::vector<Segment> outputs_for(std::vector<Segment> segments, Report report) {
  if (report == Report::every_step) {
    for (auto& s : segments) {
      s.output_every = 1;
      s.output_at_times = false;  // (output.at: every step instead)
      s.output_times.clear();
    }
  }
  return segments;
}

template <class Segment>
long total_increments(const std::vector<Segment>& segments) {
  long n = 0;
  for (const auto& s : segments) n += s.increments;
  return n;
}

// An outer node takes part in the interpolation of a bracket only when its spacing is at least
// this fraction of the bracket's. Nodes packed far closer than the bracket (a 1e150-graded
// segment has nodes at 9e-18, 2e-8 and 50 s) turn the cubic into an extrapolation of their local
// slope across the whole bracket: measured, 2e12 between values of 0.1 (a crystal parser-edge
// case of crystal_parser_edges.yaml in `subslip accuracy`). Adaptive steps grow at most 4 times.
constexpr double kSmallestOuterSpacing = 1.0 / 8.0;

// The nodes [first, last] for the bracket [t_j, t_j+1]: widened by a node on the left and one on
// the right, again, to at most four (so shifted inward at the ends of the nodes), never by a node
// whose spacing is below kSmallestOuterSpacing of the bracket's.
std::pair<std::size_t, std::size_t> interpolation_nodes(const std::vector<double>& t,
                                                        std::size_t j) {
  const double least = kSmallestOuterSpacing * (t[j + 1] - t[j]);
  std::size_t first = j, last = j + 1;
  const auto left_ok = [&] { return first > 0 && t[first] - t[first - 1] >= least; };
  const auto right_ok = [&] { return last + 1 < t.size() && t[last + 1] - t[last] >= least; };
  while (last - first < 3) {
    const bool left = left_ok(), right = right_ok();
    if (!left && !right) break;
    if (left) --first;
    if (right && last - first < 3) ++last;
  }
  return {first, last};
}

// Local cubic interpolation on nodes (t strictly increasing), clamped to their span: the cubic
// through the four nodes around x (j-1 .. j+2 for x in [t_j, t_j+1], shifted inward at the ends
// of the nodes; fewer nodes, lower degree, also where outer nodes are packed much closer than
// the bracket). Exact for cubics; the error falls as h^4 where the path is smooth. Every channel
// of the node-major values y (width per node) is interpolated with the same weights.
void local_cubic_at(const std::vector<double>& t, const std::vector<double>& y, int width, double x,
                    std::span<double> out) {
  const auto w = static_cast<std::size_t>(width);
  const auto copy_node = [&](std::size_t k) {
    std::copy(y.begin() + static_cast<std::ptrdiff_t>(k * w),
              y.begin() + static_cast<std::ptrdiff_t>((k + 1) * w), out.begin());
  };
  const std::size_t n = t.size();
  if (n == 1 || x <= t.front()) return copy_node(0);
  if (x >= t.back()) return copy_node(n - 1);
  const auto upper = std::upper_bound(t.begin(), t.end(), x);
  const std::size_t j = static_cast<std::size_t>(upper - t.begin()) - 1;
  if (x == t[j]) return copy_node(j);
  const auto [first, last] = interpolation_nodes(t, j);
  std::fill(out.begin(), out.end(), 0.0);
  for (std::size_t a = first; a <= last; ++a) {
    double weight = 1.0;
    for (std::size_t b = first; b <= last; ++b) {
      if (b != a) weight *= (x - t[b]) / (t[a] - t[b]);
    }
    const double* node = y.data() + a * w;
    for (std::size_t c = 0; c < w; ++c) out[c] += weight * node[c];
  }
}

// CVODE at a relative tolerance rtol and absolute tolerances of min(rtol, atol_scale) times
// each component's natural scale (the peer's atol_scale). Measured runs also report every
// internal CVODE step.
cvode::CvodeOptions cvode_options(const Setting& s, Report report) {
  cvode::CvodeOptions o;
  o.rtol = s.value;
  o.atol_scale = std::min(s.value, s.atol_scale);
  o.report_every_step = report == Report::every_step;
  return o;
}

RunCounters counters_of(const contact::RunStats& st) {
  return {st.substeps, st.rejected, st.iterations, st.cutbacks};
}

RunCounters counters_of(const crystal::AggregateStats& st) {
  return {st.substeps, st.rejected, st.newton_iterations, st.cutbacks};
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
// The header's column widths are the row's.
std::string ladder_header(Integrator integrator) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "%-17s  %8s  %9s  %9s  %9s  %9s  %4s",
                std::string(to_string(integrator)).c_str(), "steps", "max error", "at t",
                "end error", "time[s]", "runs");
  return buf;
}

std::string describe_point(const PointResult& p) {
  const std::string setting = format_setting(p.setting);
  if (!p.ok) return setting + ": failed: " + p.failure;
  char buf[256];
  std::snprintf(buf, sizeof buf, "%-17s  %8ld  %9.3e  %9.3g  %9.3e  %9.4g  %4d", setting.c_str(),
                p.counters.steps, p.error.max_error, p.error.max_error_time, p.error.end_error,
                p.median_seconds, p.repeats);
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

// Wraps an observer so that the run knows its last reported time.
struct LastTime {
  const PointObserver& observe;
  double last = kNaN;
  void operator()(double t, std::span<const double> v, int segment) {
    last = t;
    observe(t, v, segment);
  }
};

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

// ---- contact

ContactProblem::ContactProblem(contact::ContactModel model, std::vector<contact::Segment> segments,
                               contact::IntegratorOptions options)
    : model_(std::move(model)), segments_(std::move(segments)), options_(options) {}

bool ContactProblem::supports(Integrator integrator) const {
  // The rate-independent form has no ODE form (its slip rate comes from consistency).
  if (integrator == Integrator::cvode) {
    return cvode_available() && model_.law.overstress.form != law::OverstressForm::rate_independent;
  }
  return true;
}

long ContactProblem::base_increments() const {
  return total_increments(segments_);
}

std::string ContactProblem::error_scale_description() const {
  return "mu_s (the static friction coefficient: the yield ratio f_t/f_n of a fresh contact)";
}

RunResult ContactProblem::run(const Setting& setting, Report report, const PointObserver& observe,
                              const StopTimes&) const {
  RunResult out;
  const auto start = Clock::now();
  LastTime seen{observe};
  const auto record = [&seen](const contact::ContactState& s, int segment) {
    const double ratio = s.traction_ratio();
    seen(s.time, std::span<const double>(&ratio, 1), segment);
  };
  contact::IntegratorOptions opt = options_;
  opt.tolerance = 0.0;
  try {
    switch (setting.integrator) {
      case Integrator::forward_euler:
      case Integrator::implicit: {
        opt.method = setting.integrator == Integrator::implicit ? contact::Method::implicit
                                                                : contact::Method::forward_euler;
        // A forward Euler point is forward Euler at that step: a step above its stability limit
        // fails the point instead of being cut back to the limit (which any setting would reach).
        if (opt.method == contact::Method::forward_euler) opt.max_cutbacks = 0;
        const auto segments =
            refine(segments_, setting.value, setting.uniform, report == Report::every_step);
        out.counters = counters_of(contact::run_history(model_, segments, opt, record));
        break;
      }
      case Integrator::implicit_adaptive:
      case Integrator::extrapolated_2:
      case Integrator::extrapolated_3:
      case Integrator::extrapolated_4:
        opt.method = contact::Method::implicit;
        opt.tolerance = setting.value;
        opt.order = extrapolation_order(setting.integrator);
        out.counters =
            counters_of(contact::run_history(model_, outputs_for(segments_, report), opt, record));
        break;
      case Integrator::cvode:
        out.counters = counters_of(cvode::run_contact_history(
            model_, outputs_for(segments_, report), cvode_options(setting, report), record));
        break;
    }
    out.ok = true;
  } catch (const contact::StepFailure& e) {
    out.failure = e.what();
  } catch (const cvode::CvodeFailure& e) {
    out.failure = e.what();
  }
  out.seconds = seconds_since(start);
  out.last_time = seen.last;
  return out;
}

// ---- crystal

CrystalProblem::CrystalProblem(crystal::PhaseDescription phase,
                               std::vector<crystal::Orientation> orientations,
                               std::vector<crystal::LoadSegment> segments,
                               crystal::AggregateOptions options, std::pair<int, int> component,
                               Measure measure)
    : phase_(std::move(phase)),
      orientations_(std::move(orientations)),
      segments_(std::move(segments)),
      options_(options),
      component_(component),
      measure_(measure) {}

bool CrystalProblem::supports(Integrator integrator) const {
  // The rate-independent form has no slip rate for forward Euler or an ODE solver.
  const auto rate_independent = [](const crystal::SlipGroupSettings& g) {
    return g.law.overstress.form == law::OverstressForm::rate_independent;
  };
  const bool any_rate_independent =
      phase_.custom_systems.empty() ? std::any_of(phase_.family_settings.begin(),
                                                  phase_.family_settings.end(), rate_independent)
                                    : rate_independent(phase_.custom_settings);
  if (integrator == Integrator::cvode) return cvode_available() && !any_rate_independent;
  if (integrator == Integrator::forward_euler) return !any_rate_independent;
  return true;
}

long CrystalProblem::base_increments() const {
  return total_increments(segments_);
}

std::string CrystalProblem::quantity() const {
  return "sigma_" + std::to_string(component_.first + 1) + std::to_string(component_.second + 1);
}

std::vector<double> CrystalProblem::error_scales(const Trajectory& reference) const {
  double largest = 0.0;
  for (double v : reference.headline()) largest = std::max(largest, std::abs(v));
  largest = largest > 0.0 ? largest : 1.0;
  std::vector<double> scales(static_cast<std::size_t>(reference.width),
                             measure_ == Measure::stress ? largest : 1.0);
  scales[0] = largest;
  return scales;
}

std::string CrystalProblem::error_scale_description() const {
  const std::string flow = "the largest |" + quantity() +
                           "| of the reference along the path (the flow stress the test reaches)";
  if (measure_ == Measure::stress) return flow + ", for every grain's stress as well";
  return flow + "; every grain's r, ln(CRSS) and r_s of each slip system: 1";
}

namespace {
constexpr int kPerSystem = 3;  // r, ln(mu tau0), r_s
constexpr const char* kStressNames[6] = {"sigma_11", "sigma_22", "sigma_33",
                                         "sigma_23", "sigma_13", "sigma_12"};
}  // namespace

std::string CrystalProblem::measured() const {
  return quantity() + (measure_ == Measure::stress ? " and every grain's stress"
                                                   : " and every grain's r, ln(CRSS), r_s");
}

std::string CrystalProblem::channel_name(int channel) const {
  if (channel <= 0) return quantity();
  const int k = channel - 1;
  if (measure_ == Measure::stress)
    return "grain " + std::to_string(k / 6) + " " + kStressNames[k % 6];
  const int slips = crystal::checked_slip_count(phase_);
  const int system = (k / kPerSystem) % slips;
  const int grain = k / kPerSystem / slips;
  static constexpr const char* kWhat[kPerSystem] = {"r", "ln(CRSS)", "r_s"};
  return "grain " + std::to_string(grain) + " system " + std::to_string(system) + " " +
         kWhat[k % kPerSystem];
}

namespace {

// The segments with output at the stops only (times into each segment), for an adaptive run.
std::vector<crystal::LoadSegment> with_stops(std::vector<crystal::LoadSegment> segments,
                                             const StopTimes& stops) {
  std::vector<double> starts(segments.size());
  double start = 0.0;  // (accumulated as the aggregate accumulates it)
  for (std::size_t k = 0; k < segments.size(); ++k) {
    starts[k] = start;
    start += segments[k].duration;
    segments[k].output_at_times = true;
    segments[k].output_times.clear();
  }
  // A run's times are absolute, resolved to a few ulps of the time itself: within that of its
  // segment's start a point is the start (reported by the segment before), within that of the
  // segment's end it is the end (else the reference would take a last step of 1e-15 s, which
  // no grain solve resolves).
  using integrators::kSameTime;
  for (const auto& [segment, time] : stops) {
    if (segment < 0 || static_cast<std::size_t>(segment) >= segments.size()) continue;
    const double segment_start = starts[static_cast<std::size_t>(segment)];
    auto& s = segments[static_cast<std::size_t>(segment)];
    const double into = time - segment_start;
    if (into <= kSameTime * segment_start) continue;
    const bool at_end = into >= s.duration - kSameTime * (segment_start + s.duration);
    s.output_times.push_back(at_end ? s.duration : into);
  }
  for (auto& s : segments) {
    std::sort(s.output_times.begin(), s.output_times.end());
    s.output_times.erase(std::unique(s.output_times.begin(), s.output_times.end()),
                         s.output_times.end());
    if (s.output_times.empty() || s.output_times.back() < s.duration)
      s.output_times.push_back(s.duration);  // every segment reports its end
  }
  return segments;
}

}  // namespace

RunResult CrystalProblem::run(const Setting& setting, Report report, const PointObserver& observe,
                              const StopTimes& stops) const {
  RunResult out;
  const auto start = Clock::now();
  LastTime seen{observe};
  const auto [i, j] = component_;
  // Reused from point to point (the observer runs between steps, never concurrently).
  std::vector<double> ratio, crss, r_s, channels;
  const auto record = [&](const crystal::MacroState& m, const crystal::GrainFields& grains) {
    if (report == Report::scene_points) {  // timed: the grains' fields are not what is timed
      const double headline = m.stress(i, j);
      seen(m.time, std::span<const double>(&headline, 1), m.segment);
      return;
    }
    if (measure_ == Measure::stress) {
      channels.resize(1 + 6 * static_cast<std::size_t>(grains.grain_count()));
      channels[0] = m.stress(i, j);
      grains.stress(channels.data() + 1);
      seen(m.time, channels, m.segment);
      return;
    }
    const auto n = static_cast<std::size_t>(grains.grain_count()) *
                   static_cast<std::size_t>(grains.slip_count());
    ratio.resize(n), crss.resize(n), r_s.resize(n), channels.resize(1 + kPerSystem * n);
    grains.ratio(ratio.data());
    grains.crss(crss.data());
    grains.subloading_ratio(r_s.data());
    channels[0] = m.stress(i, j);
    for (std::size_t k = 0; k < n; ++k) {
      channels[1 + kPerSystem * k] = ratio[k];
      channels[2 + kPerSystem * k] = std::log(crss[k]);
      channels[3 + kPerSystem * k] = r_s[k];
    }
    seen(m.time, channels, m.segment);
  };
  crystal::AggregateOptions opt = options_;
  opt.tolerance = 0.0;
  try {
    switch (setting.integrator) {
      case Integrator::forward_euler:
      case Integrator::implicit: {
        opt.method = setting.integrator == Integrator::implicit
                         ? crystal::CrystalMethod::implicit
                         : crystal::CrystalMethod::forward_euler;
        // As for contact: forward Euler at that step, not cut back to its stability limit.
        if (opt.method == crystal::CrystalMethod::forward_euler) opt.max_cutbacks = 0;
        const auto segments =
            refine(segments_, setting.value, setting.uniform, report == Report::every_step);
        auto aggregate = crystal::build_taylor_aggregate(phase_, orientations_);
        out.counters = counters_of(aggregate->run(segments, opt, record));
        break;
      }
      case Integrator::implicit_adaptive:
      case Integrator::extrapolated_2:
      case Integrator::extrapolated_3:
      case Integrator::extrapolated_4: {
        opt.method = crystal::CrystalMethod::implicit;
        opt.tolerance = setting.value;
        opt.order = extrapolation_order(setting.integrator);
        auto aggregate = crystal::build_taylor_aggregate(phase_, orientations_);
        const auto segments =
            stops.empty() ? outputs_for(segments_, report) : with_stops(segments_, stops);
        out.counters = counters_of(aggregate->run(segments, opt, record));
        break;
      }
      case Integrator::cvode:
        out.counters = counters_of(
            cvode::run_taylor_aggregate(phase_, orientations_, outputs_for(segments_, report),
                                        cvode_options(setting, report), record));
        break;
    }
    out.ok = true;
  } catch (const crystal::CrystalStepFailure& e) {
    out.failure = e.what();
  } catch (const cvode::CvodeFailure& e) {
    out.failure = e.what();
  }
  out.seconds = seconds_since(start);
  out.last_time = seen.last;
  return out;
}

// ---- interpolation and errors

PathInterpolant::PathInterpolant(const Trajectory& path) : width_(path.width) {
  for (std::size_t k = 0; k < path.size(); ++k) {
    const int seg = path.segment[k];
    if (pieces_.empty() || pieces_.back().segment != seg) {
      Piece p;
      p.segment = seg;
      if (k > 0) {  // the segment starts where the previous one ended
        p.t.push_back(path.time[k - 1]);
        const auto v = path.at(k - 1);
        p.y.insert(p.y.end(), v.begin(), v.end());
      }
      pieces_.push_back(std::move(p));
    }
    pieces_.back().t.push_back(path.time[k]);
    const auto v = path.at(k);
    pieces_.back().y.insert(pieces_.back().y.end(), v.begin(), v.end());
  }
}

const PathInterpolant::Piece* PathInterpolant::piece_of(int segment) const {
  for (const auto& p : pieces_)
    if (p.segment == segment) return &p;
  return nullptr;
}

void PathInterpolant::at(double t, int segment, std::span<double> out) const {
  const Piece* p = piece_of(segment);
  if (p == nullptr) {
    throw std::out_of_range("reference path has no segment " + std::to_string(segment));
  }
  if (out.size() != static_cast<std::size_t>(width_)) {
    throw std::invalid_argument("a path of " + std::to_string(out.size()) +
                                " channels compared with a reference of " + std::to_string(width_));
  }
  local_cubic_at(p->t, p->y, width_, t, out);
}

double PathInterpolant::at(double t, int segment) const {
  std::vector<double> out(static_cast<std::size_t>(width_));
  at(t, segment, out);
  return out[0];
}

double PathInterpolant::estimated_error(std::span<const double> scales) const {
  const auto w = static_cast<std::size_t>(width_);
  const auto scale = [&](std::size_t c) { return scales.empty() ? 1.0 : scales[c]; };
  double worst = 0.0;
  std::vector<double> value(w);
  for (const auto& p : pieces_) {
    const std::size_t n = p.t.size();
    if (n < 5) continue;
    std::vector<double> t2, y2;
    const auto keep = [&](std::size_t k) {
      t2.push_back(p.t[k]);
      y2.insert(y2.end(), p.y.begin() + static_cast<std::ptrdiff_t>(k * w),
                p.y.begin() + static_cast<std::ptrdiff_t>((k + 1) * w));
    };
    for (std::size_t k = 0; k < n; k += 2) keep(k);
    if ((n - 1) % 2 != 0) keep(n - 1);  // keep the last node
    for (std::size_t k = 1; k + 1 < n; k += 2) {
      local_cubic_at(t2, y2, width_, p.t[k], value);
      for (std::size_t c = 0; c < w; ++c)
        worst = std::max(worst, std::abs(value[c] - p.y[k * w + c]) / scale(c));
    }
  }
  return worst;
}

ErrorAccumulator::ErrorAccumulator(const PathInterpolant& reference, std::vector<double> scales)
    : reference_(reference),
      scales_(std::move(scales)),
      interpolated_(static_cast<std::size_t>(reference.width())) {
  if (scales_.size() != interpolated_.size()) {
    throw std::invalid_argument("one error scale per channel of the reference is needed");
  }
}

void ErrorAccumulator::add(double time, std::span<const double> values, int segment) {
  if (values.size() != interpolated_.size()) {
    throw std::invalid_argument("a point of " + std::to_string(values.size()) +
                                " channels compared with a reference of " +
                                std::to_string(interpolated_.size()));
  }
  reference_.at(time, segment, interpolated_);
  double d = 0.0;
  int channel = 0;
  for (std::size_t c = 0; c < values.size(); ++c) {
    const double dc = std::abs(values[c] - interpolated_[c]) / scales_[c];
    if (std::isnan(dc) || dc > d) {  // a NaN wins
      d = dc;
      channel = static_cast<int>(c);
      if (std::isnan(dc)) break;
    }
  }
  // The first point sets the maximum; a NaN sticks.
  if (!std::isnan(e_.max_error) && (!any_ || !(d <= e_.max_error))) {
    e_.max_error = d;
    e_.max_error_time = time;
    e_.max_error_channel = channel;
  }
  e_.end_error = d;
  any_ = true;
}

ErrorMeasure ErrorAccumulator::result(bool complete) const {
  if (!complete || !any_) return {};
  return e_;
}

ErrorMeasure measure_error(const Trajectory& run, const PathInterpolant& reference,
                           const std::vector<double>& scales, bool complete) {
  ErrorAccumulator acc(reference, scales);
  for (std::size_t k = 0; k < run.size(); ++k) acc.add(run.time[k], run.at(k), run.segment[k]);
  return acc.result(complete);
}

ErrorMeasure measure_error(const Trajectory& run, const PathInterpolant& reference, double scale,
                           bool complete) {
  return measure_error(run, reference, std::vector<double>{scale}, complete);
}

Trajectory richardson(const Trajectory& fine, const Trajectory& coarse) {
  // The correction y_h - y_2h is known at the coarse points (fine nodes there); it is small and
  // smooth, so interpolating it to the other fine nodes adds only a small fraction of itself.
  const PathInterpolant f(fine);
  const auto w = static_cast<std::size_t>(fine.width);
  std::vector<double> v(w);
  Trajectory correction;
  for (std::size_t k = 0; k < coarse.size(); ++k) {
    const double t = coarse.time[k];
    f.at(t, coarse.segment[k], v);
    const auto c = coarse.at(k);
    for (std::size_t i = 0; i < w; ++i) v[i] -= c[i];
    correction.add(t, v, coarse.segment[k]);
  }
  const PathInterpolant c(correction);
  Trajectory out;
  for (std::size_t k = 0; k < fine.size(); ++k) {
    const double t = fine.time[k];
    c.at(t, fine.segment[k], v);
    const auto y = fine.at(k);
    for (std::size_t i = 0; i < w; ++i) v[i] += y[i];
    out.add(t, v, fine.segment[k]);
  }
  return out;
}

double median(std::vector<double> values) {
  if (values.empty()) return kNaN;
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
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

// The reference (options.reference, adaptive) and its 10x looser companion at a run's times;
// throws ReferenceFailure when either fails.
void reference_at(const Problem& problem, const StudyOptions& options, const StopTimes& stops,
                  Trajectory& reference, Trajectory& companion) {
  const Setting looser{options.reference.integrator, 10.0 * options.reference.value};
  const PointObserver keep_reference = [&](double t, std::span<const double> v, int seg) {
    reference.add(t, v, seg);
  };
  const PointObserver keep_companion = [&](double t, std::span<const double> v, int seg) {
    companion.add(t, v, seg);
  };
  reference = {}, companion = {};
  for (const auto& [setting, keep] :
       {std::pair{options.reference, &keep_reference}, std::pair{looser, &keep_companion}}) {
    const RunResult r = problem.run(setting, Report::every_step, *keep, stops);
    if (!r.ok) {
      throw ReferenceFailure("the reference (" + std::string(to_string(setting.integrator)) + " " +
                             format_setting(setting) + ") at a run's times failed: " + r.failure);
    }
  }
}

}  // namespace

PointResult measure_point(const Problem& problem, const Setting& setting,
                          const PathInterpolant& reference, const std::vector<double>& scales,
                          const StudyOptions& options) {
  PointResult p;
  p.setting = setting;
  const bool own_reference = options.reference_at_run_times && problem.supports_stops() &&
                             !is_fixed_step(options.reference.integrator);
  ErrorAccumulator error(reference, scales);
  Trajectory path;  // kept only when the run gets its own reference
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
    reference_at(problem, options, stops_of(path), at_run, companion);
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

// Runs the reference (or one of its companions); a failure stops the study.
RunResult run_reference_setting(const Problem& problem, const Setting& setting, Trajectory& path) {
  RunResult r = record(problem, setting, Report::every_step, path);
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
  ref.run = run_reference_setting(problem, ref.setting, ref.path);
  ref.check = {ref.setting.integrator, 0.5 * r, ref.setting.uniform};
  Trajectory half;
  const RunResult half_run = run_reference_setting(problem, ref.check, half);
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
    ref.run = run_reference_setting(problem, ref.setting, ref.path);
    ref.check = {ref.setting.integrator, 10.0 * ref.setting.value};
    Trajectory looser;
    if (record(problem, ref.check, Report::every_step, looser).ok) check = std::move(looser);
  }
  ref.scales = problem.error_scales(ref.path);
  ref.scale = ref.scales.front();
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
  say(options, describe_reference(problem, out.reference));
  const PathInterpolant reference(out.reference.path);
  for (const Ladder& ladder : options.ladders) {
    if (!problem.supports(ladder.integrator)) {
      out.notes.push_back(std::string(to_string(ladder.integrator)) + ": not available");
      say(options, out.notes.back());
      continue;
    }
    say(options, ladder_header(ladder.integrator));
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
      if (out.points.back().error.max_error_channel >= 0) {
        out.points.back().max_error_on =
            problem.channel_name(out.points.back().error.max_error_channel);
      }
      say(options, describe_point(out.points.back()));
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
