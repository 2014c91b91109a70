// fric_ of libsubslip_fe, called through its C ABI as Abaqus calls it, against the contact
// history driver (history::run_history) on the shipped paper scenes of figures 7 to 9 (every
// case of their sweeps); its derivatives against central differences; refused increments.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "subslip/fe/abaqus.h"
#include "subslip/fe/fric_layout.h"
#include "subslip/history/contact_history.hpp"
#include "subslip/io/contact_scene.hpp"

namespace {

namespace ct = subslip::contact;
namespace lw = subslip::law;

std::vector<double> fric_props(const lw::LawParameters& law, double alpha_t, double tolerance) {
  const auto code_of_function = [](lw::SubloadingFunction f) {
    return f == lw::SubloadingFunction::cot       ? 1.0
           : f == lw::SubloadingFunction::neg_log ? 2.0
                                                  : 3.0;
  };
  const auto code_of_form = [](lw::OverstressForm f) {
    return f == lw::OverstressForm::exponential ? 1.0 : f == lw::OverstressForm::power ? 2.0 : 3.0;
  };
  return {law.friction.mu_s,
          law.friction.mu_k,
          law.friction.kappa,
          law.friction.xi,
          code_of_function(law.subloading.function),
          law.subloading.u_tilde,
          code_of_form(law.overstress.form),
          law.overstress.eta_v,
          law.overstress.n,
          law.overstress.r_hat,
          alpha_t,
          0.0,
          0.0,
          tolerance};
}

std::string last_message() {
  char buffer[512];
  subslip_fe_last_message(buffer, sizeof buffer);
  return buffer;
}

// One contact point driven through fric_ (3D: NFDIR = 2).
struct FricPoint {
  std::vector<double> props;
  std::vector<double> statev = std::vector<double>(SUBSLIP_FRIC_NSTATV, 0.0);
  std::array<double, 2> tau{};
  std::array<double, 4> ddtddg{};
  std::array<double, 2> ddtddp{};
  std::array<double, 2> dslip{};
  double sed = 0, sfd = 0;
  int lm = 0;
  int nfdir = 2;

