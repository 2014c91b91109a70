// subslip_extreme_report: runs the stiff and extreme case set (inputs/extreme/*.yaml)
// and prints Markdown:
//
//  * one table per scene file, one row per case: outcome (ran to the end, or the failure
//    message), steps, Newton iterations and cutbacks per step, min(r_hat - r) over the outputs
//    (every grain and slip system for crystals), admissibility (finite, 0 <= r_s <= r < r_hat at
//    every output), and the error against a reference (the same case with every increment split
//    into R), at 1, 2 and 4 splits with the observed order;
//  * adaptive stepping on chosen cases (when the library has it): steps and error per tolerance;
//  * where forward Euler goes unstable: the measured critical step against the linearised
//    estimate dt_crit = 2 / lambda, lambda = alpha dphi/dr / (f_n mu) for a contact and the
//    largest eigenvalue of A diag(dphi_a/dr_a / (mu_a tau0_a)) for a crystal.
//
// Usage: subslip_extreme_report [SCENE.yaml ...] [--reference R] [--skip-cases] [--skip-fe]
// (default: every inputs/extreme/*.yaml). Errors are in units of the yield scale: contact
// |f_t - f_t,ref| / (f_n mu_s) (the traction vector, f_n the initial normal traction), crystal
// max_ij |sigma_ij - sigma_ref,ij| / max_a(mu0_a tau0_a) (mu0 the initial friction coefficient).
#include <omp.h>
#include <CLI/CLI.hpp>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <limits>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "forward_euler_limit.hpp"
#include "report_format.hpp"
#include "subslip/contact/contact_point.hpp"
#include "subslip/crystal/aggregate.hpp"
#include "subslip/crystal/crystal_kernel.hpp"
#include "subslip/crystal/elasticity.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/history/contact_history.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/scene_common.hpp"
#include "subslip/law/subloading_friction.hpp"
#include "subslip/material_point.hpp"

namespace fs = std::filesystem;
using namespace subslip;
namespace ct = subslip::contact;
namespace hs = subslip::history;
namespace cr = subslip::crystal;
using bench::fmt;
using bench::sci;

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// ------------------------------------------------------------------------------------------
// Time series of one run and the error of one series against another.
// ------------------------------------------------------------------------------------------

struct Series {
  // Where each output is along the history: its segment (-1: the initial state) and the time into
  // it. Not the absolute time, which cannot resolve 1e-11 s steps after 1e6 s; not a fraction of
  // the segment either, which cannot resolve a 1e-12 s relaxation at the start of a 1e6 s one.
  std::vector<int> segment;
  std::vector<double> segment_time;
  std::vector<std::vector<double>> value;  // one vector per output

  void add(int k, double t, std::vector<double> v) {
    segment.push_back(k);
    segment_time.push_back(k < 0 ? 0.0 : t);
    value.push_back(std::move(v));
  }
  size_t size() const { return value.size(); }
  bool before(size_t i, int k, double t) const {
    return segment[i] < k || (segment[i] == k && segment_time[i] < t);
  }
};

// max over the outputs of |s - ref| (max norm) for runs with the same output steps (a split
// run reports at the original increments).
double max_error_nested(const Series& s, const Series& ref) {
  if (s.value.size() != ref.value.size()) return std::nan("");
  double worst = 0.0;
  for (size_t i = 0; i < s.value.size(); ++i)
    for (size_t j = 0; j < s.value[i].size(); ++j)
      worst = std::max(worst, std::abs(s.value[i][j] - ref.value[i][j]));
  return worst;
}

// The same for an adaptive run, which reports every accepted step, against a fixed-step
// reference: the run is interpolated linearly in time (its history position) at the
// reference's outputs. (Not
// the other way round: at the onset of a hold the traction relaxes within ~alpha-scale times,
// 1e-8 min, which the adaptive run resolves and a fixed reference step of 1e-5 min jumps over;
// the implicit reference is right at its own nodes, L-stable, but not in between.)
double max_error_interpolated(const Series& s, const Series& ref) {
  if (s.size() < 2 || ref.size() == 0) return std::nan("");
  double worst = 0.0;
  size_t k = 1;  // s's outputs k - 1 and k bracket the reference output
  for (size_t i = 0; i < ref.size(); ++i) {
    const int seg = ref.segment[i];
    const double t = ref.segment_time[i];
    while (k + 1 < s.size() && s.before(k, seg, t)) ++k;
    // A bracket across segments starts at the end of the previous one: time 0 of this one. A
    // reference output past this run's last one in the same segment (their end times differ in
    // the last bits) takes that last one.
    const double t1 = s.segment_time[k];
    const double t0 = s.segment[k - 1] == s.segment[k] ? s.segment_time[k - 1] : 0.0;
    const double w = s.segment[k] != seg ? 0.0
                     : t1 > t0           ? std::clamp((t - t0) / (t1 - t0), 0.0, 1.0)
                                         : 1.0;
    for (size_t j = 0; j < ref.value[i].size(); ++j) {
      const double v = (1.0 - w) * s.value[k - 1][j] + w * s.value[k][j];
      worst = std::max(worst, std::abs(v - ref.value[i][j]));
    }
  }
  return worst;
}

