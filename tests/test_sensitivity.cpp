// Forward sensitivities of a contact point's path to the law's constants, carried through the
// implicit updates, against central finite differences of whole runs.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "paper_law.hpp"
#include "subslip/history/contact_history.hpp"
#include "subslip/law/parameter_table.hpp"

namespace {

using namespace subslip;

// The outputs compared: f_t/f_n, mu and r_s at every output state.
struct Path {
  std::vector<double> values;
  std::vector<law::ParameterGradient> gradients;
};

contact::Segment slide(double speed, double distance, int increments, double growth = 1.0) {
  contact::Segment s;
  s.velocity = contact::Vec2(speed, 0.0);
  s.duration = distance / std::abs(speed);
  s.normal_control = contact::NormalControl::traction;
  s.normal_traction = 5.56;
  s.increments = increments;
  s.growth = growth;
  return s;
}

// Sliding from rest at 1 mm/min (graded steps through the peak), a hold, a faster slide, a
// reversal through zero traction (the step's path dips below r_s) and a slide under a rising
// normal traction: every branch of the implicit update.
std::vector<contact::Segment> history_of_every_branch() {
  std::vector<contact::Segment> h;
  h.push_back(slide(1.0, 1.0, 150, 1.03));
  contact::Segment hold = slide(0.0, 0.0, 20);
  hold.duration = 0.5;
  h.push_back(hold);
  h.push_back(slide(20.0, 0.4, 60));
  h.push_back(slide(-5.0, 0.3, 60));
  contact::Segment loaded = slide(-5.0, 0.2, 40);
  loaded.normal_traction = 7.0;
  h.push_back(loaded);
  return h;
}

contact::ContactModel model_of(const law::LawParameters& p) {
  contact::ContactModel m;
  m.law = p;
  m.initial_law_state.mu = p.friction.mu_s;  // as a scene without `initial: {mu: ...}`
  m.stiffness = {1.0e6, 1.0e6};
  m.initial_normal_traction = 5.56;
  return m;
}

history::IntegratorOptions options() {
  history::IntegratorOptions opt;
  opt.residual_tolerance = 1e-15;  // the differences below resolve 1e-6 of the derivatives
  return opt;
}

void append(Path& path, const contact::ContactState& s, const contact::ContactSensitivity* d) {
  path.values.insert(path.values.end(), {s.traction_ratio(), s.law.mu, s.law.r_s});
  if (d) path.gradients.insert(path.gradients.end(), {d->traction_ratio(s), d->mu, d->r_s});
}

Path run_plain(const law::LawParameters& p) {
  Path path;
  history::run_history(model_of(p), history_of_every_branch(), options(),
                       [&](const contact::ContactState& s, int) { append(path, s, nullptr); });
  return path;
}

Path run_with_sensitivities(const law::LawParameters& p) {
  Path path;
  history::run_history(model_of(p), history_of_every_branch(), options(), true,
                       [&](const contact::ContactState& s, const contact::ContactSensitivity& d,
                           int) { append(path, s, &d); });
  return path;
}

// d(outputs)/d(constant k) by central differences of whole runs, Richardson-extrapolated from
// relative steps 2e-3 and 1e-3 (truncation error of order h^4, about 1e-12). Smaller steps let
// through the round-off of the runs themselves (steps of 1e-5 miss by 1e-5 of the largest
// derivative): the difference of two runs resolves only about 1e-13 of f_t/f_n.
std::vector<double> finite_difference(const law::LawParameters& p, std::size_t k) {
  const auto& info = law::kLawParameters[k];
  auto central = [&](double h) {
    law::LawParameters up = p, down = p;
    const double step = h * info.value(p);
    info.ref(up) += step;
    info.ref(down) -= step;
    const Path a = run_plain(up), b = run_plain(down);
    std::vector<double> d(a.values.size());
    for (std::size_t i = 0; i < d.size(); ++i) d[i] = (a.values[i] - b.values[i]) / (2.0 * step);
    return d;
  };
  const std::vector<double> coarse = central(2e-3), fine = central(1e-3);
  std::vector<double> d(fine.size());
  for (std::size_t i = 0; i < d.size(); ++i) d[i] = (4.0 * fine[i] - coarse[i]) / 3.0;
  return d;
}

// Every constant the form uses: its sensitivities along the path equal the finite differences
// to 1e-6 of their largest magnitude (which must not vanish: the path depends on each one).
void expect_sensitivities_match(const law::LawParameters& p) {
  const Path carried = run_with_sensitivities(p);
  ASSERT_EQ(carried.values, run_plain(p).values) << "carrying them changed the path";
  const bool rate_independent = p.overstress.form == law::OverstressForm::rate_independent;
  for (std::size_t k = 0; k < law::kLawParameters.size(); ++k) {
    const auto& info = law::kLawParameters[k];
    if (rate_independent && info.rate_dependent_only) continue;
    const std::vector<double> fd = finite_difference(p, k);
    ASSERT_EQ(fd.size(), carried.gradients.size());
    double scale = 0.0, error = 0.0;
    std::size_t worst = 0;
    for (std::size_t i = 0; i < fd.size(); ++i) {
      const double d = carried.gradients[i](static_cast<int>(k));
      scale = std::max(scale, std::abs(d));
      if (std::abs(d - fd[i]) > error) {
        error = std::abs(d - fd[i]);
        worst = i;
      }
    }
    EXPECT_GT(scale, 0.0) << info.name;
    EXPECT_LE(error, 1e-6 * scale)
        << info.name << ": output " << worst << " (state " << worst / 3 << ", quantity "
        << worst % 3 << ") carried " << carried.gradients[worst](static_cast<int>(k))
        << ", finite differences " << fd[worst] << ", largest " << scale;
  }
}

TEST(Sensitivity, ExponentialOverstressMatchesFiniteDifferences) {
  expect_sensitivities_match(subslip::testing::paper_law());
}

TEST(Sensitivity, PowerOverstressMatchesFiniteDifferences) {
  law::LawParameters p = subslip::testing::paper_law(law::OverstressForm::power);
  p.overstress.n = 2.0;  // the power form's fit of figure 11b has a low exponent
  p.overstress.eta_v = 2.0e-4;
  expect_sensitivities_match(p);
}

TEST(Sensitivity, NegLogSubloadingMatchesFiniteDifferences) {
  expect_sensitivities_match(subslip::testing::paper_law(law::OverstressForm::exponential,
                                                         law::SubloadingFunction::neg_log));
}

TEST(Sensitivity, ReciprocalSubloadingMatchesFiniteDifferences) {
  expect_sensitivities_match(subslip::testing::paper_law(law::OverstressForm::exponential,
                                                         law::SubloadingFunction::reciprocal));
}

TEST(Sensitivity, RateIndependentMatchesFiniteDifferences) {
  expect_sensitivities_match(subslip::testing::paper_law(law::OverstressForm::rate_independent));
}

TEST(Sensitivity, InitialFrictionCoefficientFollowsMuS) {
  EXPECT_EQ(contact::initial_sensitivity(true).mu(0), 1.0);
  EXPECT_EQ(contact::initial_sensitivity(false).mu.norm(), 0.0);
}

TEST(Sensitivity, AdaptiveStepsAreRefused) {
  history::IntegratorOptions opt = options();
  opt.tolerance = 1e-4;
  EXPECT_THROW(history::run_history(model_of(subslip::testing::paper_law()),
                                    history_of_every_branch(), opt, true, [](auto&&...) {}),
               std::invalid_argument);
}

}  // namespace
