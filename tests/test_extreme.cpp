// The stiff and extreme case set (inputs/extreme/*.yaml) through the
// library: every shipped case runs to the end without NaN or Inf and keeps 0 <=
// r_s <= r < r_hat at every output; where the law has an analytical limit the
// runs reach it (steady sliding law::steady_state, Schmid saturation, the
// elastic slope before yield, relaxation during holds, mu frozen when nothing
// drives it, an open contact); errors against a refined reference fall as the
// step is refined; forward Euler's stability limit is where the linearised
// estimate puts it; and the kernel regressions found by this set stay fixed.
//
// Expected values come from closed forms, the law's analytical steady state,
// bounds derived in the comments, or runs of the same case with smaller steps;
// no number is copied from a run. Heavier sweeps (every case at 1, 2, 4 and 32
// splits, the forward-Euler bisection over four stiffnesses) are in
// bench/extreme_report.cpp (docs/extreme_cases.md).
#include <gtest/gtest.h>

#include <omp.h>
#include "copper_phase.hpp"
#include "grain_recorder.hpp"
#include "paper_law.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <limits>
#include <numbers>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "single_thread.hpp"
#include "subslip/contact/contact_point.hpp"
#include "subslip/crystal/aggregate.hpp"
#include "subslip/crystal/crystal_kernel.hpp"
#include "subslip/crystal/elasticity.hpp"
#include "subslip/crystal/phase_builder.hpp"
#include "subslip/crystal/slip_systems.hpp"
#include "subslip/history/contact_history.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/scene_common.hpp"
#include "subslip/law/subloading_friction.hpp"
#include "subslip/study/explicit_stability.hpp"

namespace fs = std::filesystem;
using namespace subslip;
namespace ct = subslip::contact;
namespace hs = subslip::history;
namespace cr = subslip::crystal;

