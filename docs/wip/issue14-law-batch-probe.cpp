// Probe of 2026-11-28 (issue 14; docs/grain_step.md, "The flow points in SIMD batches"): the law
// of 12 systems per grain, scalar against one xsimd batch. Build against a Release build of
// subslip_core, e.g. g++ -std=c++20 -O3 -DNDEBUG [-mavx2 -mfma | -march=native] -Iinclude
// -I/usr/include/eigen3 docs/wip/issue14-law-batch-probe.cpp build/src/libsubslip_core.a;
// run with: a.out GRAINS REPEATS (prints ns per grain evaluation and the largest differences).
// Probe (issue 14): the flow points of a grain's 12 systems, scalar (the law's own functions)
// against one xsimd batch evaluation of the same formulas (cot subloading, exponential overstress).
#include <xsimd/xsimd.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <random>
#include <vector>
#include "subslip/law/subloading_friction.hpp"

using namespace subslip::law;
constexpr int kSys = 12;
struct Inputs {  // SoA, one grain
  alignas(64) double mu0[kSys], eff[kSys], slip[kSys], cos0[kSys], omc0[kSys], r0[kSys], tau[kSys];
};
struct Outputs {
  alignas(64) double g[kSys], g_s[kSys], mu[kSys], rs[kSys];
};

