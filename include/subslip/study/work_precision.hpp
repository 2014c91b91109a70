// The work-precision study: a problem (one contact or crystal case) is run with each integrator
// over a ladder of settings; every run's path is compared with a much finer reference run and
// timed. No I/O: the command line and src/io/accuracy_output.cpp print and write the results.
//
// Settings. Fixed-step integrators (forward Euler, implicit) take an increment factor f: every
// segment gets round(f n) increments whose geometric grading is kept (growth^(n / n')), so for
// an integer f each original increment is split into exactly f. Adaptive integrators (implicit
// with a tolerance, CVODE) take a tolerance.
//
// Errors. A run reports, at every step it takes, a vector of measured values (channels). Channel 0
// is the headline quantity: f_t/f_n (contact) or the stress component along the loading
// direction (crystal). A contact adds its tangential traction's components over f_n, f_x/f_n
// and f_y/f_n, which see the traction's direction (a turn or a reversal errs there, where the
// magnitude does not show it) as the extrapolated integrators' estimate does. A crystal adds, for
// every grain and slip system, the loading ratio r (resolved shear over the CRSS: what the
// extrapolated integrator's error estimate bounds), ln of the CRSS (its relative error) and r_s,
// which follow r where the split of slip among the systems is determined. At each step the
// reference is interpolated (PathInterpolant) and the error is the largest over the channels of
// |value - reference| / scale, each channel with its own scale (channel 0: the yield scale of the
// problem, mu_s or the largest |stress| of the reference along the path; the dimensionless crystal
// channels: 1). Reported: the maximum over the run's steps, where and on which channel it is, and
// the error at the end. Timing runs are separate and report only the scene's output points.
#pragma once

#include <cmath>
#include <cstddef>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "subslip/contact/contact_point.hpp"
#include "subslip/crystal/aggregate.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/crystal/rotation.hpp"
#include "subslip/history/contact_history.hpp"

namespace subslip::study {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// implicit_adaptive: backward Euler with its own error estimate; extrapolated_k: backward Euler
// Richardson-extrapolated to order k (integrators/extrapolation.hpp), adaptive.
enum class Integrator {
  forward_euler,
  implicit,
  implicit_adaptive,
  extrapolated_2,
  extrapolated_3,
  extrapolated_4,
  cvode
};
inline constexpr Integrator kAllIntegrators[] = {
    Integrator::forward_euler,  Integrator::implicit,       Integrator::implicit_adaptive,
    Integrator::extrapolated_2, Integrator::extrapolated_3, Integrator::extrapolated_4,
    Integrator::cvode};
// The order of the adaptive implicit integrator's extrapolation (1: none).
int extrapolation_order(Integrator integrator);
std::string_view to_string(Integrator integrator);
// What a setting's value means for this integrator: "increment factor", "tolerance" or "rtol".
std::string_view setting_kind(Integrator integrator);
bool is_fixed_step(Integrator integrator);

struct Setting {
  Integrator integrator = Integrator::implicit;
  double value = 1.0;  // fixed step: increment factor; adaptive: tolerance; CVODE: rtol
  // Fixed step: uniform increments (growth 1) instead of the scene's grading, in the same
  // number. Forward Euler's step is bounded by stability everywhere, so grading only wastes
  // its steps.
  bool uniform = false;
  // CVODE: absolute tolerances are min(value, atol_scale) times each component's natural scale
  // (the peer's CvodeOptions::atol_scale).
  double atol_scale = 1e-10;
};

// One observed path: the measured channels at the reported points of a run.
struct Trajectory {
  int width = 1;  // channels per point (set by the first point added)
  std::vector<double> time;
  std::vector<double> value;  // point-major: value[k * width + c]
  std::vector<int> segment;   // loading segment of each point, -1 for the initial state
  // Times are times into each point's segment (Problem::times_into_segments), not absolute:
  // every segment then starts at 0.
  bool times_into_segments = false;

