// The pressure-sensitive reading of the law on slip planes: f_n,a = tau0 + (compressive normal
// stress on the plane of a), i.e. the literal Coulomb law with a cohesion tau0.
#include <gtest/gtest.h>

#include <cmath>

#include "subslip/crystal/elasticity.hpp"
#include "subslip/crystal/phase_builder.hpp"

namespace {

using namespace subslip::crystal;
namespace law = subslip::law;

// Saturated shear stress of one slip system (s = e1, m = e2) sheared quasi-statically while
// the normal stress on its plane is held at -p (compression p) by mixed control.
double saturated_shear(double p, bool pressure_sensitive) {
  PhaseDescription d;
  d.custom_systems = {{Vec3(1, 0, 0), Vec3(0, 1, 0)}};
  d.custom_settings.tau0 = 10.0;
  // No hardening (mu_s = mu_k), quasi-static (eta_v tiny), fast r_s saturation.
  d.custom_settings.law.friction = {0.5, 0.5, 0.0, 0.0};
  d.custom_settings.law.subloading = {law::SubloadingFunction::cot, 2000.0};
  d.custom_settings.law.overstress = {law::OverstressForm::exponential, 1e-6, 16.0, 1.6};
  d.stiffness = isotropic_from_G_nu(1e4, 0.3);
  d.kinematics = Kinematics::small_strain;
  d.pressure_sensitive = pressure_sensitive;
  std::vector<Orientation> grain(1);
  grain[0].g = Mat3::Identity();
  grain[0].weight = 1.0;
  auto aggregate = build_taylor_aggregate(d, grain);
  // First bring sigma_22 to -p (L_22 free), then shear with sigma_22 held at -p.
  LoadSegment press, shear;
  press.free(1, 1) = true;
  press.stress_target(1, 1) = -p;
  press.duration = 1.0;
  press.increments = 10;
  shear = press;
  shear.velocity_gradient(0, 1) = 1e-2;
  shear.duration = 10.0;  // shear strain 0.1: many times the saturation slip 1/u_tilde
  shear.increments = 200;
  double tau = 0.0, sigma22 = 0.0;
  aggregate->run({press, shear}, AggregateOptions{}, [&](const MacroState& m, const GrainFields&) {
    tau = m.stress(0, 1);
    sigma22 = m.stress(1, 1);
  });
  EXPECT_NEAR(sigma22, -p, 1e-6 * (p + 1.0));
  return tau;
}

}  // namespace

TEST(CrystalPressureSensitive, SaturatedShearFollowsCoulombOnTheSlipPlane) {
  // Quasi-static saturation: r -> r_s -> 1, so tau -> mu f_n = mu (tau0 + p). The remaining
  // overstress is eta_v (r_hat - 1) gdot / n ~ 4e-8 relative, and r_s falls short of 1 by
  // ~exp(-pi u_tilde gamma / 2) ~ 0: assert 1e-5 relative.
  const double mu = 0.5, tau0 = 10.0;
  for (double p : {0.0, 5.0, 20.0}) {
    const double with = saturated_shear(p, true);
    EXPECT_NEAR(with, mu * (tau0 + p), 1e-5 * mu * (tau0 + p)) << "p = " << p;
    // Without the pressure-sensitive reading the normal stress must not matter.
    const double without = saturated_shear(p, false);
    EXPECT_NEAR(without, mu * tau0, 1e-5 * mu * tau0) << "p = " << p;
  }
}