  double call(const std::array<double, 2>& dgam, double press, double dpress, double dtime) {
    std::array<double, 4> ddtddt{};
    std::array<double, 2> taulm{}, slip{}, time{0, 0}, temp{293, 293};
    std::array<double, 3> coords{}, rcoord{};
    std::array<double, 4> drot{1, 0, 0, 1};
    std::array<double, 2> predef{};
    double ddpddh = 0, pnewdt = 1, chrlngth = 1;
    const int kstep = 1, kinc = 1, noel = 1, npt = 1, node = 1, npatch = 1, mcrd = 3, npred = 0;
    const int nstatv = static_cast<int>(statev.size()), nprops = static_cast<int>(props.size());
    char names[3][80];
    std::memset(names, ' ', sizeof names);
    fric_(&lm, tau.data(), ddtddg.data(), ddtddp.data(), dslip.data(), &sed, &sfd, ddtddt.data(),
          &pnewdt, statev.data(), dgam.data(), taulm.data(), &press, &dpress, &ddpddh, slip.data(),
          &kstep, &kinc, time.data(), &dtime, &noel, names[0], names[1], names[2], &npt, &node,
          &npatch, coords.data(), rcoord.data(), drot.data(), temp.data(), predef.data(), &nfdir,
          &mcrd, &npred, &nstatv, &chrlngth, props.data(), &nprops, 80, 80, 80);
    return pnewdt;
  }
};

// The largest |value| of a series, for relative comparisons.
double scale_of(const std::vector<double>& v) {
  double s = 0.0;
  for (double x : v) s = std::max(s, std::abs(x));
  return s;
}

struct Series {
  std::vector<double> t1, t2, mu, r_s, r, vp_slip;
  void add(const ct::ContactState& s) {
    t1.push_back(s.traction_t(0));
    t2.push_back(s.traction_t(1));
    mu.push_back(s.law.mu);
    r_s.push_back(s.law.r_s);
    r.push_back(s.r);
    vp_slip.push_back(s.vp_slip);
  }
};

void expect_series(const std::vector<double>& fric, const std::vector<double>& driver,
                   const std::string& what) {
  ASSERT_EQ(fric.size(), driver.size()) << what;
  const double scale = scale_of(driver);
  int reported = 0;
  for (std::size_t k = 0; k < fric.size(); ++k)
    if (!(std::abs(fric[k] - driver[k]) <= 1e-10 * scale) && reported++ < 3)
      ADD_FAILURE() << what << " at output " << k << ": " << fric[k] << " vs " << driver[k];
}

// Every case of a contact scene: fric_ along its history with the increments the driver takes
// equals the driver's output to 1e-10 (relative to each series' largest value).
void expect_scene(const std::string& scene) {
  const auto loaded =
      subslip::io::load_contact_scene(std::string(SUBSLIP_SOURCE_DIR) + "/inputs/" + scene);
  ASSERT_FALSE(loaded.cases.empty());
  for (const auto& c : loaded.cases) {
    SCOPED_TRACE(scene + ", case " + c.name);
    ASSERT_EQ(c.integrator.tolerance, 0.0) << "fixed increments expected";
    Series driver, fric;
    subslip::history::run_history(c.model, c.segments, c.integrator,
                                  [&](const ct::ContactState& s, int) { driver.add(s); });

    FricPoint point{
        fric_props(c.model.law, c.model.stiffness.alpha_t, c.integrator.residual_tolerance)};
    ASSERT_EQ(c.model.initial_law_state.r_s, 0.0);
    ASSERT_EQ(c.model.initial_law_state.mu, c.model.law.friction.mu_s);
    ct::ContactState start = ct::initial_state(c.model);
    fric.add(start);
    double press = c.model.initial_normal_traction;
    for (const ct::Segment& seg : c.segments) {
      ASSERT_EQ(seg.output_every, 1);
      ASSERT_FALSE(seg.output_at_times);
      const double fn_start = press;
      double t = 0.0;
      for (double dt : ct::increment_lengths(seg)) {
        t += dt;
        const double next = ct::normal_traction_at(seg, c.model.stiffness, fn_start, t);
        const std::array<double, 2> dgam{seg.velocity(0) * dt, seg.velocity(1) * dt};
        ASSERT_EQ(point.call(dgam, next, next - press, dt), 1.0) << last_message();
        ASSERT_EQ(point.lm, 0);
        press = next;
        ct::ContactState s;
        s.traction_t = {point.tau[0], point.tau[1]};
        s.law.mu = point.statev[SUBSLIP_FRIC_MU - 1];
        s.law.r_s = point.statev[SUBSLIP_FRIC_R_S - 1];
        s.r = point.statev[SUBSLIP_FRIC_R - 1];
        s.vp_slip = point.statev[SUBSLIP_FRIC_VP_SLIP - 1];
        fric.add(s);
      }
    }
    expect_series(fric.t1, driver.t1, "traction 1");
    expect_series(fric.t2, driver.t2, "traction 2");
    expect_series(fric.mu, driver.mu, "mu");
    expect_series(fric.r_s, driver.r_s, "r_s");
    expect_series(fric.r, driver.r, "r");
    expect_series(fric.vp_slip, driver.vp_slip, "viscoplastic slip");
    EXPECT_GT(scale_of(driver.r_s), 0.5);  // the scene slides
  }
}

TEST(FeFric, PaperFigure7ScenesEqualTheContactDriver) {
  for (const char* scene : {"paper_fig7_n.yaml", "paper_fig7_eta_v.yaml", "paper_fig7_r_hat.yaml"})
    expect_scene(scene);
}

TEST(FeFric, PaperFigure8SceneEqualsTheContactDriver) {
  expect_scene("paper_fig8_speed.yaml");
}

TEST(FeFric, PaperFigure9SceneEqualsTheContactDriver) {
  expect_scene("paper_fig9_peak_bottom.yaml");
}

lw::LawParameters paper_law() {
  lw::LawParameters law;  // the section 4 constants (the library's defaults)
  return law;
}

// DDTDDG and DDTDDP against central differences of TAU while sliding obliquely to the traction
// under a changing pressure.
TEST(FeFric, DerivativesAreThoseOfTheTraction) {
  FricPoint p{fric_props(paper_law(), 1e6, 0.0)};
  const double press = 5.56, dt = 0.01;
  for (int k = 0; k < 40; ++k) ASSERT_EQ(p.call({2e-5, 0.0}, press, 0.0, dt), 1.0);
  const std::array<double, 2> dgam{1e-5, 1.5e-5};
  const double next = 5.4;
  FricPoint at = p;
  ASSERT_EQ(at.call(dgam, next, next - press, dt), 1.0);
  for (int j = 0; j < 3; ++j) {
    const double h = j < 2 ? 1e-11 : 1e-6;
    FricPoint plus = p, minus = p;
    auto gp = dgam, gm = dgam;
    double pp = next, pm = next;
    if (j < 2) {
      gp[static_cast<std::size_t>(j)] += h;
      gm[static_cast<std::size_t>(j)] -= h;
    } else {
      pp += h;
      pm -= h;
    }
    ASSERT_EQ(plus.call(gp, pp, pp - press, dt), 1.0);
    ASSERT_EQ(minus.call(gm, pm, pm - press, dt), 1.0);
    for (int i = 0; i < 2; ++i) {
      const double fd =
          (plus.tau[static_cast<std::size_t>(i)] - minus.tau[static_cast<std::size_t>(i)]) /
          (2 * h);
      const double given = j < 2 ? at.ddtddg[static_cast<std::size_t>(i + 2 * j)]
                                 : at.ddtddp[static_cast<std::size_t>(i)];
      const double scale = j < 2 ? 1e6 : 1.0;
      EXPECT_NEAR(given, fd, 1e-5 * scale) << i << ", " << j;
    }
  }
  // The viscoplastic part of the slip and its dissipation.
  const double ft = std::hypot(at.tau[0], at.tau[1]);
  EXPECT_GT(at.sfd, 0.0);
  EXPECT_NEAR(at.sed, ft * ft / 2e6, 1e-12 * ft * ft);
  for (int a = 0; a < 2; ++a)
    EXPECT_NEAR(
        at.dslip[static_cast<std::size_t>(a)],
        dgam[static_cast<std::size_t>(a)] -
            (at.tau[static_cast<std::size_t>(a)] - p.tau[static_cast<std::size_t>(a)]) / 1e6,
        1e-15);
}

// Contact points updated at once from OpenMP threads, each sliding its own way: the results
// equal the serial ones bitwise.
TEST(FeFric, ConcurrentCallsGiveTheSerialResults) {
  constexpr int kPoints = 16;
  std::vector<double> props = fric_props(paper_law(), 1e6, 0.0);
  props[SUBSLIP_FRIC_MU_K - 1] *= 1.0 + 1e-9;  // a material no other test made
  auto run = [&](int p) {
    FricPoint point{props};
    const double angle = 0.4 * p;
    for (int k = 0; k < 60; ++k) {
      const double s = k < 40 ? 1e-5 : -1e-5;
      if (point.call({s * std::cos(angle), s * std::sin(angle)}, 5.56, 0.0, 0.01) != 1.0)
        ADD_FAILURE() << last_message();
    }
    return point;
  };
  std::vector<FricPoint> parallel(kPoints, FricPoint{props});
#pragma omp parallel for num_threads(4) schedule(dynamic)
  for (int p = 0; p < kPoints; ++p) parallel[static_cast<std::size_t>(p)] = run(p);
  for (int p = 0; p < kPoints; ++p) {
    const FricPoint serial = run(p);
    EXPECT_EQ(serial.tau, parallel[static_cast<std::size_t>(p)].tau) << p;
    EXPECT_EQ(serial.statev, parallel[static_cast<std::size_t>(p)].statev) << p;
    EXPECT_EQ(serial.ddtddg, parallel[static_cast<std::size_t>(p)].ddtddg) << p;
  }
}

// Refused increments: PNEWDT < 1, TAU and STATEV as they came in, a message naming the cause.
TEST(FeFric, BadInputIsRefusedAndLeavesTauAndStatev) {
  FricPoint p{fric_props(paper_law(), 1e6, 0.0)};
  for (int k = 0; k < 5; ++k) ASSERT_EQ(p.call({1e-5, 0.0}, 5.56, 0.0, 0.01), 1.0);
  auto refused = [&](FricPoint q, const std::array<double, 2>& dgam, double dtime,
                     const std::string& naming) {
    const auto tau = q.tau;
    const auto statev = q.statev;
    EXPECT_LT(q.call(dgam, 5.56, 0.0, dtime), 1.0);
    EXPECT_EQ(q.tau, tau);
    EXPECT_EQ(q.statev, statev);
    EXPECT_NE(last_message().find(naming), std::string::npos) << last_message();
  };
  FricPoint short_statev = p;
  short_statev.statev.resize(8);
  refused(short_statev, {1e-5, 0.0}, 0.01, "NSTATV = 8");
  FricPoint short_props = p;
  short_props.props.pop_back();
  refused(short_props, {1e-5, 0.0}, 0.01, "NPROPS = 13");
  FricPoint bad_law = p;
  bad_law.props[SUBSLIP_FRIC_R_HAT - 1] = 0.9;
  refused(bad_law, {1e-5, 0.0}, 0.01, "r_hat");
  refused(p, {std::nan(""), 0.0}, 0.01, "DGAM");
  refused(p, {1e-5, 0.0}, 0.0, "DTIME = 0");
  // No pressure: frictionless (LM = 2), nothing changed.
  FricPoint open = p;
  const auto statev = open.statev;
  EXPECT_EQ(open.call({1e-5, 0.0}, 0.0, -5.56, 0.01), 1.0);
  EXPECT_EQ(open.lm, 2);
  EXPECT_EQ(open.statev, statev);
}

}  // namespace