// ------------------------------------------------------------------------------------------
// One run of one case.
// ------------------------------------------------------------------------------------------

struct CaseRun {
  std::string failure;    // empty: ran to the end
  std::string violation;  // first output outside the admissible set, if any
  long steps = 0;         // accepted steps (cutback pieces included)
  long increments = 0;
  long iterations = 0;  // Newton iterations (per grain solve for crystals)
  long solves = 0;      // grain solves (crystals)
  long cutbacks = 0;
  long rejected = 0;      // adaptive steps refused by the error estimate
  double min_gap = kInf;  // min(r_hat - r) over the outputs, rate-dependent systems
  double wall = 0.0;
  Series series;
  double scale = 1.0;  // the yield scale the series is divided by
};

// Every increment of every segment split into k: k times the increments with growth^(1/k)
// gives the same increment boundaries (a geometric progression of ratio g^(1/k) summed over k
// terms is proportional to g^i). Outputs stay at the original increments.
template <class Seg>
std::vector<Seg> split(std::vector<Seg> segs, int k) {
  for (Seg& s : segs) {
    s.increments *= k;
    s.growth = std::pow(s.growth, 1.0 / k);
    s.output_every = k;
  }
  return segs;
}

// How much splitting every increment into k shrinks the largest increment of a segment of n
// increments with ratio q between neighbours: the largest is the fraction (1 - p)/(1 - p^n),
// p = min(q, 1/q), of the segment, before and after the split (n k increments, ratio q^(1/k)).
// Nested splitting keeps the grading, so with extreme growth (1e150: a 1e-150 first increment,
// then the rest) the largest increment hardly shrinks at all and the error cannot fall.
double largest_fraction(double q, long n) {
  const double p = std::min(q, 1.0 / q);
  return p == 1.0 ? 1.0 / static_cast<double>(n) : (1.0 - p) / (1.0 - std::pow(p, n));
}

template <class Seg>
double largest_step_shrink(const std::vector<Seg>& segs, int k) {
  double worst = kInf;
  for (const Seg& s : segs)
    worst = std::min(worst, largest_fraction(s.growth, s.increments) /
                                largest_fraction(std::pow(s.growth, 1.0 / k),
                                                 static_cast<long>(s.increments) * k));
  return worst;
}

std::string contact_inadmissible(const ct::ContactState& s, const law::LawParameters& p) {
  const bool finite = std::isfinite(s.traction_t.x()) && std::isfinite(s.traction_t.y()) &&
                      std::isfinite(s.traction_n) && std::isfinite(s.law.mu) &&
                      std::isfinite(s.law.r_s) && std::isfinite(s.r) && std::isfinite(s.time);
  std::ostringstream why;
  if (!finite) why << "non-finite";
  if (!(s.law.r_s >= 0.0)) why << " r_s<0";
  if (!(s.law.r_s <= s.r)) why << " r_s>r";
  if (p.overstress.form != law::OverstressForm::rate_independent && !(s.r < p.overstress.r_hat))
    why << " r>=r_hat";
  if (!(s.law.mu > 0.0)) why << " mu<=0";
  if (why.str().empty()) return {};
  why << " at t=" << s.time << " (r=" << s.r << ", r_s=" << s.law.r_s << ")";
  return why.str();
}

// The order of every adaptive run (--order: 1 is backward Euler's estimate, 2 .. 4 the
// extrapolated integrator); set once from the command line.
int adaptive_order = 1;