namespace {

constexpr double kEps = std::numeric_limits<double>::epsilon();
constexpr double kPi = std::numbers::pi;
const fs::path kExtremeDir = fs::path(SUBSLIP_SOURCE_DIR) / "inputs" / "extreme";

std::ostream& measured() {
  return std::cout << std::setprecision(6) << "[ measured ] ";
}

using subslip::testing::SingleThread;

std::vector<fs::path> extreme_scenes(std::string_view kind) {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(kExtremeDir)) {
    if (e.path().extension() != ".yaml") continue;
    if (io::scene_kind(io::YamlDocument::from_file(e.path()), {"contact", "crystal"}) == kind)
      out.push_back(e.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

template <class Scene>
const auto& case_named(const Scene& scene, const std::string& name) {
  for (const auto& c : scene.cases)
    if (c.name == name) return c;
  throw std::runtime_error("no case '" + name + "' in " + scene.file);
}

// Every increment split into k: k times the increments with growth^(1/k) has
// the same increment boundaries (sum_{m<k} g^((ik+m)/k) is proportional to
// g^i). Outputs stay at the original increments (output_every = k), so split
// runs compare output by output.
template <class Seg>
std::vector<Seg> split(std::vector<Seg> segs, int k) {
  for (Seg& s : segs) {
    s.increments *= k;
    s.growth = std::pow(s.growth, 1.0 / k);
    s.output_every = k;
  }
  return segs;
}

// ---- contact
// ------------------------------------------------------------------------------

struct ContactTrace {
  std::vector<ct::ContactState> states;  // the initial state, then one per output
  std::vector<int> segment;
  hs::RunStats stats;
};

ContactTrace run_contact(const io::ContactCase& c, int k = 1, double tolerance = 0.0) {
  hs::IntegratorOptions opt = c.integrator;
  opt.tolerance = tolerance;
  ContactTrace t;
  t.stats =
      hs::run_history(c.model, split(c.segments, k), opt, [&](const ct::ContactState& s, int seg) {
        t.states.push_back(s);
        t.segment.push_back(seg);
      });
  return t;
}

// Empty when the state is admissible: finite, 0 <= r_s <= r < r_hat, mu > 0,
// and f_t/f_n = r mu (2.22) to rounding.
std::string contact_inadmissible(const ct::ContactState& s, const law::LawParameters& p) {
  std::ostringstream why;
  const bool finite = std::isfinite(s.traction_t.x()) && std::isfinite(s.traction_t.y()) &&
                      std::isfinite(s.traction_n) && std::isfinite(s.law.mu) &&
                      std::isfinite(s.law.r_s) && std::isfinite(s.r) && std::isfinite(s.vp_slip) &&
                      std::isfinite(s.vp_rate) && std::isfinite(s.time);
  if (!finite) why << "non-finite ";
  if (!(s.law.r_s >= 0.0)) why << "r_s<0 ";
  if (!(s.law.r_s <= s.r)) why << "r_s>r ";
  if (p.overstress.form != law::OverstressForm::rate_independent && !(s.r < p.overstress.r_hat))
    why << "r>=r_hat ";
  if (!(s.law.mu > 0.0)) why << "mu<=0 ";
  if (finite && s.traction_n > 0.0 &&
      std::abs(s.traction_ratio() - s.r * s.law.mu) > 8 * kEps * s.traction_ratio())
    why << "ratio!=r*mu ";
  if (!why.str().empty())
    why << "(t=" << s.time << " r=" << s.r << " r_s=" << s.law.r_s << " mu=" << s.law.mu << ")";
  return why.str();
}

// The resolution of r in an implicit contact increment of sliding du (as
// derived in test_contact.cpp): the flow residual tolerance plus the slip
// resolution 1e-14 du turned into traction by alpha, twice.
double ratio_resolution(const io::ContactCase& c, double du, double mu) {
  return 2.0 * (c.integrator.residual_tolerance +
                c.model.stiffness.alpha_t * 1e-14 * du / (c.model.initial_normal_traction * mu));
}

// ---- crystal
// ------------------------------------------------------------------------------

using Snapshot = subslip::testing::GrainSnapshot;
using Recorder = subslip::testing::GrainRecorder;

struct CrystalTrace {
  std::vector<Snapshot> snaps;
  cr::AggregateStats stats;
};

CrystalTrace run_crystal(const io::CrystalCase& c, int k = 1, double tolerance = 0.0,
                         std::size_t max_grains = 0) {
  auto grains = c.orientations;
  if (max_grains > 0 && grains.size() > max_grains) grains.resize(max_grains);
  auto agg = cr::build_taylor_aggregate(c.phase, grains);
  cr::AggregateOptions opt = c.options;
  opt.tolerance = tolerance;
  Recorder rec;
  CrystalTrace t;
  t.stats = agg->run(split(c.segments, k), opt, rec.observer());
  t.snaps = std::move(rec.snaps);
  return t;
}

// Per slip system, in output order: the law of its group.
std::vector<law::LawParameters> system_laws(const cr::PhaseDescription& d) {
  std::vector<law::LawParameters> out;
  for (const auto& sys : cr::described_systems(d))
    out.push_back(d.custom_systems.empty() ? d.family_settings[static_cast<size_t>(sys.group)].law
                                           : d.custom_settings.law);
  return out;
}

// Empty when every grain and system of the snapshot is admissible: finite, CRSS
// > 0, 0 <= r_s <= r (exactly: the kernel stores r_s = min(r_s, r) with r from
// the stored stress, the same arithmetic as the observer's), r < r_hat for the
// rate-dependent forms.
std::string crystal_inadmissible(const Snapshot& s, const std::vector<law::LawParameters>& laws) {
  const size_t n = laws.size();
  if (!s.macro.stress.allFinite())
    return "non-finite macro stress at t=" + std::to_string(s.macro.time);
  for (size_t i = 0; i < s.ratio.size(); ++i) {
    const auto& o = laws[i % n].overstress;
    std::ostringstream why;
    if (!std::isfinite(s.ratio[i]) || !std::isfinite(s.r_s[i]) || !std::isfinite(s.crss[i]) ||
        !std::isfinite(s.slip[i]) || !std::isfinite(s.rate[i]))
      why << "non-finite ";
    else if (!(s.r_s[i] >= 0.0))
      why << "r_s<0 ";
    else if (!(s.r_s[i] <= s.ratio[i]))
      why << "r_s>r ";
    else if (o.form != law::OverstressForm::rate_independent && !(s.ratio[i] < o.r_hat))
      why << "r>=r_hat ";
    else if (!(s.crss[i] > 0.0))
      why << "crss<=0 ";
    if (!why.str().empty()) {
      why << "(t=" << s.macro.time << " grain " << i / n << " system " << i % n
          << " r=" << std::setprecision(17) << s.ratio[i] << " r_s=" << s.r_s[i] << ")";
      return why.str();
    }
  }
  for (double v : s.stress)
    if (!std::isfinite(v)) return "non-finite grain stress";
  return {};
}

// The last snapshot of a segment.
const Snapshot& end_of_segment(const CrystalTrace& t, int segment) {
  const Snapshot* last = nullptr;
  for (const auto& s : t.snaps)
    if (s.macro.segment == segment) last = &s;
  if (!last) throw std::runtime_error("segment without output");
  return *last;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// The shipped files.
// ---------------------------------------------------------------------------------------------

TEST(ExtremeScenes, EveryFileParsesAndSaysWhatItStresses) {
  std::size_t files = 0;
  for (const auto& e : fs::directory_iterator(kExtremeDir)) {
    if (e.path().extension() != ".yaml") continue;
    ++files;
    SCOPED_TRACE(e.path().string());
    std::ifstream in(e.path());
    std::string first;
    std::getline(in, first);
    EXPECT_TRUE(first.rfind("# Stiff and extreme cases", 0) == 0) << first;
    const auto kind = io::scene_kind(io::YamlDocument::from_file(e.path()), {"contact", "crystal"});
    if (kind == "contact") {
      const auto scene = io::load_contact_scene(e.path());
      EXPECT_FALSE(scene.title.empty());
      EXPECT_GT(scene.cases.size(), 1u);  // every file sweeps
    } else {
      const auto scene = io::load_crystal_scene(e.path());
      EXPECT_FALSE(scene.title.empty());
      EXPECT_GT(scene.cases.size(), 1u);
    }
  }
  EXPECT_EQ(files, extreme_scenes("contact").size() + extreme_scenes("crystal").size());
  EXPECT_GE(extreme_scenes("contact").size(), 6u);
  EXPECT_GE(extreme_scenes("crystal").size(), 5u);
}

// Every contact case of every file, as shipped: to the end, admissible at every
// output.
TEST(ExtremeScenes, EveryContactCaseRunsToTheEndAdmissibly) {
  std::size_t cases = 0;
  long steps = 0, iterations = 0, cutbacks = 0;
  for (const auto& path : extreme_scenes("contact")) {
    const auto scene = io::load_contact_scene(path);
    for (const auto& c : scene.cases) {
      SCOPED_TRACE(path.filename().string() + ": " + c.name);
      ++cases;
      ContactTrace t;
      ASSERT_NO_THROW(t = run_contact(c));
      ASSERT_EQ(t.states.size(), io::output_count(c.segments));
      for (const auto& s : t.states) ASSERT_EQ(contact_inadmissible(s, c.model.law), "");
      steps += t.stats.substeps;
      iterations += t.stats.iterations;
      cutbacks += t.stats.cutbacks;
    }
  }
  measured() << "extreme contact set: " << cases << " cases, " << steps << " steps, "
             << static_cast<double>(iterations) / static_cast<double>(steps)
             << " Newton iterations per step, " << cutbacks << " cutbacks\n";
  EXPECT_GE(cases, 250u);
}

// Crystal cases that do not run to the end with the current drivers, each a
// finding (docs/extreme_cases.md, "Findings"): mixed
// control whose Newton update on the free components of L has no line search
// (aggregate.cpp try_step) at G/tau0 = 1e5 with strain steps of 1e-2 and at the
// switch from loading to a hold, a grain Newton that stalls there, and the
// power form at the reversal under confinement. The test holds them to the
// standard for a failure (a CrystalStepFailure naming the time and the grain or
// the mixed control, no NaN or Inf) and fails when one of them starts to pass,
// so that the list gets shortened.
const std::set<std::string> kKnownCrystalFailures = {};

// Every crystal case of every file, with at most two grains (the eight-grain
// cases at G/tau0 = 1e5 take minutes): to the end, admissible at every output.
// (The neg_log and reciprocal law edges were left to subslip_extreme_report for
// their tens of seconds each until their holds started elastically: the time
// went into the far branch that ElasticSegmentStart below rules out.)
TEST(ExtremeScenes, EveryCrystalCaseRunsToTheEndAdmissibly) {
  const SingleThread one;
  std::size_t cases = 0, failed = 0;
  for (const auto& path : extreme_scenes("crystal")) {
    const auto scene = io::load_crystal_scene(path);
    for (const auto& c : scene.cases) {
      const std::string key = path.filename().string() + ": " + c.name;
      SCOPED_TRACE(key);
      ++cases;
      const bool known = kKnownCrystalFailures.count(key) > 0;
      const auto laws = system_laws(c.phase);
      try {
        const CrystalTrace t = run_crystal(c, 1, 0.0, 2);
        ASSERT_EQ(t.snaps.size(), io::crystal_output_count(c.segments));
        for (const auto& s : t.snaps) ASSERT_EQ(crystal_inadmissible(s, laws), "");
        EXPECT_FALSE(known) << "runs to the end now: remove it from kKnownCrystalFailures";
      } catch (const cr::CrystalStepFailure& e) {
        ++failed;
        const std::string msg = e.what();
        EXPECT_TRUE(known) << msg;
        EXPECT_EQ(msg.find("nan"), std::string::npos) << msg;
        EXPECT_EQ(msg.find("inf"), std::string::npos) << msg;
        EXPECT_NE(msg.find("at time "), std::string::npos) << msg;
        EXPECT_TRUE(msg.find("grain ") != std::string::npos ||
                    msg.find("mixed control") != std::string::npos)
            << msg;
      }
    }
  }
  measured() << "extreme crystal set (<= 2 grains): " << cases << " cases, " << failed
             << " known failures\n";
  EXPECT_GE(cases, 150u);
}

// Every case of crystal_law_edges.yaml ends in a one-hour hold (L = 0 but for the free lateral
// L11 and L22, which keep sigma11 = sigma22 = 0) after compression. With L33 held, the hold only
// relaxes: its lateral strain is of the order of the relaxation's elastic strain, |delta
// sigma33| / E (E the smallest eigenvalue of the lattice stiffness); 4x that bounds it here.
// When a segment's free components started from the last segment's (the loading's lateral
// flow), 21 of the 45 holds converged on a far branch of the step's equations at a yield
// vertex: L11 = -L22 ~ 2e-2 /s at constant stress, lateral strains of 0.7 ... 6 in the hour.
// A segment now starts from the elastic response to its loading (Aggregate, start_segment).
TEST(ExtremeScenes, HoldsAfterLoadingOnlyRelax) {
  const SingleThread one;
  const auto scene = io::load_crystal_scene(kExtremeDir / "crystal_law_edges.yaml");
  ASSERT_EQ(scene.cases.size(), 45u);
  double worst = 0.0;
  for (const auto& c : scene.cases) {
    SCOPED_TRACE(c.name);
    ASSERT_EQ(c.segments.size(), 3u);
    const CrystalTrace t = run_crystal(c, 1, 0.0, 2);
    const auto hold_start = std::find_if(t.snaps.begin(), t.snaps.end(),
                                         [](const Snapshot& s) { return s.macro.segment == 2; });
    ASSERT_NE(hold_start, t.snaps.begin());
    const cr::MacroState& before = std::prev(hold_start)->macro;
    const cr::MacroState& end = t.snaps.back().macro;
    const double e_min =
        Eigen::SelfAdjointEigenSolver<cr::Mat6>(c.phase.stiffness).eigenvalues().minCoeff();
    const double relaxation_strain = std::abs(end.stress(2, 2) - before.stress(2, 2)) / e_min;
    for (int i : {0, 1}) {
      const double lateral = std::abs(end.strain(i, i) - before.strain(i, i));
      EXPECT_LE(lateral, 4.0 * relaxation_strain + 1e-12) << "component " << i;
      worst = std::max(worst, lateral / std::max(relaxation_strain, 1e-300));
    }
  }
  measured() << "law-edge holds: lateral strain <= " << worst << " x the relaxation's\n";
}

// ---------------------------------------------------------------------------------------------
// Contact: analytical limits.
// ---------------------------------------------------------------------------------------------

// Every case of contact_speed_viscosity.yaml slides 20 mm: the mu transient
// decays like exp(-(kappa/mu_k + xi/(mu_s v)) u) <= e^-47 and r_s = 1 to double
// precision after a few 1/u_tilde, so the end is the analytical steady state at
// the slide speed, from 1e-4 to 1e6 mm/min, eta_v 10..1e5, r_hat 1.01..6.4
// (r_hat - r_ss down to ~2e-12), to the resolution of r in the last increment.
TEST(ExtremeContact, SpeedAndViscositySweepEndsAtTheAnalyticalSteadyState) {
  const auto scene = io::load_contact_scene(kExtremeDir / "contact_speed_viscosity.yaml");
  ASSERT_EQ(scene.cases.size(), 54u);
  double worst = 0.0;
  for (const auto& c : scene.cases) {
    SCOPED_TRACE(c.name);
    const ContactTrace t = run_contact(c);
    const ct::ContactState& end = t.states.back();
    const double v = c.segments[0].velocity.norm();
    const auto ss = law::SubloadingFrictionLaw(c.model.law).steady_state(v);
    const auto dts = cr::increment_lengths(c.segments[0].duration, c.segments[0].increments,
                                           c.segments[0].growth);
    const double tol_r = ratio_resolution(c, v * dts.back(), ss.mu);
    EXPECT_EQ(end.law.r_s, 1.0);
    EXPECT_NEAR(end.law.mu, ss.mu, 1e-12 * ss.mu);
    EXPECT_NEAR(end.r, ss.r, tol_r);
    EXPECT_LT(end.r, c.model.law.overstress.r_hat);
    EXPECT_NEAR(end.vp_rate, v, 1e-9 * v);  // all the sliding is viscoplastic
    worst = std::max(worst, std::abs(end.r - ss.r) / tol_r);
  }
  measured() << "speed/viscosity sweep: worst |r - r_ss| / resolution " << worst << "\n";
}

// 2 m forward and 2 m back at 1e4 and 1e6 mm/min, in one increment, 100 or
// 10000: the end of each slide is the steady state at that speed. A single
// increment of length L slides at the rate v (1 - f_t/(alpha L)) on average
// (the traction builds up within it), which shifts r by (f_t/(alpha L)) v /
// phi_r (test_contact.cpp): below 1e-12 here.
TEST(ExtremeContact, MetreSlidesAtImpactSpeedEndAtTheSteadyState) {
  const auto scene = io::load_contact_scene(kExtremeDir / "contact_impact_metres.yaml");
  ASSERT_EQ(scene.cases.size(), 6u);
  for (const auto& c : scene.cases) {
    SCOPED_TRACE(c.name);
    const ContactTrace t = run_contact(c);
    const law::SubloadingFrictionLaw lw(c.model.law);
    for (int seg : {0, 1}) {
      size_t last = 0;
      for (size_t i = 0; i < t.states.size(); ++i)
        if (t.segment[i] == seg) last = i;
      const ct::ContactState& s = t.states[last];
      const auto& segment = c.segments[static_cast<size_t>(seg)];
      const double v = segment.velocity.norm();
      const auto ss = lw.steady_state(v);
      const auto dts = cr::increment_lengths(segment.duration, segment.increments, segment.growth);
      const double length = v * dts.back();
      const double deficit = s.traction_ratio() * c.model.initial_normal_traction /
                             (c.model.stiffness.alpha_t * length);
      const double shift = deficit * v / lw.slip_rate_slope(ss.r, 1.0);
      EXPECT_NEAR(s.r, ss.r, ratio_resolution(c, length, ss.mu) + 2.0 * shift) << "segment " << seg;
      EXPECT_NEAR(s.law.mu, ss.mu, 1e-12 * ss.mu) << "segment " << seg;
      // The traction points against the sliding: +x after the first slide, -x
      // after the second.
      EXPECT_GT(s.traction_t.x() * segment.velocity.x(), 0.0) << "segment " << seg;
      EXPECT_EQ(s.traction_t.y(), 0.0);
    }
  }
}

// The elastic slope before yield. Over the first (implicit) increment from the
// unloaded state, the viscoplastic slip is ds = dt phi(r1, r_s1) with 0 <=
// r_s1, so ds <= dt phi(r1, 0) (phi decreases in r_s), and f_t = alpha (du -
// ds): 0 <= 1 - f_t/(alpha du) <= phi(r1, 0)/v. With the 1000 graded increments
// (first ~1e-10 mm) that is the elastic slope to ~1e-6 at the stiffest alpha
// and n = 1; with n = 128 the bound is looser and the slope still elastic.
TEST(ExtremeContact, FirstIncrementFollowsTheElasticSlope) {
  const auto scene = io::load_contact_scene(kExtremeDir / "contact_stiffness_exponent.yaml");
  int checked = 0;
  double worst = 0.0;
  for (const auto& c : scene.cases) {
    if (c.segments[0].increments != 1000) continue;
    SCOPED_TRACE(c.name);
    const ContactTrace t = run_contact(c);
    const ct::ContactState& s1 = t.states.at(1);
    const double v = c.segments[0].velocity.norm();
    const double du = s1.slip.norm();
    const double alpha = c.model.stiffness.alpha_t;
    const double deficit = 1.0 - s1.traction_t.norm() / (alpha * du);
    const double bound = law::SubloadingFrictionLaw(c.model.law).slip_rate(s1.r, 0.0) / v;
    EXPECT_GE(deficit, -4 * kEps);
    EXPECT_LE(deficit, bound + 4 * kEps);
    EXPECT_LT(deficit, 1e-2);  // still elastic to 1 % in the first increment
    worst = std::max(worst, deficit);
    ++checked;
  }
  EXPECT_EQ(checked, 32);
  measured() << "first increment: largest 1 - f_t/(alpha du) = " << worst << "\n";
}

// Holds of 1, 10 and 100 hours, in one increment or 100. During a hold nothing
// slides, so the traction can only relax: f_t never grows and keeps its
// direction, the viscoplastic slip never decreases, the overstress r - r_s
// decreases. With xi = 0 mu can only fall toward mu_k (slip, no recovery); with
// xi > 0 the long holds (>= 600 min >> mu_s/xi = 11 min) end with mu back at
// mu_s: once stuck, mu - mu_s decays like exp(-xi t/mu_s) (e^-49 after the
// first 5 % of a 600 min hold).
TEST(ExtremeContact, HoldsOfHoursRelaxTheRightWay) {
  const auto scene = io::load_contact_scene(kExtremeDir / "contact_hold_hours.yaml");
  ASSERT_EQ(scene.cases.size(), 12u);
  for (const auto& c : scene.cases) {
    SCOPED_TRACE(c.name);
    const ContactTrace t = run_contact(c);
    const auto& f = c.model.law.friction;
    std::vector<size_t> hold;
    for (size_t i = 0; i < t.states.size(); ++i)
      if (t.segment[i] == 1) hold.push_back(i);
    ASSERT_EQ(hold.size(), static_cast<size_t>(c.segments[1].increments));
    const ct::ContactState& before = t.states[hold.front() - 1];
    for (size_t i : hold) {
      const ct::ContactState &s = t.states[i], &p = t.states[i - 1];
      EXPECT_LE(s.traction_t.norm(), p.traction_t.norm() * (1.0 + 4 * kEps)) << i;
      EXPECT_GT(s.traction_t.x(), 0.0) << i;
      EXPECT_GE(s.vp_slip, p.vp_slip) << i;
      EXPECT_EQ(s.slip, before.slip) << i;
      if (f.xi == 0.0) {
        EXPECT_LE(s.law.mu, p.law.mu) << i;
      }
    }
    const ct::ContactState& end = t.states[hold.back()];
    EXPECT_LT(end.r - end.law.r_s, before.r - before.law.r_s);
    EXPECT_LT(end.traction_t.norm(), before.traction_t.norm());
    // (In ONE increment the relaxation slip is spread over the whole hold at a constant rate,
    // which the exact mu update balances against recovery: mu ends ~1e-9 below mu_s.)
    if (f.xi > 0.0 && c.segments[1].duration >= 600.0 && c.segments[1].increments > 1) {
      EXPECT_NEAR(end.law.mu, f.mu_s, 1e-12 * f.mu_s);
    }
    // The re-slide after a hold with recovery peaks above the ratio the hold
    // started from.
    if (f.xi > 0.0) {
      double repeak = 0.0;
      for (size_t i = 0; i < t.states.size(); ++i)
        if (t.segment[i] == 2) repeak = std::max(repeak, t.states[i].traction_ratio());
      EXPECT_GT(repeak, before.traction_ratio());
    }
  }
}

// kappa = xi = 0: nothing drives mu, which stays exactly at its initial value
// mu_s through slides, a hold, a reversal and a turn. mu_s = mu_k: the exact
// update's drive (kappa s + xi dt)(1 - mu/mu_s) vanishes at mu = mu_s, so mu
// stays at mu_s to rounding. The rate-independent model never passes the
// normal-yield surface: r <= 1 (to the residual tolerance) and r_s <= 1.
TEST(ExtremeContact, LawEdgesKeepTheirInvariants) {
  const auto scene = io::load_contact_scene(kExtremeDir / "contact_law_edges.yaml");
  ASSERT_EQ(scene.cases.size(), 72u);
  for (const auto& c : scene.cases) {
    SCOPED_TRACE(c.name);
    const ContactTrace t = run_contact(c);
    const auto& f = c.model.law.friction;
    const bool ri = c.model.law.overstress.form == law::OverstressForm::rate_independent;
    // r = r_s <= 1 to the resolution of r in the longest increment (r - r_s is the residual).
    double du_max = 0.0;
    for (const auto& seg : c.segments)
      du_max = std::max(du_max,
                        seg.velocity.norm() *
                            cr::increment_lengths(seg.duration, seg.increments, seg.growth).back());
    const double r_resolution = ratio_resolution(c, du_max, std::min(f.mu_s, f.mu_k));
    for (const auto& s : t.states) {
      if (f.kappa == 0.0 && f.xi == 0.0) {
        ASSERT_EQ(s.law.mu, f.mu_s) << "t=" << s.time;
      } else if (f.mu_s == f.mu_k) {
        // The drive vanishes at mu_s up to the rounding of A - B mu_s: a few ulps per step,
        // which the contracting update does not amplify.
        ASSERT_NEAR(s.law.mu, f.mu_s, 8 * kEps * f.mu_s * static_cast<double>(t.states.size()))
            << "t=" << s.time;
      }
      if (ri) {
        ASSERT_LE(s.r, 1.0 + r_resolution) << "t=" << s.time;
        ASSERT_LE(s.law.r_s, 1.0);
      }
    }
  }
}

// An open contact (f_n <= 0) transmits nothing: zero traction, r = r_s = 0,
// whatever the law's parameters (contact_parser_edges.yaml ramps f_n to -1 MPa
// while sliding, then closes again).
TEST(ExtremeContact, OpenContactTransmitsNoTraction) {
  const auto scene = io::load_contact_scene(kExtremeDir / "contact_parser_edges.yaml");
  for (const auto& c : scene.cases) {
    SCOPED_TRACE(c.name);
    const ContactTrace t = run_contact(c);
    int open = 0;
    for (const auto& s : t.states) {
      if (s.traction_n > 0.0) continue;
      ++open;
      EXPECT_EQ(s.traction_t.norm(), 0.0);
      EXPECT_EQ(s.r, 0.0);
      EXPECT_EQ(s.law.r_s, 0.0);
    }
    EXPECT_GT(open, 0);
    EXPECT_GT(t.states.back().traction_n, 0.0);  // closed again at the end
    EXPECT_GT(t.states.back().traction_ratio(), 0.0);
  }
}

// ---------------------------------------------------------------------------------------------
// Crystal: analytical limits.
// ---------------------------------------------------------------------------------------------

// One slip system in simple shear is a contact (test_crystal_physics.cpp): with
// no hardening transient left after a slip of 1 (kappa/mu_k = 50: e^-50; xi = 0
// so mu_ss = mu_k) and r_s = 1 (u_tilde = 200), the end of the forward shear is
// tau/tau0 = mu_k r_ss(gamma_dot) for every G/tau0 (1e2..1e5), rate (1e-6..1e4
// /s) and slip step of 1e-2. Resolution of r: the grain tolerance 1e-12 (twice)
// plus the rounding of tau = tau_trial - G dgamma with a trial up to G
// dgamma/(mu tau0) = 500 times the CRSS (a few eps each: 12 eps G dgamma / (mu
// tau0)).
TEST(ExtremeCrystal, SingleSlipShearEndsAtTheAnalyticalSteadyState) {
  const SingleThread one;
  const auto scene = io::load_crystal_scene(kExtremeDir / "crystal_single_slip_stiffness.yaml");
  ASSERT_EQ(scene.cases.size(), 64u);
  std::set<std::pair<double, double>> done;  // (tau0, forward rate): the reverse rate is irrelevant
  double worst = 0.0;
  for (const auto& c : scene.cases) {
    const double tau0 = c.phase.custom_settings.tau0;
    const double rate = c.segments[0].velocity_gradient(0, 1);
    if (!done.insert({tau0, rate}).second) continue;
    SCOPED_TRACE(c.name);
    auto forward = c;
    forward.segments.resize(1);
    const CrystalTrace t = run_crystal(forward);
    const Snapshot& end = t.snaps.back();
    const auto& lw = c.phase.custom_settings.law;
    const auto ss = law::SubloadingFrictionLaw(lw).steady_state(rate);
    const double G = c.phase.stiffness(5, 5) / 2.0;  // Mandel C_66 = 2 G
    const double dgamma = rate * forward.segments[0].duration / forward.segments[0].increments;
    const double tol_r = 2e-12 + 12 * kEps * G * dgamma / (ss.mu * tau0);
    EXPECT_EQ(end.r_s[0], 1.0);
    EXPECT_NEAR(end.crss[0] / tau0, ss.mu, 1e-13 * ss.mu);
    EXPECT_NEAR(end.macro.stress(0, 1) / (ss.mu * tau0), ss.r, tol_r);
    EXPECT_NEAR(end.rate[0], rate, 1e-9 * rate);
    worst = std::max(worst, std::abs(end.macro.stress(0, 1) / (ss.mu * tau0) - ss.r) / tol_r);
  }
  EXPECT_EQ(done.size(), 16u);
  measured() << "single slip steady state: worst |r - r_ss| / resolution " << worst << "\n";
}

namespace {

// Cubic compliance S = C^-1 (Mandel); under uniaxial stress along a cube axis
// sigma_33 = (eps_33 - eps_p,33) / S_33.
double cube_axis_compliance(const cr::Mat6& c) {
  return c.inverse()(2, 2);
}

}  // namespace

// A copper crystal pulled along [001] with the lateral stresses free: the eight
// {111}<110> systems with Schmid factor 1/sqrt(6) slip alike, and with no
// hardening (mu_s = mu_k, kappa = xi = 0) and small strain the axial stress
// saturates at
//   sigma_33 = sqrt(6) mu tau0 r_ss(gamma_dot),  gamma_dot = sqrt(6) eps_dot /
//   8
// (D^p_33 = 8 gamma_dot / sqrt(6) = eps_dot once the elastic rate has died
// out), to the mixed- control tolerance (lateral and shear stresses within 1e-8
// of the stress scale enter tau_a with weights <= 1/2 each: 3e-8 sqrt(6), 2e-7
// relative allowed). Checked for G/tau0 = C44/tau0 from 1e2 to 1e5, rates 1e-6,
// 1 and 1e4 /s and strain steps of 1e-2 and 1e-4. At every output the
// small-strain identity sigma = C : (eps - sum_a gamma_a P_a) holds (the
// recorded slips against the macro strain, no tolerance but accumulated
// rounding), and before yield (every r_a <= 0.5) the axial response is elastic
// up to the subloading slip: gamma_a <= H(r_a) (the slip integral of the cot
// form, since r_s,a <= r_a and r_s,a = R(gamma_a) under monotone loading), so
// |sigma_33 S_33 - eps_33| <= sum_a |P_a,33| H(r_a). During the final hold
// (L_33 = 0, lateral stresses free) |sigma_33| only relaxes.
// The [001] copper crystal at G/tau0 = 1e5 (crystal_fcc_schmid_stiff.yaml, 1000 increments of
// loading), its increments split into 2 and 32: tension, reversal and hold with the lateral L
// free. The fourfold axis makes L11 = L22 exact, and the eight systems at their vertex leave
// the mode L11 = -L22 almost free (the free stresses' Jacobian has singular values 6.5e6 and
// 5.7e-5 MPa s). Newton's exact step on the free components moved L along that mode by 2.5e-8 /s
// to remove a residual part of 5e-12 MPa, and the hold failed at every cutback ("not reduced
// along the Newton update"); the least change that meets the tolerance keeps the symmetry to
// round-off and runs to the end. Round-off here is what one ulp of the stresses does along that
// mode: at |sigma| ~ 2 MPa, 4.4e-16 MPa / 5.7e-5 MPa s = 7.8e-12 /s, about 1e-11 of the largest
// |L| (1 /s in the reversal), which the bound allows (and 2500 times below the exact step's
// 2.5e-8). (It was 1e-12, below one ulp's worth: met while the semismooth step read unset values
// after an inadmissible system, which made its rounding at the reversal's first step whatever
// the stack held; since those are set, the slow-tension run ends at 2.7e-12.)
TEST(ExtremeCrystal, FccSchmidCubeKeepsItsFourfoldSymmetryWhenRefined) {
  const SingleThread one;
  const auto scene = io::load_crystal_scene(kExtremeDir / "crystal_fcc_schmid_stiff.yaml");
  int runs = 0;
  for (const auto& c : scene.cases) {
    if (c.name.find("tau0=0.754,") != 0 || c.name.find("increments=1000") == std::string::npos)
      continue;
    for (int k : {2, 32}) {
      SCOPED_TRACE(c.name + " x" + std::to_string(k));
      CrystalTrace t;
      ASSERT_NO_THROW(t = run_crystal(c, k));
      ++runs;
      double largest = 0.0, asymmetry = 0.0;
      for (const auto& s : t.snaps) {
        largest = std::max(largest, s.macro.velocity_gradient.cwiseAbs().maxCoeff());
        asymmetry = std::max(
            asymmetry, std::abs(s.macro.velocity_gradient(0, 0) - s.macro.velocity_gradient(1, 1)));
      }
      EXPECT_LE(asymmetry, 1e-11 * largest);
    }
  }
  EXPECT_EQ(runs, 6);
}

TEST(ExtremeCrystal, FccSchmidSaturationElasticSlopeAndRelaxation) {
  const SingleThread one;
  const auto scene = io::load_crystal_scene(kExtremeDir / "crystal_fcc_schmid_stiff.yaml");
  ASSERT_EQ(scene.cases.size(), 18u);
  const auto systems = cr::slip_systems(cr::SlipFamily::fcc_111_110);
  std::vector<cr::Vec6> schmid;
  for (const auto& sys : systems)
    schmid.push_back(
        cr::mandel_from_symmetric(0.5 * (sys.s * sys.m.transpose() + sys.m * sys.s.transpose())));
  double worst_saturation = 0.0, worst_identity = 0.0;
  int elastic_outputs = 0;
  for (const auto& c : scene.cases) {
    SCOPED_TRACE(c.name);
    const CrystalTrace t = run_crystal(c);
    const auto& settings = c.phase.family_settings[0];
    const law::SubloadingFrictionLaw lw(settings.law);
    const double mu = settings.law.friction.mu_s, tau0 = settings.tau0;
    const double rate = c.segments[0].velocity_gradient(2, 2);
    const double s33 = cube_axis_compliance(c.phase.stiffness);
    const double c_max = c.phase.stiffness.cwiseAbs().maxCoeff();
    // Saturation at the end of the tension.
    const Snapshot& top = end_of_segment(t, 0);
    const double predicted =
        std::sqrt(6.0) * mu * tau0 * lw.steady_state(std::sqrt(6.0) * rate / 8.0).r;
    const double rel = top.macro.stress(2, 2) / predicted - 1.0;
    EXPECT_LT(std::abs(rel), 2e-7);
    worst_saturation = std::max(worst_saturation, std::abs(rel));
    // The eight slip in the direction of their Schmid factor and share the plastic slip. How
    // they share it is set by resolved-stress differences within the mixed-control tolerance
    // (1e-8), strongly amplified near rate independence, so only to 10 %: a system that does
    // not slip, or slips the wrong way, is an O(1) difference.
    double mean = 0.0;
    for (int a = 0; a < 12; ++a)
      if (std::abs(schmid[static_cast<size_t>(a)](2)) > 0.1)
        mean += std::abs(top.slip[static_cast<size_t>(a)]) / 8.0;
    for (int a = 0; a < 12; ++a) {
      const double m = schmid[static_cast<size_t>(a)](2), slip = top.slip[static_cast<size_t>(a)];
      if (std::abs(m) < 0.1) continue;  // the four with m = 0
      EXPECT_GT(slip * m, 0.0) << "system " << a;
      EXPECT_NEAR(std::abs(slip), mean, 0.1 * mean) << "system " << a;
    }
    // The small-strain identity at every output, and the elastic slope before
    // yield.
    double n_steps = 0.0;
    for (const auto& seg : c.segments) n_steps += seg.increments;
    double sigma_max = 0.0, strain_max = 0.0;
    for (const auto& s : t.snaps) {
      cr::Vec6 plastic = cr::Vec6::Zero();
      for (int a = 0; a < 12; ++a)
        plastic += s.slip[static_cast<size_t>(a)] * schmid[static_cast<size_t>(a)];
      const cr::Vec6 elastic = cr::mandel_from_symmetric(s.macro.strain) - plastic;
      const cr::Vec6 sigma = cr::mandel_from_symmetric(s.macro.stress);
      // Accumulated rounding of the stress, strain and slip sums: a few eps per step of the
      // largest stress and of C times the largest strain or plastic strain seen so far.
      sigma_max = std::max(sigma_max, s.macro.stress.cwiseAbs().maxCoeff());
      strain_max = std::max(
          {strain_max, s.macro.strain.cwiseAbs().maxCoeff(), plastic.cwiseAbs().maxCoeff()});
      const double tol = 64 * n_steps * kEps * (sigma_max + c_max * strain_max + 1e-300);
      const double err = (sigma - c.phase.stiffness * elastic).cwiseAbs().maxCoeff();
      EXPECT_LE(err, tol) << "t=" << s.macro.time;
      worst_identity = std::max(worst_identity, err / tol);
      if (s.macro.segment != 0 || s.macro.time == 0.0) continue;
      double r_max = 0.0, bound = 0.0;
      for (int a = 0; a < 12; ++a) {
        const double r = s.ratio[static_cast<size_t>(a)];
        r_max = std::max(r_max, r);
        bound += std::abs(schmid[static_cast<size_t>(a)](2)) * lw.subloading_slip_integral(r);
      }
      if (r_max > 0.5) continue;
      ++elastic_outputs;
      const double eps33 = s.macro.strain(2, 2);
      EXPECT_LE(std::abs(s.macro.stress(2, 2) * s33 - eps33), bound + 1e-8 * eps33)
          << "t=" << s.macro.time;
    }
    // Relaxation during the hold.
    const Snapshot* previous = &end_of_segment(t, 1);
    const double sign = previous->macro.stress(2, 2) > 0.0 ? 1.0 : -1.0;
    for (const auto& s : t.snaps) {
      if (s.macro.segment != 2) continue;
      const double scale = std::abs(previous->macro.stress(2, 2));
      EXPECT_LE(sign * s.macro.stress(2, 2), scale * (1.0 + 1e-7)) << "t=" << s.macro.time;
      EXPECT_GT(sign * s.macro.stress(2, 2), 0.0) << "t=" << s.macro.time;
      previous = &s;
    }
  }
  EXPECT_GT(elastic_outputs, 100);
  measured() << "Cu [001]: worst |sigma_sat / predicted - 1| " << worst_saturation
             << ", worst identity error / bound " << worst_identity << ", " << elastic_outputs
             << " pre-yield outputs checked\n";
}

// ---------------------------------------------------------------------------------------------
// Kernel regressions found by the extreme set (crystal_kernel.cpp).
// ---------------------------------------------------------------------------------------------

namespace {

// The flow rule of every system of a converged implicit step, from the outputs
// alone: slipping systems satisfy G(r, r_s, |dgamma|, dt) = 0 (the law's
// residual, ratio units), idle ones have r <= r_s (3.12); returns the largest
// violation.
template <int N>
double flow_rule_violation(const cr::Phase<N>& ph, const cr::GrainState<N>& s0,
                           const cr::GrainState<N>& s1, double dt) {
  const auto r = cr::loading_ratio(ph, s1);
  double worst = 0.0;
  for (int a = 0; a < ph.slip_count; ++a) {
    const double slip = std::abs(s1.slip(a) - s0.slip(a));
    const auto& lw = ph.laws[static_cast<size_t>(a)];
    const double g = slip > 0.0 ? lw.flow_residual(r(a), s1.r_s(a), slip, dt).value
                                : std::max(0.0, r(a) - s1.r_s(a));
    worst = std::max(worst, std::abs(g));
  }
  return worst;
}

law::LawParameters hardening_law(law::OverstressForm form) {
  law::LawParameters p;
  p.friction = {1.0, 3.0, 10.0, 0.0};
  p.subloading = {law::SubloadingFunction::cot, 200.0};
  p.overstress = {form, 1e-3, 16.0, 1.6};
  return p;
}

}  // namespace

// Regression. An FCC grain of crystal_cubic_families.yaml (G/tau0 = 1e5) in
// mixed-control tension, dumped at the step the grain Newton could not finish
// (at any cutback: the case failed after 20). Systems 10 (r > r_s at zero slip,
// so on the flow-rule branch) wanted a negative step; the line search projected
// it back to zero, which left the other eleven with a step computed for a slip
// system 10 never takes. With A of rank 5 and entries ~1e5 that direction was
// no descent direction: the line search stalled at rows ~1e-7. Fixed by holding
// such systems at zero and re-solving for the others (newton_step in
// crystal_kernel.cpp).
TEST(ExtremeKernel, StiffFccGrainConvergesWithASystemHeldAtZero) {
  cr::Phase<12> ph;
  std::vector<cr::Vec3> s, m;
  for (const auto& sys : cr::slip_systems(cr::SlipFamily::fcc_111_110)) {
    s.push_back(sys.s);
    m.push_back(sys.m);
  }
  ph.kinematics = cr::Kinematics::finite_rotation;
  ph.tau0 = cr::SlipTypes<12>::VecN::Constant(0.7692);
  ph.laws.assign(12, law::SubloadingFrictionLaw(hardening_law(law::OverstressForm::exponential)));
  ph.assemble(s, m, cr::isotropic_from_E_nu(200000.0, 0.3));
  cr::Mat3 L = cr::Mat3::Zero(), g;
  L(0, 0) = -0.00065650810867669783, L(1, 1) = -0.0003434502213443662, L(2, 2) = 0.001;
  g << -0.28617562747823172, -0.81728280673195608, 0.50015230086222406, 0.83514341746472631,
      -0.46864145306754357, -0.28794211350908672, 0.46972223973618582, 0.33529688678405267,
      0.81666211814320422;
  cr::GrainState<12> s0;
  s0.reset(12, g, cr::SlipTypes<12>::VecN::Ones(12));
  s0.stress << 0.65548502111457196, 0.63423218047617524, 1.2146320642172697, -1.1290344223390605,
      1.8154815550824139, -0.24331597389109305;
  s0.mu << 1.000051489618907, 1.1185781976423645, 1.0898236764117557, 1.024043950123805,
      1.0994856707836882, 1.0022770163868069, 1.0021105231592078, 1.0122635659984254,
      1.0334205593541745, 1.0017131805505246, 1.0018148887360727, 1.0072360254832176;
  s0.r_s << 0.035637878815791307, 0.99799467652175544, 0.9916240656626284, 0.79273648651095119,
      0.99480646832017428, 0.28133787375353103, 0.26833208543917003, 0.62154523189541355,
      0.86902276800343803, 0.24591746987681781, 0.21787370836771161, 0.4612701333704462;
  s0.rate << 2.2385667790778021e-08, 0.0010318835458273407, -0.00075511879619210979,
      -0.00012728262591496725, -0.00089477587558769328, 0, 0, -9.1346132307198471e-05,
      0.0002126660023186189, 0, 0, 0;
  const double dt = 10.0 / 1048576.0;  // the increment of 10 s after 20 halvings
  cr::GrainState<12> s1 = s0;
  const auto rep = cr::implicit_grain_step(ph, s0, L, dt, cr::GrainStepOptions{}, s1, nullptr);
  ASSERT_TRUE(rep.ok) << rep.why << " (system " << rep.system << ", " << rep.iterations << ")";
  // Converged: every flow rule to 1e-11 (the tolerance 1e-12 plus the rounding
  // of r at stresses ~1 MPa and slips ~1e-8).
  EXPECT_LT(flow_rule_violation(ph, s0, s1, dt), 1e-11);
  EXPECT_LE(rep.iterations, 10);
}

// Regression (finding 6 of docs/extreme_cases.md). The first mixed-control step of
// MixedControl.StiffGrainsWithStrainStepsOf1e2ThroughALoadToHoldSwitch: a virgin copper grain at
// C44/tau0 = 1e5 and a strain step of 1e-2 (the lateral rates are the mixed control's first
// guess). Systems 0, 4, 10 and 11 slip in the trial's direction early in the iteration; the
// others' slip then turns their shear. The Newton step takes such a slip to zero, but at zero
// the system's direction follows its shear and its row there is large, so the line search
// halved those slips instead, 54 times, and the step "converged" with them at 1e-18 in their
// stale directions, loaded up to r = 1.9 the other way. Since 2026-11-30 the unknowns are signed
// slips, each system's residual continuous through zero: a system whose shear turns passes
// through zero to the other direction, and nothing is left stale (13 Newton iterations here).
TEST(ExtremeKernel, StiffFccGrainLeavesNoSystemInAStaleSlipDirection) {
  const auto built = cr::build_phase<12>(subslip::testing::copper_phase(0.754));
  const cr::Phase<12>& ph = built.phase;
  cr::Mat3 g, L;
  g << 0.23570226039551567, 0.70710678118654746, 0.66666666666666674, 0.23570226039551578,
      -0.70710678118654768, 0.66666666666666674, 0.94280904158206336, 5.5511151231257827e-17,
      -0.33333333333333337;
  L << -0.00069142663533895026, 4.5712949764366877e-05, 0.00026102042023441274,
      4.5712949764366877e-05, -0.00030802695000898926, 3.1975338350615075e-05,
      0.00026102042023441274, 3.1975338350615075e-05, 0.001;
  const double dt = 10.0;
  cr::GrainState<12> s0;
  s0.reset(12, g, built.initial_mu);
  cr::GrainState<12> s1 = s0;
  const auto rep = cr::implicit_grain_step(ph, s0, L, dt, cr::GrainStepOptions{}, s1, nullptr);
  ASSERT_TRUE(rep.ok) << rep.why << " (system " << rep.system << ", " << rep.iterations << ")";
  // Every system slips along its end shear or not at all, and its flow rule holds: a system left
  // in a stale direction has a slip against its shear and a residual of order its r.
  const cr::SlipTypes<12>::VecN tau = ph.schmid.transpose() * s1.stress;
  for (int a = 0; a < 12; ++a) {
    const double dgamma = s1.slip(a) - s0.slip(a);
    EXPECT_GE(dgamma * tau(a), 0.0)
        << "system " << a << ": slip " << dgamma << ", shear " << tau(a);
  }
  EXPECT_LT(flow_rule_violation(ph, s0, s1, dt), 1e-11);
  measured() << "stiff FCC first step: " << rep.iterations << " Newton iterations\n";
}

// Regression. With the power overstress the flow residual behaves like
// -slip^(1/n) at zero slip: its slope is infinite there (and infinite x 0 = NaN
// in the unknown z = slip^(1/n)). A system with r > r_s > 0 that starts from
// zero slip (no previous rate) made the first Newton step NaN, and every grain
// step of crystal_law_edges.yaml's power cases failed "after 0 iterations". Now
// such a system gets the scalar start (make_admissible) like the r_s = 0 case.
TEST(ExtremeKernel, PowerFormSystemStartsFromZeroSlip) {
  cr::Phase<Eigen::Dynamic> ph;
  ph.kinematics = cr::Kinematics::small_strain;
  ph.tau0 = cr::SlipTypes<Eigen::Dynamic>::VecN::Constant(1, 10.0);
  ph.laws.assign(1, law::SubloadingFrictionLaw(hardening_law(law::OverstressForm::power)));
  ph.assemble({cr::Vec3::UnitX()}, {cr::Vec3::UnitY()}, cr::isotropic_from_G_nu(1e4, 0.3));
  for (double r_s : {1e-8, 0.3, 0.9}) {
    SCOPED_TRACE("r_s = " + std::to_string(r_s));
    cr::GrainState<Eigen::Dynamic> s0;
    s0.reset(1, cr::Mat3::Identity(), cr::SlipTypes<Eigen::Dynamic>::VecN::Constant(1, 1.0));
    s0.r_s(0) = r_s;
    s0.stress(5) = std::sqrt(2.0) * 10.0 * (r_s + 0.2);  // Mandel sqrt2 sigma_12: r = r_s + 0.2
    cr::Mat3 L = cr::Mat3::Zero();
    L(0, 1) = 1e-3;
    const double dt = 1e-3;
    cr::GrainState<Eigen::Dynamic> s1 = s0;
    const auto rep = cr::implicit_grain_step(ph, s0, L, dt, cr::GrainStepOptions{}, s1, nullptr);
    ASSERT_TRUE(rep.ok) << rep.why << " after " << rep.iterations;
    EXPECT_GT(std::abs(s1.slip(0)), 0.0);
    EXPECT_LT(flow_rule_violation(ph, s0, s1, dt), 1e-11);
  }
}

// ---------------------------------------------------------------------------------------------
// Forward Euler: where it goes unstable.
//
// Forward Euler moves the traction by df_t = alpha_t (du - dt phi(r, r_s)), r =
// f_t/(f_n mu). Linearised about steady sliding with mu and r_s frozen (they
// move on the slip scales 1/kappa and 1/u_tilde; the r_s mode's rate pi u_tilde
// v / 2 ~ 1e2 /min is 1e-4 of lambda below), a traction perturbation is
// multiplied by 1 - lambda dt per step, lambda = alpha_t phi_r / (f_n mu):
// stable for dt < 2/lambda. A crystal slip system reads the same with alpha_t
// -> A_aa
// (= G in single slip) and f_n -> tau0. The windows [0.9, 1.1] x 2/lambda leave
// the amplification at 0.8 or 1.2 per step, 400 steps: 1e-39 or 1e31, no
// ambiguity.
// The damping test itself: study::forward_euler_damps_*_perturbation.
// ---------------------------------------------------------------------------------------------

TEST(ExtremeForwardEuler, ContactStabilityLimitIsTwoOverLambda) {
  const law::LawParameters p = subslip::testing::paper_law();  // the paper's section 5 fit
  const law::SubloadingFrictionLaw lw(p);
  const double v = 1.0, fn = 5.56;
  for (double alpha : {1e5, 1e6, 1e8}) {
    SCOPED_TRACE("alpha = " + std::to_string(alpha));
    io::ContactCase c;
    c.model.law = p;
    c.model.initial_law_state = {p.friction.mu_s, 0.0};
    c.model.stiffness = {alpha, alpha};
    c.model.initial_normal_traction = fn;
    ct::Segment seg;
    seg.velocity = ct::Vec2(v, 0.0);
    seg.duration = 30.0;  // 30 mm: mu and r_s at their attractors
    seg.normal_traction = fn;
    seg.increments = 3000;
    seg.growth = 1.004;
    c.segments = {seg};
    const ct::ContactState steady = run_contact(c).states.back();
    const auto ss = lw.steady_state(v);
    ASSERT_NEAR(steady.r, ss.r, 1e-8);
    const double lambda = alpha * lw.slip_rate_slope(ss.r, 1.0) / (fn * ss.mu);
    // The closed form at steady sliding, exponential form: phi_r = n/(eta_v
    // (r_hat - r)) + n v + v/(r_hat - r) (differentiate (e^{n x} - 1)/(eta_v
    // (r_hat - r)) and use phi = v).
    const auto& o = p.overstress;
    const double gap = o.r_hat - ss.r;
    EXPECT_NEAR(lambda, alpha * (o.n / (o.eta_v * gap) + o.n * v + v / gap) / (fn * ss.mu),
                1e-10 * lambda);
    const double dt_crit = 2.0 / lambda;
    EXPECT_TRUE(study::forward_euler_damps_contact_perturbation(lw, c.model.stiffness, steady, v,
                                                                0.9 * dt_crit));
    EXPECT_FALSE(study::forward_euler_damps_contact_perturbation(lw, c.model.stiffness, steady, v,
                                                                 1.1 * dt_crit));
    // By default forward Euler refuses the unstable step (the driver then cuts it back) and
    // takes the stable one.
    for (double f : {0.9, 1.1}) {
      const auto a = ct::forward_euler_step(lw, c.model.stiffness, steady,
                                            ct::Vec2(v * f * dt_crit, 0.0), fn, f * dt_crit);
      EXPECT_EQ(a.ok, f < 1.0) << a.why;
      if (!a.ok) {
        EXPECT_NE(a.why.find("stability limit"), std::string::npos) << a.why;
      }
    }
    measured() << "forward Euler, contact alpha=" << alpha
               << " MPa/mm: dt_crit = 2/lambda = " << dt_crit << " min (slip " << v * dt_crit
               << " mm)\n";
  }
}

TEST(ExtremeForwardEuler, SingleSlipStabilityLimitIsTwoOverLambda) {
  const double tau0 = 1.0, rate = 1.0;
  law::LawParameters p;
  p.friction = {1.0, 2.0, 0.0, 0.0};  // no hardening: the implicit run reaches the steady state
  p.subloading = {law::SubloadingFunction::cot, 200.0};
  p.overstress = {law::OverstressForm::exponential, 1e-3, 16.0, 1.6};
  const law::SubloadingFrictionLaw lw(p);
  for (double g_over_tau0 : {1e2, 1e5}) {
    SCOPED_TRACE("G/tau0 = " + std::to_string(g_over_tau0));
    cr::Phase<Eigen::Dynamic> ph;
    ph.kinematics = cr::Kinematics::small_strain;
    ph.tau0 = cr::SlipTypes<Eigen::Dynamic>::VecN::Constant(1, tau0);
    ph.laws.assign(1, lw);
    ph.assemble({cr::Vec3::UnitX()}, {cr::Vec3::UnitY()},
                cr::isotropic_from_G_nu(g_over_tau0 * tau0, 0.3));
    cr::Mat3 L = cr::Mat3::Zero();
    L(0, 1) = rate;
    cr::GrainState<Eigen::Dynamic> steady;
    steady.reset(1, cr::Mat3::Identity(), cr::SlipTypes<Eigen::Dynamic>::VecN::Constant(1, 1.0));
    for (int i = 0; i < 1000; ++i) {  // slip 1 in steps of 1e-3: r_s = 1
      cr::GrainState<Eigen::Dynamic> next = steady;
      ASSERT_TRUE(cr::implicit_grain_step(ph, steady, L, 1e-3, {}, next, nullptr).ok);
      steady = next;
    }
    // Nothing drives mu (kappa = xi = 0): it stays at mu_s, and law::steady_state's mu is 0/0.
    ASSERT_EQ(steady.mu(0), p.friction.mu_s);
    const double r = cr::loading_ratio(ph, steady)(0);
    ASSERT_NEAR(r, lw.steady_state(rate).r, 1e-9);
    const double lambda = ph.interaction(0, 0) * lw.slip_rate_slope(r, 1.0) / (steady.mu(0) * tau0);
    EXPECT_NEAR(ph.interaction(0, 0), g_over_tau0 * tau0,
                1e-9 * g_over_tau0);  // A = G
    auto stable = [&](double dt) {
      return study::forward_euler_damps_grain_perturbation(ph, steady, L, dt);
    };
    EXPECT_TRUE(stable(0.9 * 2.0 / lambda));
    EXPECT_FALSE(stable(1.1 * 2.0 / lambda));
    measured() << "forward Euler, single slip G/tau0=" << g_over_tau0
               << ": dt_crit = 2/lambda = " << 2.0 / lambda << " s (strain step "
               << rate * 2.0 / lambda << ")\n";
  }
}

// Regression (include/subslip/integrators/scalar_root.hpp). With the power
// overstress at n = 128 the slip of an early increment is far below the
// smallest double (dt r^128 / eta_v ~ 1e-550 mm), the previous rate is a
// denormal, and the flow residual's derivative overflows to infinity at the
// warm start z = (1e-319)^(1/128). The bracketed Newton took an infinite slope
// as "double precision cannot resolve F here" and declared convergence with G =
// +0.5: the contact of contact_stiffness_exponent.yaml (power, alpha = 1e7, n =
// 128) then stayed elastic up to r = 1.796 (r_hat = 1.8) instead of sliding.
// Now every increment satisfies its flow rule: G within the tolerance, or G < 0
// with the slip at the underflow limit (the exact slip is not representable,
// and zero is the closest double).
TEST(ExtremeContact, PowerFormN128SatisfiesTheFlowRuleInEveryIncrement) {
  const auto scene = io::load_contact_scene(kExtremeDir / "contact_stiffness_exponent.yaml");
  for (const char* name : {"form=power,alpha_t=1.0e7,n=128,increments=1000",
                           "form=power,alpha_t=1.0e8,n=128,increments=1000"}) {
    SCOPED_TRACE(name);
    const auto& c = case_named(scene, name);
    const law::SubloadingFrictionLaw lw(c.model.law);
    for (int k : {1, 32}) {
      const ContactTrace t = run_contact(c, k);
      auto fine = c.segments;  // one output per increment of the split run
      fine[0].increments *= k;
      fine[0].growth = std::pow(fine[0].growth, 1.0 / k);
      ContactTrace all;
      hs::run_history(c.model, fine, c.integrator, [&](const ct::ContactState& s, int seg) {
        all.states.push_back(s);
        all.segment.push_back(seg);
      });
      for (size_t i = 1; i < all.states.size(); ++i) {
        const auto &s0 = all.states[i - 1], &s1 = all.states[i];
        const double ds = s1.vp_slip - s0.vp_slip, dt = s1.time - s0.time;
        const auto fr = lw.flow_residual(s1.r, s1.law.r_s, ds, dt);
        const double g = fr.value;
        // The solver iterates in z = ds^(1/n): z is resolved to 4 eps, ds to 4 n eps, r to
        // alpha 4 n eps ds / (f_n mu), and G to dG/dr times that; the bracket-collapse exit leaves
        // a few times more (8x).
        const double resolution =
            8.0 * (c.integrator.residual_tolerance + fr.d_r * c.model.stiffness.alpha_t * 4.0 *
                                                         lw.slip_exponent() * kEps * ds /
                                                         (s1.traction_n * s1.law.mu));
        // G > 0 is a step that stopped short of the root (the bug: +0.5); the bracketed
        // solver only does that within its tolerance or resolution. G < 0 is the bracket end on the
        // far side of a root that double precision cannot place (near r_hat, or a slip below
        // 1e-300).
        const bool underflow = ds < 1e-300 && g < 0.0;
        ASSERT_LE(g, resolution) << "split " << k << ", increment " << i << ", slip " << ds
                                 << ", r = " << s1.r;
        ASSERT_TRUE(-g <= 2.0 * resolution || underflow)
            << "split " << k << ", increment " << i << ": G = " << g << " (resolution "
            << resolution << ", dG/dr " << fr.d_r << "), slip " << ds << ", r = " << s1.r;
      }
      // It slides: the viscoplastic rate carries the imposed speed (the bug left it at 1e-308,
      // elastic). (Its steady r is within an ulp of r_hat: 0.8^128 = 950 (1.8 - r) gives
      // r_hat - r ~ 4e-16.)
      EXPECT_GT(t.states.back().vp_rate, 0.5 * c.segments[0].velocity.norm());
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Convergence under step refinement: the implicit integrator is first order, so
// the error against a reference with every increment split into 32 falls by ~2
// per halving; the observed order over 1, 2, 4 splits must lie in [0.8, 1.3]
// (order 0.5 or 2 would fail).
// ---------------------------------------------------------------------------------------------

namespace {

double observed_order(double e1, double e4) {
  return std::log2(e1 / e4) / 2.0;
}

double contact_error(const ContactTrace& t, const ContactTrace& ref, double scale) {
  EXPECT_EQ(t.states.size(), ref.states.size());
  double worst = 0.0;
  for (size_t i = 0; i < std::min(t.states.size(), ref.states.size()); ++i)
    worst = std::max(worst, (t.states[i].traction_t - ref.states[i].traction_t).norm() / scale);
  return worst;
}

double crystal_error(const CrystalTrace& t, const CrystalTrace& ref, double scale) {
  EXPECT_EQ(t.snaps.size(), ref.snaps.size());
  double worst = 0.0;
  for (size_t i = 0; i < std::min(t.snaps.size(), ref.snaps.size()); ++i)
    worst = std::max(
        worst, (t.snaps[i].macro.stress - ref.snaps[i].macro.stress).cwiseAbs().maxCoeff() / scale);
  return worst;
}

}  // namespace

// Every 1000-increment case of the stiffness/exponent file (alpha 1e5..1e8
// MPa/mm, n 1..128, exponential and power), a 100-hour hold, and 2 m at 1e6
// mm/min. Error: max over the outputs of |f_t - f_t,ref| / (f_n mu_s).
TEST(ExtremeConvergence, ContactErrorsFallAtFirstOrderUnderStepRefinement) {
  std::vector<std::pair<std::string, std::string>> picks = {
      {"contact_hold_hours.yaml", "duration=6000,increments=1,xi=0"},
      {"contact_impact_metres.yaml", "speed=1.0e6,increments=10000"}};
  const auto stiff = io::load_contact_scene(kExtremeDir / "contact_stiffness_exponent.yaml");
  for (const auto& c : stiff.cases)
    if (c.segments[0].increments == 1000)
      picks.push_back({"contact_stiffness_exponent.yaml", c.name});
  for (const auto& [file, name] : picks) {
    SCOPED_TRACE(file + ": " + name);
    const auto scene = io::load_contact_scene(kExtremeDir / file);
    const auto& c = case_named(scene, name);
    const double scale = c.model.initial_normal_traction * c.model.law.friction.mu_s;
    const ContactTrace ref = run_contact(c, 32);
    const double e1 = contact_error(run_contact(c, 1), ref, scale);
    const double e2 = contact_error(run_contact(c, 2), ref, scale);
    const double e4 = contact_error(run_contact(c, 4), ref, scale);
    EXPECT_LT(e2, e1);
    EXPECT_LT(e4, e2);
    EXPECT_GE(observed_order(e1, e4), 0.8) << e1 << " " << e2 << " " << e4;
    EXPECT_LE(observed_order(e1, e4), 1.3) << e1 << " " << e2 << " " << e4;
  }
}

// Crystals: single slip at G/tau0 = 1e2 sheared at 1e-2 /s and reversed at 1e4
// /s (slip steps of 1e-2), and the Cu [001] crystal at G/tau0 = 1e4, 1e4 /s, in
// steps of 1e-4 then 1e-2 with mixed control. Error: max over the outputs of
// max_ij |sigma_ij - sigma_ref,ij| / (mu_s tau0). (Cases whose steps are longer
// than the elastic unloading length at a reversal are not first-order yet: see
// ExtremeFindings below.)
TEST(ExtremeConvergence, CrystalErrorsFallAtFirstOrderUnderStepRefinement) {
  const SingleThread one;
  const std::pair<const char*, const char*> picks[] = {
      {"crystal_single_slip_stiffness.yaml",
       "tau0=1000,loading[0].L[0][1]=1.0e-2,loading[1].L[0][1]=-1.0e4"},
      {"crystal_fcc_schmid_stiff.yaml", "tau0=7.54,L[2][2]=1.0e4,increments=1000"}};
  for (const auto& [file, name] : picks) {
    SCOPED_TRACE(std::string(file) + ": " + name);
    const auto scene = io::load_crystal_scene(kExtremeDir / file);
    const auto& c = case_named(scene, name);
    const auto& settings =
        c.phase.custom_systems.empty() ? c.phase.family_settings[0] : c.phase.custom_settings;
    const double scale = settings.law.friction.mu_s * settings.tau0;
    const CrystalTrace ref = run_crystal(c, 32);
    const double e1 = crystal_error(run_crystal(c, 1), ref, scale);
    const double e2 = crystal_error(run_crystal(c, 2), ref, scale);
    const double e4 = crystal_error(run_crystal(c, 4), ref, scale);
    EXPECT_LT(e2, e1);
    EXPECT_LT(e4, e2);
    EXPECT_GE(observed_order(e1, e4), 0.8) << e1 << " " << e2 << " " << e4;
    EXPECT_LE(observed_order(e1, e4), 1.3) << e1 << " " << e2 << " " << e4;
  }
}

// ---------------------------------------------------------------------------------------------
// Adaptive stepping (IntegratorOptions::tolerance > 0): every accepted step is
// an output.
// ---------------------------------------------------------------------------------------------

namespace {

// max over the reference outputs of |f_t,ref - f_t| with the adaptive run
// interpolated linearly in time (it resolves fast transients, e.g. the
// relaxation at a hold onset, that a fixed reference step jumps over: the
// reference is right at its nodes, not in between).
double adaptive_error(const ContactTrace& run, const ContactTrace& ref, double scale) {
  double worst = 0.0;
  for (const auto& r : ref.states) {
    const auto hi =
        std::lower_bound(run.states.begin(), run.states.end(), r.time,
                         [](const ct::ContactState& s, double t) { return s.time < t; });
    const size_t k =
        std::clamp<size_t>(static_cast<size_t>(hi - run.states.begin()), 1, run.states.size() - 1);
    const auto &a = run.states[k - 1], &b = run.states[k];
    const double w =
        b.time > a.time ? std::clamp((r.time - a.time) / (b.time - a.time), 0.0, 1.0) : 1.0;
    const ct::Vec2 f = (1.0 - w) * a.traction_t + w * b.traction_t;
    worst = std::max(worst, (f - r.traction_t).norm() / scale);
  }
  return worst;
}

long steps_in_segment(const ContactTrace& t, int segment) {
  return std::count(t.segment.begin(), t.segment.end(), segment);
}

}  // namespace

// A 100-hour hold given as ONE increment and 2 m at 1e6 mm/min given as ONE
// increment each way: with a tolerance of 1e-3 the hold takes under 100 steps
// (the traction relaxes within ~1e-8 min at its onset, so a uniform step
// resolving that would need ~1e12 steps) and each 2 m slide under 200, and the
// states they end in are the ones the fine fixed-step runs give.
TEST(ExtremeAdaptive, HoldsOfHoursAndMetreSlidesAtImpactTakeFewSteps) {
  const double tol = 1e-3;
  {
    const auto scene = io::load_contact_scene(kExtremeDir / "contact_hold_hours.yaml");
    const auto& c = case_named(scene, "duration=6000,increments=1,xi=0.009");
    const ContactTrace t = run_contact(c, 1, tol);
    for (const auto& s : t.states) ASSERT_EQ(contact_inadmissible(s, c.model.law), "");
    const long hold = steps_in_segment(t, 1);
    EXPECT_LE(hold, 100);
    // The fine reference: the same history in the 100 graded hold increments,
    // split into 16.
    const ContactTrace ref =
        run_contact(case_named(scene, "duration=6000,increments=100,xi=0.009"), 16);
    const double scale = c.model.initial_normal_traction * c.model.law.friction.mu_s;
    const double err = adaptive_error(t, ref, scale);
    EXPECT_LT(err, 10 * tol);
    EXPECT_NEAR(t.states.back().law.mu, ref.states.back().law.mu, 1e-9);
    measured() << "adaptive, 100 h hold: " << hold << " steps in the hold, " << t.stats.substeps
               << " in all, " << t.stats.rejected << " rejected; max error " << err << "\n";
  }
  {
    const auto scene = io::load_contact_scene(kExtremeDir / "contact_impact_metres.yaml");
    const auto& c = case_named(scene, "speed=1.0e6,increments=1");
    const ContactTrace t = run_contact(c, 1, tol);
    for (const auto& s : t.states) ASSERT_EQ(contact_inadmissible(s, c.model.law), "");
    const auto ss = law::SubloadingFrictionLaw(c.model.law).steady_state(1e6);
    for (int seg : {0, 1}) {
      EXPECT_LE(steps_in_segment(t, seg), 200) << "segment " << seg;
      size_t last = 0;
      for (size_t i = 0; i < t.states.size(); ++i)
        if (t.segment[i] == seg) last = i;
      // The last steps are long (tens of mm): the ratio resolution of a 100 mm
      // increment.
      EXPECT_NEAR(t.states[last].r, ss.r, ratio_resolution(c, 100.0, ss.mu)) << "segment " << seg;
    }
    measured() << "adaptive, 2 m at 1e6 mm/min each way: " << steps_in_segment(t, 0) << " + "
               << steps_in_segment(t, 1) << " steps, " << t.stats.rejected << " rejected\n";
  }
}

// The error against a fine fixed-step reference falls as the tolerance
// tightens, and stays below it on these two monotone slides (quasi-static and
// near r_hat at impact): the flow contracts perturbations, so local errors do
// not accumulate.
TEST(ExtremeAdaptive, ErrorFallsAsTheToleranceTightens) {
  const auto scene = io::load_contact_scene(kExtremeDir / "contact_speed_viscosity.yaml");
  for (const char* name :
       {"speed=1.0e6,eta_v=1.0e5,r_hat=1.01", "speed=1.0e-4,eta_v=10,r_hat=1.8"}) {
    SCOPED_TRACE(name);
    const auto& c = case_named(scene, name);
    const double scale = c.model.initial_normal_traction * c.model.law.friction.mu_s;
    const ContactTrace ref = run_contact(c, 16);
    double previous = std::numeric_limits<double>::infinity();
    for (double tol : {1e-2, 1e-3, 1e-4, 1e-5}) {
      const ContactTrace t = run_contact(c, 1, tol);
      const double err = adaptive_error(t, ref, scale);
      EXPECT_LT(err, previous) << "tol " << tol;
      EXPECT_LT(err, tol) << "tol " << tol;
      previous = err;
      measured() << name << " tol " << tol << ": " << t.stats.substeps << " steps, error " << err
                 << "\n";
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Findings of this set, fixed.
// ---------------------------------------------------------------------------------------------

// An increment whose elastic trial passes through zero traction (a reversal)
// used to end with r_s = min(r_s0, r_end) ~ 0.5: along the way r fell to 0, and
// (3.12) makes r_s follow r down wherever no viscoplastic sliding occurs, so the
// exact r_s after the crossing is 0, regrown (3.11) only by the slip of the
// rest of the increment. The implicit steps now start r_s from the lowest r on
// the elastic predictor path (contact_point.cpp implicit_step,
// crystal_kernel.cpp ImplicitSolver). Checked against the same reversal in 1000
// increments, which resolves the crossing: r_s and the traction after one
// increment agree with it to the first-order error of one backward-Euler step
// (0.05 in r_s, 0.05 f_n mu in traction), where the old step was off by ~0.5
// in r_s (the whole subloading transition after the reversal was lost).
TEST(ExtremeFindings, ReversalWithinOneIncrementResetsTheSubloadingRatio) {
  const auto scene = io::load_contact_scene(kExtremeDir / "contact_hold_hours.yaml");
  io::ContactCase c = case_named(scene, "duration=60,increments=1,xi=0");
  c.segments.resize(1);  // 1 mm at 1 mm/min: r_s = 1, f_t ~ 0.66 MPa
  ct::Segment back = c.segments[0];
  back.velocity = -back.velocity;
  back.duration = 1e-6;  // 1e-6 mm back: the trial passes zero and ends at -0.34 MPa
  back.growth = 1.0;
  auto reversal_in = [&](int increments) {
    auto run = c;
    back.increments = increments;
    run.segments.push_back(back);
    return run_contact(run);
  };
  const ContactTrace trace_fine = reversal_in(1000);
  const ct::ContactState& end_fine = trace_fine.states.back();
  // The fine run did cross zero (the traction reversed) and r_s went to ~0 there.
  double lowest_rs = 1.0;
  for (const auto& s : trace_fine.states)
    if (s.time > c.segments[0].duration) lowest_rs = std::min(lowest_rs, s.law.r_s);
  EXPECT_LT(end_fine.traction_t.x() * c.segments[0].velocity.x(), 0.0);
  EXPECT_LT(lowest_rs, 0.01);
  // Errors at the end, traction in units of the yield traction f_n mu. The purely elastic
  // answer (the old step: no slip, the trial traction) is the yardstick for the traction.
  const double yield = end_fine.traction_n * end_fine.law.mu;
  const ct::ContactState start = run_contact(c).states.back();  // before the reversal
  const double elastic =
      start.traction_t.x() + c.model.stiffness.alpha_t * back.velocity.x() * back.duration;
  const double elastic_error = std::abs(elastic - end_fine.traction_t.x()) / yield;
  std::vector<double> traction_error;
  for (int k : {1, 4, 16}) {
    const ct::ContactState end = reversal_in(k).states.back();
    EXPECT_EQ(contact_inadmissible(end, c.model.law), "") << k << " increments";
    EXPECT_NEAR(end.law.r_s, end_fine.law.r_s, 0.05) << k << " increments";
    traction_error.push_back(std::abs(end.traction_t.x() - end_fine.traction_t.x()) / yield);
    measured() << "contact reversal in " << k << " increment(s): r_s " << end.law.r_s
               << " (1000 increments: " << end_fine.law.r_s << ", lowest " << lowest_rs
               << "), traction error " << traction_error.back()
               << " (purely elastic step: " << elastic_error << ")\n";
  }
  // One increment takes most of the slip after the crossing, and refining converges.
  EXPECT_LT(traction_error[0], 0.5 * elastic_error);
  EXPECT_LT(traction_error[1], traction_error[0]);
  EXPECT_LT(traction_error[2], 0.5 * traction_error[1]);
  // Forward Euler from the same start, at the same 1000 steps (dt = 1e-9 min; 2/lambda is
  // 5e-8 min here), agrees with the implicit run.
  const law::SubloadingFrictionLaw lw(c.model.law);
  auto forward_euler = [&](int steps) {
    ct::ContactState s = start;
    const double dt = back.duration / steps;
    for (int i = 0; i < steps; ++i) {
      const auto a =
          ct::forward_euler_step(lw, c.model.stiffness, s, back.velocity * dt, s.traction_n, dt);
      EXPECT_TRUE(a.ok) << a.why;
      s = a.state;
    }
    return s;
  };
  const ct::ContactState fe_fine = forward_euler(1000);
  measured() << "forward Euler, 1000 steps: r_s " << fe_fine.law.r_s << ", traction error "
             << std::abs(fe_fine.traction_t.x() - end_fine.traction_t.x()) / yield << "\n";
  EXPECT_NEAR(fe_fine.law.r_s, end_fine.law.r_s, 0.05);
  EXPECT_LT(std::abs(fe_fine.traction_t.x() - end_fine.traction_t.x()) / yield, 0.05);
  // Adaptive stepping sees the crossing (the sliding velocity flips within the step) and
  // refines the reversal given as one increment to within the tolerance's reach (10 tol, as
  // in ExtremeAdaptive).
  const double tol = 1e-3;
  auto run = c;
  back.increments = 1;
  run.segments.push_back(back);
  const ContactTrace adaptive = run_contact(run, 1, tol);
  const ct::ContactState& end = adaptive.states.back();
  measured() << "adaptive (tol " << tol << "): " << steps_in_segment(adaptive, 1)
             << " steps in the reversal, r_s " << end.law.r_s << ", traction error "
             << std::abs(end.traction_t.x() - end_fine.traction_t.x()) / yield << "\n";
  EXPECT_GT(steps_in_segment(adaptive, 1), 1);
  EXPECT_NEAR(end.law.r_s, end_fine.law.r_s, 0.05);
  EXPECT_LT(std::abs(end.traction_t.x() - end_fine.traction_t.x()) / yield, 10 * tol);
}

// The crystal image: one slip system sheared to steady state (r_s = 1), then
// sheared back by 1.5 times its elastic strain in one increment (the trial
// shear ends at -0.5 of the steady one, below r_s0 = 1: without the fix the
// implicit grain step stays elastic with r_s = r_end ~ 0.5), against the same
// in 1000 increments (r_s ~ 0.14). implicit_grain_step starts a system that
// slips against its shear at the start of the step from r_s = 0; the multi-slip
// cases this once broke
// (systems restarting at r_s = 0 while others slip, U(0) infinite) run through
// ExtremeScenes.EveryCrystalCaseRunsToTheEndAdmissibly.
TEST(ExtremeFindings, CrystalReversalWithinOneIncrementResetsTheSubloadingRatio) {
  const SingleThread one;
  const auto scene = io::load_crystal_scene(kExtremeDir / "crystal_single_slip_stiffness.yaml");
  const io::CrystalCase* found = nullptr;
  for (const auto& c : scene.cases)
    if (c.phase.custom_settings.tau0 == 10.0 && c.segments[0].velocity_gradient(0, 1) == 1e-2)
      found = &c;
  ASSERT_NE(found, nullptr);
  io::CrystalCase c = *found;
  c.segments.resize(1);  // slip 1 at 1e-2 /s: r_s = 1
  const CrystalTrace forward = run_crystal(c);
  const double tau_end = forward.snaps.back().macro.stress(0, 1);
  const double G = c.phase.stiffness(5, 5) / 2.0;  // Mandel C_66 = 2 G
  cr::LoadSegment back = c.segments[0];
  back.velocity_gradient(0, 1) = -1e-2;
  back.duration = 1.5 * tau_end / G / 1e-2;  // shear strain 1.5 tau/G back
  back.growth = 1.0;
  auto coarse = c, fine = c;
  back.increments = 1;
  coarse.segments.push_back(back);
  back.increments = 1000;
  fine.segments.push_back(back);
  const CrystalTrace tc = run_crystal(coarse), tf = run_crystal(fine);
  const auto laws = system_laws(c.phase);
  for (const auto* t : {&tc, &tf})
    for (const auto& s : t->snaps) ASSERT_EQ(crystal_inadmissible(s, laws), "");
  const Snapshot &end_c = tc.snaps.back(), &end_f = tf.snaps.back();
  double lowest_rs = 1.0;
  for (const auto& s : tf.snaps)
    if (s.macro.segment == 1) lowest_rs = std::min(lowest_rs, s.r_s[0]);
  EXPECT_LT(end_f.macro.stress(0, 1) * tau_end, 0.0);  // the shear did reverse
  EXPECT_LT(lowest_rs, 0.01);
  const double crss = end_f.crss[0];
  measured() << "single-slip r_s after the reversal: one increment " << end_c.r_s[0]
             << ", 1000 increments " << end_f.r_s[0] << " (lowest " << lowest_rs
             << "); tau/CRSS: " << end_c.macro.stress(0, 1) / crss << " vs "
             << end_f.macro.stress(0, 1) / crss << "\n";
  EXPECT_NEAR(end_c.r_s[0], end_f.r_s[0], 0.05);
  EXPECT_NEAR(end_c.macro.stress(0, 1) / crss, end_f.macro.stress(0, 1) / crss, 0.05);
}

constexpr char kStiffHcpPyramidalCa[] = "families=[hcp_pyramidal_ca],tau0=0.163";

// The eight-grain aggregate the <= 2-grain sweep above leaves out, at its
// hardest: first-order pyramidal <c+a> alone (12 systems, nearly degenerate
// active sets) at C44/tau0 = 1e5, 1e-2 strain steps, tension, compression and a
// one-hour hold under mixed control. It once stopped at t = 0.18 s: a system
// reversing inside a step took its slip over the time after the elastic
// predictor's zero crossing, so the grain stress jumped (by ~4 % of tau0) as
// that predictor passed zero and the mixed-control Newton could not settle; and
// the grain Newton stalled where a system's step went below zero slip.
TEST(ExtremeFindings, HcpPyramidalCaAggregateAtStiffRatioRunsToTheEnd) {
  const SingleThread one;
  const auto scene = io::load_crystal_scene(kExtremeDir / "crystal_hcp_families.yaml");
  const io::CrystalCase* found = &case_named(scene, kStiffHcpPyramidalCa);
  ASSERT_EQ(found->orientations.size(), 8u);
  const CrystalTrace t = run_crystal(*found);
  ASSERT_EQ(t.snaps.size(), io::crystal_output_count(found->segments));
  const auto laws = system_laws(found->phase);
  for (const auto& s : t.snaps) ASSERT_EQ(crystal_inadmissible(s, laws), "");
  // Mixed control: the lateral stresses stay at their zero targets (to the default
  // tolerance, 1e-10 of the stress scale, with room for the scale: the axial stress).
  const Snapshot& end = t.snaps.back();
  for (const auto& s : t.snaps) {
    EXPECT_LT(std::abs(s.macro.stress(0, 0)), 1e-8);
    EXPECT_LT(std::abs(s.macro.stress(1, 1)), 1e-8);
  }
  measured() << "HCP <c+a> alone, 8 grains, C44/tau0 = 1e5: axial stress at the end of the hold "
             << end.macro.stress(2, 2) << " MPa\n";
}

// The same aggregate with adaptive steps (tolerance 1e-2). It stopped at t = 233.7 s: a system
// idle in one step ended the grain Newton with a leftover slip of 3e-31 against its shear, which
// counted as a reversal and reset its r_s from 0.73 to 4e-15 with r still at 0.73. The next step
// then had to relax that whole overstress at once, and the error estimate refused every step
// down to dt = 2e-14 s. Leftover slips of idle systems are now set to zero.
TEST(ExtremeFindings, HcpPyramidalCaAggregateRunsAdaptivelyAtStiffRatio) {
  const SingleThread one;
  const auto scene = io::load_crystal_scene(kExtremeDir / "crystal_hcp_families.yaml");
  const io::CrystalCase* found = &case_named(scene, kStiffHcpPyramidalCa);
  CrystalTrace t;
  ASSERT_NO_THROW(t = run_crystal(*found, 1, 1e-2));
  const auto laws = system_laws(found->phase);
  for (const auto& s : t.snaps) ASSERT_EQ(crystal_inadmissible(s, laws), "");
  EXPECT_EQ(t.snaps.back().macro.segment, 2);  // the end of the hold
  EXPECT_EQ(t.snaps.back().macro.segment_time, 3600.0);
  measured() << "HCP <c+a> alone, 8 grains, C44/tau0 = 1e5, adaptive 1e-2: " << t.stats.increments
             << " steps, " << t.stats.rejected << " rejected, " << t.stats.cutbacks
             << " cutbacks\n";
}

// The same aggregate's first 30 s of tension with backward Euler's estimate (order 1) at 1e-2,
// with a run tolerance (the free stresses at the tighter of stress_tolerance and T/100 of the
// smallest CRSS) against stress_tolerance named. The lateral split of L is set to 1e-4 of the
// CRSS only by the laws' rate sensitivity, and the estimate reads the slip rates: with the free
// stresses brought to T/100 of the CRSS alone the split jumped by 40 % of L from step to step and
// the estimate refused down to 1e-4 s steps (400 steps here, about 200 times the steps over the
// whole case; MixedControl::free_stress_tolerance). Order 1's steps are the named run's.
TEST(ExtremeFindings, HcpPyramidalCaOrderOneStepsAreNotSetByTheFreeStressTolerance) {
  const SingleThread one;
  const auto scene = io::load_crystal_scene(kExtremeDir / "crystal_hcp_families.yaml");
  io::CrystalCase tension = case_named(scene, kStiffHcpPyramidalCa);
  tension.segments.resize(1);
  tension.segments[0].duration = 30.0;
  tension.options.order = 1;
  io::CrystalCase named = tension;
  named.options.stress_tolerance_follows_tolerance = false;
  const CrystalTrace tied_run = run_crystal(tension, 1, 1e-2);
  const CrystalTrace named_run = run_crystal(named, 1, 1e-2);
  for (const CrystalTrace* t : {&tied_run, &named_run})
    ASSERT_EQ(t->snaps.back().macro.segment_time, 30.0);
  measured() << "HCP <c+a> alone, 30 s of tension, order 1 at 1e-2: tied "
             << tied_run.stats.increments << " steps, " << tied_run.stats.mixed_iterations
             << " sweeps; named " << named_run.stats.increments << " steps, "
             << named_run.stats.mixed_iterations << " sweeps\n";
  EXPECT_LE(static_cast<double>(tied_run.stats.increments),
            1.1 * static_cast<double>(named_run.stats.increments));
  EXPECT_LE(tied_run.stats.mixed_iterations, named_run.stats.mixed_iterations);
}
