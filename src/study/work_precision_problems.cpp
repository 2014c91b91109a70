#include "subslip/study/work_precision.hpp"

#include "work_precision_detail.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <utility>

#include "subslip/history/contact_history.hpp"
#include "subslip/study/cvode_peer.hpp"

namespace subslip::study {

using namespace work_precision_detail;

namespace {

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

RunCounters counters_of(const history::RunStats& st) {
  return {st.substeps, st.rejected, st.iterations, st.cutbacks};
}

RunCounters counters_of(const crystal::AggregateStats& st) {
  return {st.substeps, st.rejected, st.newton_iterations, st.cutbacks};
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

// ---- contact

ContactProblem::ContactProblem(contact::ContactModel model, std::vector<contact::Segment> segments,
                               history::IntegratorOptions options)
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

std::string ContactProblem::channel_name(int channel) const {
  if (channel == 1) return "f_x/f_n";
  if (channel == 2) return "f_y/f_n";
  return quantity();
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
    const contact::Vec2 over_fn =
        s.traction_n > 0.0 ? contact::Vec2(s.traction_t / s.traction_n) : contact::Vec2::Zero();
    const std::array<double, 3> channels{s.traction_ratio(), over_fn.x(), over_fn.y()};
    seen(s.time, channels, segment);
  };
  history::IntegratorOptions opt = options_;
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
        out.counters = counters_of(history::run_history(model_, segments, opt, record));
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
            counters_of(history::run_history(model_, outputs_for(segments_, report), opt, record));
        break;
      case Integrator::cvode:
        out.counters = counters_of(cvode::run_contact_history(
            model_, outputs_for(segments_, report), cvode_options(setting, report), record));
        break;
    }
    out.ok = true;
  } catch (const history::StepFailure& e) {
    out.failure = e.what();
    out.smallest_tolerance = e.smallest_tolerance;
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
                               Measure measure, TimeAxis clock)
    : phase_(std::move(phase)),
      orientations_(std::move(orientations)),
      segments_(std::move(segments)),
      options_(options),
      component_(component),
      measure_(measure),
      clock_(clock) {}

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

ErrorScales CrystalProblem::error_scales(const Trajectory& reference) const {
  double largest = 0.0;
  for (double v : reference.headline()) largest = std::max(largest, std::abs(v));
  largest = largest > 0.0 ? largest : 1.0;
  ErrorScales scales(static_cast<std::size_t>(reference.width),
                     ErrorScale(measure_ == Measure::stress ? largest : 1.0));
  scales[0] = ErrorScale(largest);
  if (measure_ == Measure::resolved) {
    // (tau, yield scale) pairs: tau over the scale beside it; the scale itself is not measured.
    for (std::size_t c = 1; c + 1 < scales.size(); c += 2) {
      scales[c] = ErrorScale::of_channel(static_cast<int>(c + 1));
      scales[c + 1] = ErrorScale(std::numeric_limits<double>::infinity());
    }
  }
  return scales;
}

std::string CrystalProblem::error_scale_description() const {
  const std::string flow = "the largest |" + quantity() +
                           "| of the reference along the path (the flow stress the test reaches)";
  if (measure_ == Measure::stress) return flow + ", for every grain's stress as well";
  if (measure_ == Measure::resolved)
    return flow +
           "; every grain's resolved shear of each slip system: the reference's yield scale of "
           "that system at the same point (its CRSS, or its yield traction mu f_n where a "
           "pressure-sensitive plane's compression raises it above that)";
  return flow + "; every grain's r, ln(CRSS) and r_s of each slip system: 1";
}

namespace {
constexpr int kPerSystem = 3;          // r, ln(mu tau0), r_s
constexpr int kPerSystemResolved = 2;  // tau, its yield scale
constexpr const char* kStressNames[6] = {"sigma_11", "sigma_22", "sigma_33",
                                         "sigma_23", "sigma_13", "sigma_12"};
}  // namespace

std::string CrystalProblem::measured() const {
  switch (measure_) {
    case Measure::stress:
      return quantity() + " and every grain's stress";
    case Measure::resolved:
      return quantity() + " and every grain's resolved shear over its yield scale";
    case Measure::state:
      break;
  }
  return quantity() + " and every grain's r, ln(CRSS), r_s";
}

std::string CrystalProblem::channel_name(int channel) const {
  if (channel <= 0) return quantity();
  const int k = channel - 1;
  if (measure_ == Measure::stress)
    return "grain " + std::to_string(k / 6) + " " + kStressNames[k % 6];
  const int slips = crystal::checked_slip_count(phase_);
  if (measure_ == Measure::resolved) {
    const int system = (k / kPerSystemResolved) % slips;
    const int grain = k / kPerSystemResolved / slips;
    return "grain " + std::to_string(grain) + " system " + std::to_string(system) +
           (k % kPerSystemResolved == 0 ? " tau" : " yield scale");
  }
  const int system = (k / kPerSystem) % slips;
  const int grain = k / kPerSystem / slips;
  static constexpr const char* kWhat[kPerSystem] = {"r", "ln(CRSS)", "r_s"};
  return "grain " + std::to_string(grain) + " system " + std::to_string(system) + " " +
         kWhat[k % kPerSystem];
}

namespace {

// The segments with output at the stops only (times into each segment), for an adaptive run.
// `into_segment`: the stops' times are times into their segments already (TimeAxis::segment).
std::vector<crystal::LoadSegment> with_stops(std::vector<crystal::LoadSegment> segments,
                                             const StopTimes& stops, bool into_segment) {
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
    const double segment_start = into_segment ? 0.0 : starts[static_cast<std::size_t>(segment)];
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
  std::vector<double> ratio, crss, strength, r_s, tau, channels;
  const auto record = [&](const crystal::MacroState& m, const crystal::GrainFields& grains) {
    // (The initial state, segment -1, is at time 0 on either clock.)
    const double time = clock_ == TimeAxis::segment && m.segment >= 0 ? m.segment_time : m.time;
    if (report == Report::scene_points) {  // timed: the grains' fields are not what is timed
      const double headline = m.stress(i, j);
      seen(time, std::span<const double>(&headline, 1), m.segment);
      return;
    }
    if (measure_ == Measure::stress) {
      channels.resize(1 + 6 * static_cast<std::size_t>(grains.grain_count()));
      channels[0] = m.stress(i, j);
      grains.values(crystal::GrainField::stress, channels.data() + 1);
      seen(time, channels, m.segment);
      return;
    }
    const auto n = static_cast<std::size_t>(grains.grain_count()) *
                   static_cast<std::size_t>(grains.slip_count());
    if (measure_ == Measure::resolved) {
      tau.resize(n), crss.resize(n), strength.resize(n),
          channels.resize(1 + kPerSystemResolved * n);
      grains.values(crystal::GrainField::tau, tau.data());
      grains.values(crystal::GrainField::crss, crss.data());
      grains.values(crystal::GrainField::strength, strength.data());
      channels[0] = m.stress(i, j);
      for (std::size_t k = 0; k < n; ++k) {  // (the yield scale: crystal::yield_scale)
        channels[1 + kPerSystemResolved * k] = tau[k];
        channels[2 + kPerSystemResolved * k] = std::max(crss[k], strength[k]);
      }
      seen(time, channels, m.segment);
      return;
    }
    ratio.resize(n), crss.resize(n), r_s.resize(n), channels.resize(1 + kPerSystem * n);
    grains.values(crystal::GrainField::r, ratio.data());
    grains.values(crystal::GrainField::crss, crss.data());
    grains.values(crystal::GrainField::r_s, r_s.data());
    channels[0] = m.stress(i, j);
    for (std::size_t k = 0; k < n; ++k) {
      channels[1 + kPerSystem * k] = ratio[k];
      channels[2 + kPerSystem * k] = std::log(crss[k]);
      channels[3 + kPerSystem * k] = r_s[k];
    }
    seen(time, channels, m.segment);
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
        const auto segments = stops.empty()
                                  ? outputs_for(segments_, report)
                                  : with_stops(segments_, stops, clock_ == TimeAxis::segment);
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
    out.smallest_tolerance = e.smallest_tolerance;
  } catch (const cvode::CvodeFailure& e) {
    out.failure = e.what();
  }
  out.seconds = seconds_since(start);
  out.last_time = seen.last;
  return out;
}

}  // namespace subslip::study