  void add(double t, double v, int seg);  // one channel
  void add(double t, std::span<const double> v, int seg);
  std::size_t size() const { return time.size(); }
  std::span<const double> at(std::size_t k) const {
    return {value.data() + k * static_cast<std::size_t>(width), static_cast<std::size_t>(width)};
  }
  // Channel 0 of every point (the headline quantity).
  std::vector<double> headline() const;
};

// The work of one run.
struct RunCounters {
  long steps = 0;              // accepted (sub)steps actually taken
  long rejected = 0;           // adaptive steps refused by the error estimate
  long newton_iterations = 0;  // summed over every solve (grain solves for crystals)
  long cutbacks = 0;           // halvings after a failed update
};

struct RunResult {
  RunCounters counters;  // zero when the run failed (the integrators report them at the end)
  bool ok = false;
  std::string failure;      // when !ok: the integrator's message (a data point)
  double seconds = 0.0;     // wall time of the whole run (setup included)
  double last_time = kNaN;  // the time of the last reported point
  // A failure at the error estimate's noise floor (adaptive): the tolerance it names, else NaN.
  double smallest_tolerance = kNaN;
};

// Which points a run reports.
enum class Report {
  every_step,    // every increment (fixed step), every accepted step (adaptive), every CVODE
                 // step and the scene's increments (CVODE): what the errors are measured at
  scene_points,  // the scene's output points (fixed step and CVODE; adaptive: every accepted
                 // step): the timed runs
};

// Times at which a run must end a step and report (segment, time), in path order: a reference
// computed at exactly a measured run's times needs no interpolation.
using StopTimes = std::vector<std::pair<int, double>>;

// Receives each reported point: time, measured channels, loading segment (-1: initial state).
using PointObserver = std::function<void(double time, std::span<const double> values, int segment)>;

// What divides one channel's error: a fixed scale, or the reference's own value of another
// channel at the same point (the CRSS of a system for its resolved shear, which hardens along
// the path). A channel with an infinite fixed scale is never an error itself (it only scales).
struct ErrorScale {
  ErrorScale(double fixed = 1.0) : value(fixed) {}  // NOLINT: a plain scale reads as a number
  static ErrorScale of_channel(int c) {
    ErrorScale s;
    s.channel = c;
    return s;
  }
  double value = 1.0;  // the fixed scale (channel < 0)
  int channel = -1;    // >= 0: |the reference's channel| at the point
  // The scale at a point whose reference values are `reference`.
  double at(std::span<const double> reference) const {
    return channel < 0 ? value : std::abs(reference[static_cast<std::size_t>(channel)]);
  }
};
using ErrorScales = std::vector<ErrorScale>;

// A case the study can run at any setting. run() never throws for a numerical failure: the
// failure is returned (forward Euler at coarse steps diverges, and that is a result).
class Problem {
 public:
  virtual ~Problem() = default;
  virtual RunResult run(const Setting& setting, Report report, const PointObserver& observe,
                        const StopTimes& stops = {}) const = 0;
  virtual bool supports(Integrator integrator) const = 0;
  // Whether run() honours `stops` with an adaptive integrator: its steps end there, and only
  // those points (and the initial state) are reported.
  virtual bool supports_stops() const { return false; }
  // Whether run() reports (and reads stops as) times into each segment instead of absolute ones.
  virtual bool times_into_segments() const { return false; }
  // The increments of the unrefined scene, summed over segments (the base of the factors).
  virtual long base_increments() const = 0;
  virtual std::string quantity() const = 0;  // channel 0: "f_t/f_n", "sigma_33", ...
  // The scale that divides each channel's error, from the reference path (channel 0: the yield
  // scale of the problem, a fixed one).
  virtual ErrorScales error_scales(const Trajectory& reference) const = 0;
  virtual std::string error_scale_description() const = 0;
  // What channel c is ("sigma_33", "grain 3 system 7 r", ...).
  virtual std::string channel_name(int channel) const = 0;
  // What the error is measured on, all channels together (plot labels, tables).
  virtual std::string measured() const { return quantity(); }
};

// Runs `setting` and keeps every reported point in `path`; a run still going after
// `budget_seconds` is stopped (not ok, with a message saying so).
RunResult record(const Problem& problem, const Setting& setting, Report report, Trajectory& path,
                 double budget_seconds = std::numeric_limits<double>::infinity());

// Segments with every increment count multiplied by `factor` (at least 1 each), the grading
// kept so that integer factors subdivide each original increment (growth 1 when `uniform`),
// and output_every scaled so that the scene's output points are kept (1 when `every_step`).
std::vector<contact::Segment> refine(std::vector<contact::Segment> segments, double factor,
                                     bool uniform, bool every_step);
std::vector<crystal::LoadSegment> refine(std::vector<crystal::LoadSegment> segments, double factor,
                                         bool uniform, bool every_step);

// One contact case; the quantity is f_t/f_n, the scale mu_s.
class ContactProblem final : public Problem {
 public:
  ContactProblem(contact::ContactModel model, std::vector<contact::Segment> segments,
                 history::IntegratorOptions options);
  RunResult run(const Setting& setting, Report report, const PointObserver& observe,
                const StopTimes& stops = {}) const override;
  bool supports(Integrator integrator) const override;
  long base_increments() const override;
  std::string quantity() const override { return "f_t/f_n"; }
  // f_t/f_n, f_x/f_n and f_y/f_n (the channels), each over mu_s.
  ErrorScales error_scales(const Trajectory&) const override {
    return ErrorScales(3, ErrorScale(model_.law.friction.mu_s));
  }
  std::string error_scale_description() const override;
  std::string measured() const override { return quantity() + " and f_x/f_n, f_y/f_n"; }
  std::string channel_name(int channel) const override;