int main(int argc, char** argv) {
  const int grains = argc > 1 ? std::atoi(argv[1]) : 20000;
  const int reps = argc > 2 ? std::atoi(argv[2]) : 50;
  LawParameters p;
  p.friction = {1.7, 12.24, 46.45, 0.0};
  p.subloading.function = SubloadingFunction::cot;
  p.subloading.u_tilde = 200;
  p.overstress.form = OverstressForm::exponential;
  p.overstress.eta_v = 1e-3; p.overstress.n = 16; p.overstress.r_hat = 1.6;
  const SubloadingFrictionLaw law(p);
  const double dt = 0.1, fn = 10.0;
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> U(0, 1);
  std::vector<Inputs> in(grains);
  for (auto& g : in)
    for (int a = 0; a < kSys; ++a) {
      g.mu0[a] = 1.7 + 3 * U(rng);
      g.slip[a] = std::pow(10.0, -6 + 2 * U(rng));
      g.eff[a] = g.slip[a] * 12 * U(rng);
      g.r0[a] = 0.5 + 0.49 * U(rng);
      const auto st = law.subloading_start(g.r0[a]);
      g.cos0[a] = st.cos0; g.omc0[a] = st.one_minus_cos0;
      g.tau[a] = g.mu0[a] * fn * (1.0 + 0.3 * U(rng));
    }
  std::vector<Outputs> out_s(grains), out_v(grains);
  using B = xsimd::batch<double>;
  constexpr int W = B::size;
  const auto& f = p.friction; const auto& o = p.overstress;
  const double u = p.subloading.u_tilde, pi = std::numbers::pi;
  auto scalar = [&] {
    for (int i = 0; i < grains; ++i) {
      const Inputs& g = in[i]; Outputs& r = out_s[i];
      for (int a = 0; a < kSys; ++a) {
        const auto mu = law.friction_coefficient_after(g.mu0[a], g.eff[a], dt);
        const SubloadingFrictionLaw::SubloadingStart st{g.r0[a], g.cos0[a], g.omc0[a], 0, 0};
        const auto rs = law.subloading_ratio_after(st, g.slip[a]);
        const double ratio = g.tau[a] / (mu.value * fn);
        const auto res = law.flow_residual(ratio, rs.value, g.slip[a], dt);
        r.g[a] = res.value;
        r.g_s[a] = res.d_r * (-ratio / mu.value * mu.d_slip) + res.d_rs * rs.d_slip + res.d_slip;
        r.mu[a] = mu.value; r.rs[a] = rs.value;
      }
    }
  };
  auto batched = [&] {
    for (int i = 0; i < grains; ++i) {
      const Inputs& g = in[i]; Outputs& r = out_v[i];
      for (int a = 0; a < kSys; a += W) {
        const B mu0 = B::load_aligned(g.mu0 + a), eff = B::load_aligned(g.eff + a);
        const B slip = B::load_aligned(g.slip + a);
        // friction: mu1 = mu0 + (A - B mu0) phi1(B)
        const B A = f.kappa * eff + f.xi * dt;
        const B Bq = f.kappa / f.mu_k * eff + f.xi * dt / f.mu_s;
        B ph = B(-1.0 / 3628800), sl = B(9 * (-1.0 / 3628800));
        constexpr double c[10] = {1.0, -1.0 / 2, 1.0 / 6, -1.0 / 24, 1.0 / 120, -1.0 / 720,
                                  1.0 / 5040, -1.0 / 40320, 1.0 / 362880, -1.0 / 3628800};
        for (int k = 8; k >= 0; --k) ph = ph * Bq + c[k];
        for (int k = 8; k >= 1; --k) sl = sl * Bq + k * c[k];
        const auto big = xsimd::abs(Bq) >= 0.0625;
        if (xsimd::any(big)) {
          const B ome = -xsimd::expm1(-Bq);
          ph = xsimd::select(big, ome / Bq, ph);
          sl = xsimd::select(big, ((1.0 - ome) * Bq - ome) / (Bq * Bq), sl);
        }
        const B d_drive = f.kappa - f.kappa / f.mu_k * mu0;
        const B drive = A - Bq * mu0;
        const B mu = mu0 + drive * ph;
        const B dmu = d_drive * ph + drive * sl * (f.kappa / f.mu_k);
        // subloading ratio after the slip
        const B cos0 = B::load_aligned(g.cos0 + a), omc0 = B::load_aligned(g.omc0 + a);
        const B decay = xsimd::expm1(-(0.5 * pi * u) * slip);
        const B x = cos0 * (1.0 + decay);
        const B omx = omc0 - cos0 * decay;
        const auto hi = x > 0.5;
        B r1;
        if (xsimd::all(hi)) r1 = (4.0 / pi) * xsimd::asin(xsimd::sqrt(0.5 * omx));
        else r1 = xsimd::select(hi, (4.0 / pi) * xsimd::asin(xsimd::sqrt(0.5 * omx)),
                                (2.0 / pi) * xsimd::acos(x));
        const B rs_slope = u * x / xsimd::sqrt(omx * (1.0 + x));
        // flow residual
        const B ratio = B::load_aligned(g.tau + a) / (mu * fn);
        const B gap = o.r_hat - ratio;
        const B rate = slip / dt;
        const B y = o.eta_v * gap * rate;
        const B inv = xsimd::log1p(y) / o.n;
        const B d_inv = 1.0 / (o.n * (1.0 + y));
        const B d_slip = -d_inv * (o.eta_v * gap / dt);
        const B d_r = 1.0 - d_inv * (-o.eta_v * rate);
        const B gval = (ratio - r1) - inv;
        const B g_s = d_r * (-ratio / mu * dmu) - rs_slope + d_slip;
        gval.store_aligned(r.g + a); g_s.store_aligned(r.g_s + a);
        mu.store_aligned(r.mu + a); r1.store_aligned(r.rs + a);
      }
    }
  };
  auto time = [&](auto&& fn_) {
    std::vector<double> t;
    for (int k = 0; k < reps; ++k) {
      const auto t0 = std::chrono::steady_clock::now(); fn_();
      t.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    std::sort(t.begin(), t.end()); return t[t.size() / 2];
  };
  const double ts = time(scalar), tv = time(batched);
  double worst[4] = {0, 0, 0, 0};
  for (int i = 0; i < grains; ++i)
    for (int a = 0; a < kSys; ++a) {
      const double* s[4] = {out_s[i].g, out_s[i].g_s, out_s[i].mu, out_s[i].rs};
      const double* v[4] = {out_v[i].g, out_v[i].g_s, out_v[i].mu, out_v[i].rs};
      for (int q = 0; q < 4; ++q)
        worst[q] = std::max(worst[q], std::abs(s[q][a] - v[q][a]) / std::max(std::abs(s[q][a]), 1e-300));
    }
  std::printf("arch %s width %d: scalar %.1f ns/grain-eval, batch %.1f ns, ratio %.2f; max rel diff g %.1e g_s %.1e mu %.1e r_s %.1e\n",
              B::arch_type::name(), W, 1e9 * ts / grains, 1e9 * tv / grains, ts / tv, worst[0], worst[1], worst[2], worst[3]);
}