CaseRun run_contact(const io::ContactCase& c, int split_by, double tolerance, int order) {
  CaseRun out;
  const auto& p = c.model.law;
  out.scale = c.model.initial_normal_traction * p.friction.mu_s;
  hs::IntegratorOptions opt = c.integrator;
  if (tolerance >= 0.0) opt.tolerance = tolerance;
  if (opt.tolerance > 0.0) opt.order = order;
  const bool rate_dependent = p.overstress.form != law::OverstressForm::rate_independent;
  std::vector<double> segment_start(1, 0.0);
  for (const auto& seg : c.segments) segment_start.push_back(segment_start.back() + seg.duration);
  const auto t0 = std::chrono::steady_clock::now();
  try {
    const hs::RunStats st = hs::run_history(
        c.model, split(c.segments, split_by), opt, [&](const ct::ContactState& s, int k) {
          if (out.violation.empty()) out.violation = contact_inadmissible(s, p);
          if (rate_dependent) out.min_gap = std::min(out.min_gap, p.overstress.r_hat - s.r);
          const double into = k < 0 ? 0.0 : s.time - segment_start[static_cast<size_t>(k)];
          out.series.add(k, into, {s.traction_t.x() / out.scale, s.traction_t.y() / out.scale});
        });
    out.steps = st.substeps;
    out.increments = st.increments;
    out.iterations = st.iterations;
    out.cutbacks = st.cutbacks;
    out.rejected = st.rejected;
  } catch (const std::exception& e) {
    out.failure = e.what();
  }
  out.wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

// Per slip system: r_hat (inf for rate-independent) in output order.
std::vector<double> system_r_hat(const cr::PhaseDescription& d) {
  std::vector<double> out;
  for (const auto& sys : cr::described_systems(d)) {
    const auto& settings = d.custom_systems.empty()
                               ? d.family_settings[static_cast<size_t>(sys.group)]
                               : d.custom_settings;
    const auto& o = settings.law.overstress;
    out.push_back(o.form == law::OverstressForm::rate_independent ? kInf : o.r_hat);
  }
  return out;
}

double crss_scale(const cr::PhaseDescription& d) {
  double scale = 0.0;
  auto add = [&](const cr::SlipGroupSettings& s) {
    const double mu0 = s.initial_mu > 0.0 ? s.initial_mu : s.law.friction.mu_s;
    scale = std::max(scale, mu0 * s.tau0);
  };
  if (d.custom_systems.empty()) {
    for (const auto& s : d.family_settings) add(s);
  } else {
    add(d.custom_settings);
  }
  return scale;
}

// A run stopped by the report's time limit (not a failure of the case).
struct TimeLimit : std::runtime_error {
  using std::runtime_error::runtime_error;
};
constexpr char kTimeLimitPrefix[] = "time limit";

// `seconds` > 0 stops the run after that much wall time (checked after every increment).
CaseRun run_crystal(const io::CrystalCase& c, int split_by, double tolerance, double seconds,
                    int order) {
  CaseRun out;
  out.scale = crss_scale(c.phase);
  const std::vector<double> r_hat = system_r_hat(c.phase);
  cr::AggregateOptions opt = c.options;
  if (tolerance >= 0.0) opt.tolerance = tolerance;
  if (opt.tolerance > 0.0) opt.order = order;
  const auto t0 = std::chrono::steady_clock::now();
  cr::RunControl limit;
  if (seconds > 0.0)
    limit.after_increment = [&](const cr::RunPosition&, const cr::MacroState& m) {
      if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > seconds)
        throw TimeLimit(std::string(kTimeLimitPrefix) + " of " + fmt("%g", seconds) +
                        " s reached at t = " + fmt("%g", m.time));
    };
  try {
    auto agg = cr::build_taylor_aggregate(c.phase, c.orientations);
    const size_t n = static_cast<size_t>(agg->slip_count());
    const size_t cells = n * static_cast<size_t>(agg->grain_count());
    std::vector<double> r(cells), rs(cells), crss(cells);
    const cr::AggregateStats st = agg->run(
        split(c.segments, split_by), opt,
        [&](const cr::MacroState& m, const cr::GrainFields& f) {
          f.values(cr::GrainField::r, r.data());
          f.values(cr::GrainField::r_s, rs.data());
          f.values(cr::GrainField::crss, crss.data());
          for (size_t i = 0; i < cells && out.violation.empty(); ++i) {
            const double rh = r_hat[i % n];
            std::ostringstream why;
            if (!std::isfinite(r[i]) || !std::isfinite(rs[i]) || !std::isfinite(crss[i]))
              why << "non-finite";
            else if (rs[i] < 0.0)
              why << "r_s<0";
            else if (rs[i] > r[i] + 1e-12 * std::max(1.0, r[i]))
              why << "r_s>r";
            else if (!(r[i] < rh))
              why << "r>=r_hat";
            else if (!(crss[i] > 0.0))
              why << "crss<=0";
            if (!why.str().empty()) {
              why << " at t=" << m.time << " grain " << i / n << " system " << i % n
                  << " (r=" << r[i] << ", r_s=" << rs[i] << ")";
              out.violation = why.str();
            }
          }
          if (!m.stress.allFinite() && out.violation.empty())
            out.violation = "non-finite stress at t=" + std::to_string(m.time);
          for (size_t i = 0; i < cells; ++i)
            if (std::isfinite(r_hat[i % n]))
              out.min_gap = std::min(out.min_gap, r_hat[i % n] - r[i]);
          std::vector<double> v(9);
          for (int k = 0; k < 9; ++k)
            v[static_cast<size_t>(k)] = m.stress(k / 3, k % 3) / out.scale;
          out.series.add(m.segment, m.segment_time, std::move(v));
        },
        limit);
    out.steps = st.substeps;
    out.increments = st.increments;
    out.iterations = st.newton_iterations;
    out.solves = st.grain_solves;
    out.cutbacks = st.cutbacks;
    out.rejected = st.rejected;
  } catch (const std::exception& e) {
    out.failure = e.what();
  }
  out.wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

// One name for both kinds of case, so that the tables are written once: every increment split
// into `split_by`; adaptive at `tolerance` (0: fixed steps); a crystal run stops after `seconds`
// of wall time when > 0 (contacts take seconds at most).
// `order`: that of an adaptive run (0: --order's).
CaseRun run_case(const io::ContactCase& c, int split_by, double tolerance, double = 0.0,
                 int order = 0) {
  return run_contact(c, split_by, tolerance, order > 0 ? order : adaptive_order);
}
CaseRun run_case(const io::CrystalCase& c, int split_by, double tolerance, double seconds = 0.0,
                 int order = 0) {
  return run_crystal(c, split_by, tolerance, seconds, order > 0 ? order : adaptive_order);
}
template <class Case>
constexpr bool is_crystal = std::is_same_v<Case, io::CrystalCase>;

// Calls f with the contact or crystal scene at `path`.
template <class F>
void with_scene(const fs::path& path, F&& f) {
  if (io::scene_kind(io::YamlDocument::from_file(path), {"contact", "crystal"}) == "contact") {
    f(io::load_contact_scene(path));
  } else {
    f(io::load_crystal_scene(path));
  }
}

// The error below which differences are rounding, not discretisation: a few ulps of the
// largest elastic trial of a step (the return mapping subtracts the slip from it), in units of
// the yield scale.
double largest_increment(double duration, int increments, double growth) {
  const auto dts = cr::increment_lengths(duration, increments, growth);
  return *std::max_element(dts.begin(), dts.end());
}
// Differences below this (yield-scale units) count as converged: the implicit solvers stop at
// a flow residual of 1e-12 (ratio units), which the return mapping's conditioning amplifies.
constexpr double kConvergedFloor = 1e-9;

double roundoff_floor(const io::ContactCase& c) {
  double du = 0.0;
  for (const auto& s : c.segments)
    du = std::max(du, s.velocity.norm() * largest_increment(s.duration, s.increments, s.growth));
  return 8.0 * std::numeric_limits<double>::epsilon() * c.model.stiffness.alpha_t * du /
         (c.model.initial_normal_traction * c.model.law.friction.mu_s);
}
double roundoff_floor(const io::CrystalCase& c) {
  double de = 0.0;
  for (const auto& s : c.segments)
    de = std::max(de, s.velocity_gradient.cwiseAbs().maxCoeff() *
                          largest_increment(s.duration, s.increments, s.growth));
  return 8.0 * std::numeric_limits<double>::epsilon() * c.phase.stiffness.cwiseAbs().maxCoeff() *
         de / crss_scale(c.phase);
}

// ------------------------------------------------------------------------------------------
// The per-file tables.
// ------------------------------------------------------------------------------------------

struct Options {
  std::vector<std::string> scenes;
  int reference = 32;  // splits of the reference run
  bool skip_cases = false;
  bool skip_adaptive = false;
  bool skip_fe = false;
  bool adaptive_cases = false;       // per-case adaptive convergence table
  double adaptive_reference = 1e-6;  // tolerance of the adaptive reference run
  double adaptive_seconds = 120.0;   // wall-time limit of that run (crystals)
};

std::string outcome(const CaseRun& r) {
  if (!r.failure.empty()) {
    std::string m = r.failure;
    std::replace(m.begin(), m.end(), '|', '/');
    return "**failed**: " + m;
  }
  if (!r.violation.empty()) return "**inadmissible**: " + r.violation;
  return "ran to end";
}

struct Totals {
  int cases = 0, failed = 0, inadmissible = 0, not_converging = 0;
  int not_refined = 0;     // of not_converging: splitting does not shrink the largest increment
  int refined_failed = 0;  // cases whose x1 run ended but a refined run or the reference failed
  double max_newton = 0.0, max_cutbacks = 0.0, min_gap = kInf;
};

template <class Case>
void case_table(const std::string& file, const std::string& title, const std::vector<Case>& cases,
                const Options& o, Totals& totals) {
  constexpr bool crystal = is_crystal<Case>;
  std::cout << "\n### `" << file << "`: " << title << "\n\n";
  std::cout << "| case | outcome | steps | Newton/" << (crystal ? "grain solve" : "step")
            << " | cutbacks/step | min(r_hat - r) | err x1 | err x2 | err x4 | order | wall [s] |\n"
            << "|---|---|---|---|---|---|---|---|---|---|---|\n";
  for (const Case& c : cases) {
    const CaseRun r1 = run_case(c, 1, 0.0);
    ++totals.cases;
    std::vector<double> err(3, std::nan(""));
    std::string order = "-";
    // The refined runs that failed (their errors read "-": a shorter series has none).
    std::string refined_failures;
    if (r1.failure.empty()) {
      const CaseRun ref = run_case(c, o.reference, 0.0);
      const CaseRun r2 = run_case(c, 2, 0.0), r4 = run_case(c, 4, 0.0);
      auto note_failure = [&](const CaseRun& run, const std::string& name) {
        if (!run.failure.empty()) refined_failures += (refined_failures.empty() ? "" : ", ") + name;
      };
      note_failure(r2, "x2");
      note_failure(r4, "x4");
      note_failure(ref, "x" + std::to_string(o.reference));
      if (!refined_failures.empty()) ++totals.refined_failed;
      if (ref.failure.empty()) {
        err = {max_error_nested(r1.series, ref.series), max_error_nested(r2.series, ref.series),
               max_error_nested(r4.series, ref.series)};
        const double floor = std::max(10.0 * roundoff_floor(c), kConvergedFloor);
        if (err[0] <= floor) {
          order = "round-off";
        } else {
          order = err[2] > floor ? fmt("%.2f", std::log2(err[0] / err[2]) / 2.0) : "> 1";
          const bool decreasing =
              err[1] <= err[0] && (err[2] <= err[1] || std::max(err[1], err[2]) <= floor);
          if (!decreasing) {
            ++totals.not_converging;
            // x4 should shrink the largest increment 4 times; below 2 it is not refined.
            const bool refined = largest_step_shrink(c.segments, 4) >= 2.0;
            if (!refined) ++totals.not_refined;
            order += refined ? " (!)" : " (!, largest step not refined)";
          }
        }
      }
    }
    if (!r1.failure.empty()) ++totals.failed;
    if (!r1.violation.empty()) ++totals.inadmissible;
    const double steps = std::max<double>(1.0, static_cast<double>(r1.steps));
    const double per_newton =
        static_cast<double>(r1.iterations) /
        (crystal ? std::max<double>(1.0, static_cast<double>(r1.solves)) : steps);
    const double per_cut = static_cast<double>(r1.cutbacks) /
                           std::max<double>(1.0, static_cast<double>(r1.increments));
    totals.max_newton = std::max(totals.max_newton, per_newton);
    totals.max_cutbacks = std::max(totals.max_cutbacks, per_cut);
    totals.min_gap = std::min(totals.min_gap, r1.min_gap);
    const std::string failed_too =
        refined_failures.empty() ? "" : " (**failed: " + refined_failures + "**)";
    std::cout << "| " << c.name << " | " << outcome(r1) << failed_too << " | " << r1.steps << " | "
              << fmt("%.2f", per_newton) << " | " << fmt("%.3f", per_cut) << " | "
              << (r1.min_gap == kInf ? std::string("-") : sci(r1.min_gap)) << " | " << sci(err[0])
              << " | " << sci(err[1]) << " | " << sci(err[2]) << " | " << order << " | "
              << fmt("%.3f", r1.wall) << " |\n";
  }
}

// Convergence as the adaptive tolerance tightens: every case at tolerances 1e-2, 1e-3, 1e-4
// against an adaptive run at `adaptive_reference`, which is itself compared with the fixed
// reference (every increment split into `reference`): two references built differently (steps
// chosen by the error estimate; the scene's grading split uniformly) that agree bound the
// error of both. Adaptive runs report every accepted step; the coarser run is interpolated
// linearly at the reference's output times.
//
// Where the three runs are one and the same run (same steps, same outputs), the error estimate
// never reached 1e-4 and every step was set by the growth limit: that ladder cannot show
// convergence, whatever the error. The case is then judged two decades further down, at 1e-4,
// 1e-5 and 1e-6 against a reference at adaptive_reference / 100 (measured: an almost elastic
// crystal_parser_edges.yaml case, initial_mu = 100 and eta_v = 1e6 s, takes 252 steps at every
// tolerance from 1e-2 to 1e-4, error 6.3e-5, and its error first falls below 1e-4).
struct AdaptiveTotals {
  int cases = 0, failed = 0, not_converging = 0;
  int not_judged = 0;          // the adaptive reference did not finish within the time limit
  int moved_down = 0;          // judged at 1e-4 .. 1e-6: the runs at 1e-2 .. 1e-4 were the same run
  int order_2_references = 0;  // judged against an order-2 reference (reference_unavailable)
  double worst_reference_gap = 0.0;
};

// Whether a reference run stopped because it cannot be computed at its tolerance, not because
// the integrator broke: over the wall-time limit, at the error estimate's noise floor
// (AdaptiveSegment::noise_floor_message), or where backward Euler's estimate does not fall
// (AdaptiveSegment::not_falling_message: it compares slip rates, which a nearly rate-independent
// grain does not determine). The order-2 extrapolated integrator, whose estimate is on the
// resolved shears, computes such references (docs/integrators.md).
bool reference_unavailable(const std::string& failure) {
  return failure.rfind(kTimeLimitPrefix, 0) == 0 ||
         failure.find("below what double precision resolves") != std::string::npos ||
         failure.find("does not fall as the step shrinks") != std::string::npos;
}

template <class Case>
struct Ladder {
  std::array<double, 3> tolerances;
  double reference_tolerance;
  CaseRun reference;
  std::vector<CaseRun> runs;
  std::array<double, 3> err{std::nan(""), std::nan(""), std::nan("")};
  std::string failure;  // of the reference or of a run, first found

  // Why backward Euler's own reference could not be computed, where the order-2 extrapolated
  // one is used instead (reference_unavailable).
  std::string own_reference_failure;

  Ladder(const Case& c, std::array<double, 3> tols, double ref_tol, double seconds)
      : tolerances(tols), reference_tolerance(ref_tol) {
    reference = run_case(c, 1, ref_tol, seconds);
    if (adaptive_order == 1 && reference_unavailable(reference.failure)) {
      own_reference_failure = reference.failure;
      reference = run_case(c, 1, ref_tol, seconds, 2);
    }
    for (double tol : tolerances) runs.push_back(run_case(c, 1, tol));
    failure = reference.failure;
    for (const CaseRun& r : runs)
      if (failure.empty()) failure = r.failure.empty() ? r.violation : r.failure;
    if (failure.empty())
      for (size_t k = 0; k < 3; ++k)
        err[k] = max_error_interpolated(runs[k].series, reference.series);
  }
  // "1e-2 / 1e-3 / 1e-4"
  std::string tolerance_list() const {
    return sci(tolerances[0]) + " / " + sci(tolerances[1]) + " / " + sci(tolerances[2]);
  }
  bool one_run() const {
    return failure.empty() && runs[0].steps == runs[1].steps && runs[1].steps == runs[2].steps &&
           max_error_interpolated(runs[0].series, runs[2].series) == 0.0;
  }
  // Falling from each tolerance to the next, and by at least 3 over both decades (the estimate
  // is first order in dt, so the error should go as tol^(1/2): a factor 10); or already at the
  // level the reference resolves (10 x its tolerance).
  bool falling() const {
    constexpr double kMinimumFall = 3.0;
    const double floor = std::max(kConvergedFloor, 10.0 * reference_tolerance);
    return (err[1] < err[0] || err[1] <= floor) && (err[2] < err[1] || err[2] <= floor) &&
           (err[2] <= err[0] / kMinimumFall || err[2] <= floor);
  }
};

template <class Case>
void adaptive_case_table(const std::string& file, const std::vector<Case>& cases, const Options& o,
                         AdaptiveTotals& totals) {
  std::cout << "\n### `" << file << "`: adaptive, tolerance 1e-2 / 1e-3 / 1e-4\n\n"
            << "| case | outcome | steps 1e-2 / 1e-3 / 1e-4 | err 1e-2 | err 1e-3 | err 1e-4 | "
               "converges | reference steps | adaptive ref. - fixed ref. | wall [s] |\n"
            << "|---|---|---|---|---|---|---|---|---|---|\n";
  for (const Case& c : cases) {
    ++totals.cases;
    const auto t0 = std::chrono::steady_clock::now();
    Ladder<Case> ladder(c, {1e-2, 1e-3, 1e-4}, o.adaptive_reference, o.adaptive_seconds);
    const std::string first_list = ladder.tolerance_list();
    const bool moved = ladder.one_run();
    if (moved) {
      ++totals.moved_down;
      ladder =
          Ladder<Case>(c, {1e-4, 1e-5, 1e-6}, o.adaptive_reference / 100.0, o.adaptive_seconds);
    }
    const CaseRun fixed_ref = run_case(c, o.reference, 0.0);
    std::string failure = ladder.failure;
    std::string verdict = "-";
    double gap = std::nan("");
    if (failure.empty()) {
      if (fixed_ref.failure.empty()) {
        gap = max_error_interpolated(ladder.reference.series, fixed_ref.series);
        totals.worst_reference_gap = std::max(totals.worst_reference_gap, gap);
      }
      const bool falling = ladder.falling();
      verdict = falling ? "yes" : "**no**";
      if (moved)
        verdict += " (the runs at " + first_list + " were one run; judged at " +
                   ladder.tolerance_list() + " against " + sci(ladder.reference_tolerance) + ")";
      if (!ladder.own_reference_failure.empty()) {
        ++totals.order_2_references;
        std::string why = ladder.own_reference_failure.substr(0, 60);
        std::replace(why.begin(), why.end(), '|', '/');
        verdict += " (against an order-2 reference; backward Euler's: " + why + " ...)";
      }
      if (!falling) ++totals.not_converging;
    } else if (failure == ladder.reference.failure && failure.rfind(kTimeLimitPrefix, 0) == 0) {
      ++totals.not_judged;
      verdict = "not judged: reference " + failure;
      failure.clear();
    } else {
      ++totals.failed;
      std::replace(failure.begin(), failure.end(), '|', '/');
      verdict = "**failed**: " + failure;
    }
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const auto& runs = ladder.runs;
    std::cout << "| " << c.name << " | " << (failure.empty() ? "ran to end" : "**failed**") << " | "
              << runs[0].steps << " / " << runs[1].steps << " / " << runs[2].steps << " | "
              << sci(ladder.err[0]) << " | " << sci(ladder.err[1]) << " | " << sci(ladder.err[2])
              << " | " << verdict << " | " << ladder.reference.steps << " | " << sci(gap) << " | "
              << fmt("%.2f", wall) << " |" << std::endl;  // flushed: long rows show as they finish
  }
}

void report_scene_adaptive(const fs::path& path, const Options& o, AdaptiveTotals& totals) {
  with_scene(path, [&](const auto& scene) {
    adaptive_case_table(path.filename().string(), scene.cases, o, totals);
  });
}

void report_scene_cases(const fs::path& path, const Options& o, Totals& totals);

void report_scene(const fs::path& path, const Options& o, Totals& totals) {
  try {
    report_scene_cases(path, o, totals);
  } catch (const InputError& e) {
    std::cout << "\n### `" << path.filename().string() << "`\n\n**input error**: " << e.what()
              << "\n";
    ++totals.failed;
  }
}

void report_scene_cases(const fs::path& path, const Options& o, Totals& totals) {
  with_scene(path, [&](const auto& scene) {
    case_table(path.filename().string(), scene.title, scene.cases, o, totals);
  });
}

// ------------------------------------------------------------------------------------------
// Adaptive stepping on chosen cases.
// ------------------------------------------------------------------------------------------

struct AdaptivePick {
  const char* file;
  const char* case_name;
};

const AdaptivePick kAdaptivePicks[] = {
    {"contact_hold_hours.yaml", "duration=6000,increments=100,xi=0"},
    {"contact_hold_hours.yaml", "duration=6000,increments=100,xi=0.009"},
    {"contact_impact_metres.yaml", "speed=1.0e6,increments=10000"},
    {"contact_impact_metres.yaml", "speed=1.0e4,increments=10000"},
    {"contact_speed_viscosity.yaml", "speed=1.0e6,eta_v=1.0e5,r_hat=1.01"},
    {"contact_speed_viscosity.yaml", "speed=1.0e-4,eta_v=10,r_hat=1.8"},
    {"contact_stiffness_exponent.yaml", "form=power,alpha_t=1.0e8,n=128,increments=1000"},
    {"contact_stiffness_exponent.yaml", "form=exponential,alpha_t=1.0e8,n=1,increments=1000"},
    {"crystal_single_slip_stiffness.yaml",
     "tau0=1,loading[0].L[0][1]=1.0e4,loading[1].L[0][1]=-1.0e-6"},
    {"crystal_fcc_schmid_stiff.yaml", "tau0=0.754,L[2][2]=1.0e4,increments=1000"},
};

template <class Case>
void adaptive_rows(const std::string& file, const Case& c, const Options& o) {
  const CaseRun ref = run_case(c, o.reference, 0.0);
  const CaseRun fixed = run_case(c, 1, 0.0);
  auto row = [&](const std::string& setting, const CaseRun& r) {
    const double steps = std::max<double>(1.0, static_cast<double>(r.steps));
    const double newton =
        static_cast<double>(r.iterations) / (r.solves > 0 ? static_cast<double>(r.solves) : steps);
    std::cout << "| " << file << " | " << c.name << " | " << setting << " | " << outcome(r) << " | "
              << r.steps << " | " << r.rejected << " | " << fmt("%.2f", newton) << " | "
              << (r.failure.empty() && ref.failure.empty()
                      ? sci(max_error_interpolated(r.series, ref.series))
                      : std::string("-"))
              << " | " << fmt("%.3f", r.wall) << " |\n";
  };
  row("fixed (scene)", fixed);
  for (double tol : {1e-2, 1e-3, 1e-4, 1e-5, 1e-6}) row("tol " + sci(tol), run_case(c, 1, tol));
}

void report_adaptive(const fs::path& dir, const Options& o) {
  std::cout << "\n## Adaptive stepping\n\n"
            << "Tolerance on the local error estimate (yield-scale units); the first step of each "
               "segment is the scene's first increment. Error against the fixed-step reference "
               "(each increment split into "
            << o.reference
            << "), at the reference's output times (the adaptive run interpolated linearly).\n\n"
            << "| file | case | setting | outcome | steps | rejected | Newton/step | max error | "
               "wall [s] |\n|---|---|---|---|---|---|---|---|---|\n";
  for (const AdaptivePick& pick : kAdaptivePicks) {
    const fs::path path = dir / pick.file;
    if (!fs::exists(path)) continue;
    with_scene(path, [&](const auto& scene) {
      for (const auto& c : scene.cases)
        if (c.name == pick.case_name) return adaptive_rows(pick.file, c, o);
      std::cout << "| " << pick.file << " | " << pick.case_name
                << " | - | no such case | | | | | |\n";
    });
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"Runs the stiff and extreme case set and prints Markdown tables"};
  Options o;
  app.add_option("scenes", o.scenes, "scene files (default: every inputs/extreme/*.yaml)");
  app.add_option("--reference", o.reference, "splits of every increment in the reference run")
      ->check(CLI::Range(4, 1024));
  app.add_flag("--skip-cases", o.skip_cases, "no per-case tables");
  app.add_flag("--skip-adaptive", o.skip_adaptive, "no adaptive-stepping table");
  app.add_flag("--skip-fe", o.skip_fe, "no forward-Euler stability tables");
  app.add_flag("--adaptive-cases", o.adaptive_cases,
               "every case also adaptive at tolerances 1e-2, 1e-3, 1e-4 against an adaptive "
               "reference");
  app.add_option("--adaptive-reference", o.adaptive_reference,
                 "tolerance of the adaptive reference run (--adaptive-cases)")
      ->check(CLI::Range(1e-12, 1e-5));
  app.add_option("--adaptive-seconds", o.adaptive_seconds,
                 "wall-time limit of the adaptive reference run of a crystal case; a case whose "
                 "reference takes longer is reported as not judged")
      ->check(CLI::PositiveNumber);
  app.add_option("--order", adaptive_order,
                 "order of every adaptive run: 1 backward Euler's estimate, 2 .. 4 extrapolated")
      ->check(CLI::Range(1, 4));
  CLI11_PARSE(app, argc, argv);
  omp_set_num_threads(1);  // small aggregates: a parallel region per step costs more than it gains

  const fs::path dir = fs::path(SUBSLIP_SOURCE_DIR) / "inputs" / "extreme";
  std::vector<fs::path> scenes(o.scenes.begin(), o.scenes.end());
  if (scenes.empty()) {
    for (const auto& e : fs::directory_iterator(dir))
      if (e.path().extension() == ".yaml") scenes.push_back(e.path());
    std::sort(scenes.begin(), scenes.end());
  }
  try {
    std::cout << "# Stiff and extreme cases\n\nGenerated by `subslip_extreme_report` (reference: "
                 "every increment split into "
              << o.reference << "; err xk: the case with every increment split into k).\n";
    if (!o.skip_cases) {
      Totals totals;
      for (const auto& path : scenes) report_scene(path, o, totals);
      std::cout << "\n**Summary**: " << totals.cases << " cases, " << totals.failed << " failed, "
                << totals.inadmissible << " inadmissible outputs, " << totals.not_converging
                << " with errors not decreasing under refinement (" << totals.not_refined
                << " of them with a largest increment that splitting does not shrink), "
                << totals.refined_failed
                << " whose refined runs (x2, x4) or reference failed where x1 ran; at most "
                << fmt("%.2f", totals.max_newton)
                << " Newton iterations per step (or grain solve), "
                << fmt("%.3f", totals.max_cutbacks)
                << " cutbacks per increment; smallest r_hat - r: " << sci(totals.min_gap) << "\n";
    }
    if (o.adaptive_cases) {
      std::cout << "\n## Every case adaptive\n";
      AdaptiveTotals totals;
      for (const auto& path : scenes) report_scene_adaptive(path, o, totals);
      std::cout << "\n**Adaptive summary**: " << totals.cases << " cases, " << totals.failed
                << " failed, " << totals.not_converging
                << " with errors not falling as the tolerance tightens, " << totals.not_judged
                << " not judged (reference over the time limit), " << totals.moved_down
                << " judged two decades further down (their runs at 1e-2 .. 1e-4 were one run), "
                << totals.order_2_references
                << " against an order-2 reference (backward Euler's could not be computed); "
                   "largest difference "
                   "between the adaptive and the fixed reference: "
                << sci(totals.worst_reference_gap) << "\n";
    }
    if (!o.skip_adaptive) report_adaptive(dir, o);
    if (!o.skip_fe) bench::report_forward_euler();
  } catch (const InputError& e) {
    std::cerr << "subslip_extreme_report: " << e.what() << "\n";
    return 2;
  }
  return 0;
}