 private:
  contact::ContactModel model_;
  std::vector<contact::Segment> segments_;
  history::IntegratorOptions options_;
};

// One crystal case (a Taylor aggregate, a single crystal being one grain); channel 0 is the
// Cauchy stress component (i, j) along the loading direction, its scale the reference's largest
// |sigma_ij|; then, grain by grain and system by system, r, ln(mu tau0) and r_s (scale 1: r is in
// units of the CRSS, the difference of logarithms is the relative error of the CRSS).
//
// Measure::stress instead: after channel 0, every grain's Cauchy stress (six components, sample
// frame), with channel 0's scale. For laws whose slip is split among systems that round-off
// cannot tell apart (nearly rate-independent, every system yielding at once), each system's
// CRSS follows its own slip and is not determined, while the stress is.
//
// Measure::resolved: after channel 0, grain by grain and system by system, the resolved shear
// tau = P : sigma over the reference's CRSS of that system at the same point (the CRSS rides
// along as a channel that only scales): what the extrapolated integrators' estimate bounds, step
// by step (crystal/aggregate_extrapolation.cpp). Determined where the split of slip is not, and
// blind to stress components that no system resolves (a grain of one family held elastic), on
// which the stress measure sees the elastic response.
class CrystalProblem final : public Problem {
 public:
  enum class Measure { state, stress, resolved };
  // The times a run reports its points at: absolute, or the time into each point's segment
  // (exact, where an absolute time resolves a step only to an ulp of itself: the first steps of
  // a reversal at 1e4 /s a million seconds into a history are 1e-10 s, one ulp of 1e6 s, and a
  // comparison at absolute times there compares different states). Stops (a reference at a
  // run's times) are read on the same clock.
  enum class TimeAxis { absolute, segment };
  CrystalProblem(crystal::PhaseDescription phase, std::vector<crystal::Orientation> orientations,
                 std::vector<crystal::LoadSegment> segments, crystal::AggregateOptions options,
                 std::pair<int, int> component, Measure measure = Measure::state,
                 TimeAxis clock = TimeAxis::absolute);
  RunResult run(const Setting& setting, Report report, const PointObserver& observe,
                const StopTimes& stops = {}) const override;
  bool supports(Integrator integrator) const override;
  bool supports_stops() const override { return true; }
  bool times_into_segments() const override { return clock_ == TimeAxis::segment; }
  long base_increments() const override;
  std::string quantity() const override;
  ErrorScales error_scales(const Trajectory& reference) const override;
  std::string error_scale_description() const override;
  std::string channel_name(int channel) const override;
  std::string measured() const override;

 private:
  crystal::PhaseDescription phase_;
  std::vector<crystal::Orientation> orientations_;
  std::vector<crystal::LoadSegment> segments_;
  crystal::AggregateOptions options_;
  std::pair<int, int> component_;
  Measure measure_;
  TimeAxis clock_;
};

// Interpolation of a path within each loading segment: the nodes of segment k are the points
// of segment k and the last point before it (the segment's start); between two nodes the value
// is the cubic through the four nearest nodes of the segment (exact for cubics, error ~h^4 where
// the path is smooth). It never reaches across the kink between two segments (a reversal, the
// start of a hold).
class PathInterpolant {
 public:
  explicit PathInterpolant(const Trajectory& path);
  int width() const { return width_; }
  // The channels at time t in segment `segment` (-1: the initial state, the first point), into
  // out[0 .. width). Times outside the segment's span are clamped to it.
  void at(double t, int segment, std::span<double> out) const;
  double at(double t, int segment) const;  // channel 0
  // A bound on the interpolation error, the largest over the channels of the error over its
  // scale (`scales` empty: 1): the same interpolation built on every second node, evaluated at
  // the dropped nodes. Where the path is smooth the error falls as h^4, so at the full node
  // density it is about 16 times smaller than this.
  double estimated_error(const ErrorScales& scales = {}) const;

 private:
  struct Piece {
    int segment;
    std::vector<double> t;  // nodes, strictly increasing
    std::vector<double> y;  // node-major, width_ per node
  };
  const Piece* piece_of(int segment) const;
  int width_ = 1;
  std::vector<Piece> pieces_;  // in path order
};

struct ErrorMeasure {
  double max_error = kNaN;       // max over the run's points and channels of |value - ref| / scale
  double max_error_time = kNaN;  // where the maximum is
  int max_error_channel = -1;    // and on which channel
  int max_error_segment = -1;    // and in which loading segment
  double end_error = kNaN;       // at the run's last point (NaN when the run failed)
};

// The error of a run, point by point as the run reports them (nothing is stored).
class ErrorAccumulator {
 public:
  // scales: one per channel of the reference.
  ErrorAccumulator(const PathInterpolant& reference, ErrorScales scales);
  void add(double time, std::span<const double> values, int segment);
  // NaN errors unless `complete` (a failed run has no end, and its error is not a result).
  ErrorMeasure result(bool complete) const;

 private:
  const PathInterpolant& reference_;
  ErrorScales scales_;
  std::vector<double> interpolated_;  // the reference at the current point
  ErrorMeasure e_{0.0, kNaN, -1, -1, kNaN};
  bool any_ = false;
};

ErrorMeasure measure_error(const Trajectory& run, const PathInterpolant& reference,
                           const ErrorScales& scales, bool complete);
// One channel, one scale.
ErrorMeasure measure_error(const Trajectory& run, const PathInterpolant& reference, double scale,
                           bool complete);

// Richardson extrapolation of a first-order method from runs at step h (`fine`) and 2h
// (`coarse`): y_h + (y_h - y_2h) at the fine points, the correction y_h - y_2h taken at the
// coarse points (fine nodes there when the increments nest) and interpolated between them.
Trajectory richardson(const Trajectory& fine, const Trajectory& coarse);

// The median of the times, the middle pair averaged.
double median(std::vector<double> values);

struct Ladder {
  Integrator integrator = Integrator::implicit;
  std::vector<double> values;  // settings, coarse to fine
  bool uniform = false;        // fixed step: uniform increments (Setting::uniform)
  double atol_scale = 1e-10;   // CVODE (Setting::atol_scale)
  // Forward Euler: continue the ladder by x4 factors until the predicted run time exceeds the
  // budget (the explicit values come first).
  bool extend_until_budget = false;
};

struct StudyOptions {
  std::vector<Ladder> ladders;
  // The reference: the implicit integrator at a fixed increment factor R, or adaptive at a
  // tight tolerance. Fixed step: with `richardson`, the first-order runs at R and R/2 are
  // extrapolated (2 y_R - y_R/2, second order), and the same from R/2 and R/4 is its coarser
  // companion; without, the companion is the run at R/2. Adaptive: the companion is the run at
  // a 10x looser tolerance. self_convergence = max |companion - reference|.
  Setting reference{Integrator::implicit, 64.0};
  bool richardson = true;
  // With an adaptive reference and a problem that supports stops: every measured run is compared
  // with the reference recomputed with its steps ending at exactly that run's times (and with
  // its 10x looser companion, the same way), so no interpolation enters the error. Needed where
  // the measured channels have square-root onsets (r_s of every slip system of a polycrystal,
  // each starting at its own time), which no interpolation between reference steps resolves.
  bool reference_at_run_times = false;
  // The CVODE cross-check of the reference (when available), with atol_scale = rtol.
  double cvode_check_rtol = 1e-12;
  double cvode_check_seconds = 120.0;  // the cross-check is stopped after this long
  int repeat = 5;                      // timed runs per point (median)
  double repeat_budget_seconds = 5.0;  // fewer repeats when the first run is slow
  // Ladder points predicted to run longer are skipped, and a run that does is stopped.
  double max_run_seconds = 30.0;
  // Progress: called after the reference and after each point.
  std::function<void(std::string_view line)> progress;
};

struct PointResult {
  Setting setting;
  RunCounters counters;
  bool ok = false;
  std::string failure;
  double reached_time = kNaN;  // the last output time the run reached
  ErrorMeasure error;
  std::string max_error_on;  // the channel of the max error (Problem::channel_name)
  // StudyOptions::reference_at_run_times: max |companion - reference| / scale at this run's
  // times, the resolution of its reference (NaN otherwise).
  double reference_error = kNaN;
  // Its own reference's refusals at the noise floor and the tolerance it then ran at.
  std::vector<std::string> reference_notes;
  double median_seconds = kNaN;  // of the timed runs (NaN when the run failed)
  int repeats = 0;
  double measured_seconds = 0.0;  // the run that measured the error (every step reported)
  long reported_points = 0;       // points it reported
  bool over_budget = false;       // stopped after max_run_seconds (not ok, not a result)
};

struct ReferenceResult {
  Setting setting;
  RunResult run;              // the reference run (R, for an extrapolated one)
  Trajectory path;            // the reference path: every step
  double scale = kNaN;        // the error scale of channel 0
  ErrorScales scales;         // of every channel
  bool extrapolated = false;  // Richardson: from `setting` and half its increments
  Setting check;              // the coarser companion of the self-convergence estimate
  // max |companion - ref| / scale: for a plain fixed-step reference (first order) this
  // estimates the reference's own error; for an extrapolated or adaptive one, the error of the
  // coarser companion, an upper estimate of the reference's.
  double self_convergence = kNaN;
  double interpolation_error = kNaN;  // PathInterpolant::estimated_error / scale
  std::optional<RunResult> cvode;     // the CVODE cross-check (when available)
  Trajectory cvode_path;              // its every step
  double cvode_difference = kNaN;     // max |cvode - ref| / scale
  // Refusals at the noise floor and the tolerance it then ran at (`setting` is that one).
  std::vector<std::string> notes;
};

struct StudyResult {
  std::string quantity;
  std::string measured;  // Problem::measured
  std::string scale_description;
  long base_increments = 0;  // of the scene (the increment factors multiply it)
  ReferenceResult reference;
  std::vector<PointResult> points;  // ladder by ladder, coarse to fine
  std::vector<std::string> notes;   // skipped points and why
};

// The reference run failed: nothing can be measured without it.
struct ReferenceFailure : std::runtime_error {
  using std::runtime_error::runtime_error;
};

// Runs the reference (and its checks), then every ladder. Throws ReferenceFailure when the
// reference itself fails (an adaptive reference refused at its error estimate's noise floor runs
// at the tolerance the refusal names first; StudyResult::notes say so).
StudyResult run_study(const Problem& problem, const StudyOptions& options);

// One ladder point: one run measures the error at every step; then `repeat` timed runs (fewer
// when they would take more than repeat_budget_seconds; at least one) report only the scene's
// output points, and their median is the time.
PointResult measure_point(const Problem& problem, const Setting& setting,
                          const PathInterpolant& reference, const ErrorScales& scales,
                          const StudyOptions& options);

// The cheapest measured run of `integrator` whose maximum error is at most `error`: its median
// time, NaN when no run reached that error. (Measured points only, no interpolation.)
double cheapest_time(const StudyResult& study, Integrator integrator, double error);

// The integrators that have at least one successful point, in ladder order.
std::vector<Integrator> measured_integrators(const StudyResult& study);

// How one integrator's ladder behaved: the order it showed and, for a tolerance
// (adaptive, CVODE), how the error it reached compares with the one asked for. Fitted over its
// successful points whose max error is above the reference's resolution (10 x the larger of
// self_convergence and interpolation_error, or 10 x the point's own reference_error, where the
// reference's own error would flatten the curve); NaN where fewer than two such points (with
// different steps, or settings) remain.
struct LadderSummary {
  Integrator integrator = Integrator::implicit;
  bool uniform = false;          // forward Euler's uniform ladder (a curve of its own)
  int points = 0;                // the points fitted
  double order = kNaN;           // -d log(max error) / d log(steps): 1 for backward Euler
  double exponent = kNaN;        // d log(max error) / d log(tolerance): 1 when the error follows it
  double least_ratio = kNaN;     // min of max error / tolerance over the points
  double greatest_ratio = kNaN;  // max of the same
};
std::vector<LadderSummary> ladder_summaries(const StudyResult& study);

// The least-squares slope of y over x (NaN for fewer than two distinct x).
double fitted_slope(const std::vector<double>& x, const std::vector<double>& y);

// Whether the CVODE peer integrator was built in.
bool cvode_available();

}  // namespace subslip::study
