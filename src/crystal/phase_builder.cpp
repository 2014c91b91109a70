#include "subslip/crystal/phase_builder.hpp"

#include <set>
#include <stdexcept>

namespace subslip::crystal {

std::vector<DescribedSystem> described_systems(const PhaseDescription& d) {
  std::vector<DescribedSystem> out;
  if (!d.custom_systems.empty()) {
    for (size_t i = 0; i < d.custom_systems.size(); ++i) {
      const auto& c = d.custom_systems[i];
      out.push_back({c.s.normalized(), c.m.normalized(), "custom " + std::to_string(i), 0});
    }
    return out;
  }
  for (size_t f = 0; f < d.families.size(); ++f) {
    for (const SlipSystem& sys : slip_systems(d.families[f], d.c_over_a)) {
      out.push_back({sys.s, sys.m, std::string(to_string(sys.family)) + " " + sys.label,
                     static_cast<int>(f)});
    }
  }
  return out;
}

namespace {

template <int N>
typename SlipTypes<N>::MatNN latent_matrix(const PhaseDescription& d,
                                           const std::vector<DescribedSystem>& systems) {
  const int n = static_cast<int>(systems.size());
  using MatNN = typename SlipTypes<N>::MatNN;
  MatNN q = MatNN::Identity(n, n);
  if (d.latent.kind == LatentHardening::Kind::ratio) {
    q.setConstant(n, n, d.latent.ratio);
    q.diagonal().setOnes();
  } else if (d.latent.kind == LatentHardening::Kind::coplanar) {
    q.setConstant(n, n, d.latent.non_coplanar);
    for (int a = 0; a < n; ++a) {
      for (int b = 0; b < n; ++b) {
        const bool same_plane =
            systems[a].m.cross(systems[b].m).norm() < 1e-9;  // normals parallel (up to sign)
        if (a != b && same_plane) q(a, b) = d.latent.coplanar;
      }
    }
    q.diagonal().setOnes();
  }
  return q;
}

template <int N>
std::unique_ptr<Aggregate> build(const PhaseDescription& d,
                                 const std::vector<DescribedSystem>& systems,
                                 const std::vector<Orientation>& grains) {
  const int n = static_cast<int>(systems.size());
  Phase<N> ph;
  ph.kinematics = d.kinematics;
  ph.pressure_sensitive = d.pressure_sensitive;
  ph.has_latent = d.latent.kind != LatentHardening::Kind::none;
  ph.latent = latent_matrix<N>(d, systems);
  ph.tau0.resize(n);
  typename SlipTypes<N>::VecN mu0(n);
  std::vector<Vec3> s, m;
  for (int a = 0; a < n; ++a) {
    const auto& sys = systems[static_cast<size_t>(a)];
    const SlipGroupSettings& g = d.custom_systems.empty()
                                     ? d.family_settings[static_cast<size_t>(sys.group)]
                                     : d.custom_settings;
    ph.laws.emplace_back(g.law);
    ph.tau0(a) = g.tau0;
    mu0(a) = g.initial_mu > 0.0 ? g.initial_mu : g.law.friction.mu_s;
    s.push_back(sys.s);
    m.push_back(sys.m);
  }
  ph.assemble(s, m, d.stiffness);
  std::vector<Mat3> g;
  std::vector<double> w;
  for (const auto& o : grains) {
    g.push_back(o.g);
    w.push_back(o.weight);
  }
  return make_taylor_aggregate<N>(std::move(ph), g, w, mu0);
}

}  // namespace

std::unique_ptr<Aggregate> build_taylor_aggregate(const PhaseDescription& d,
                                                  const std::vector<Orientation>& grains) {
  if (d.custom_systems.empty() && d.families.size() != d.family_settings.size())
    throw std::invalid_argument("one settings entry per slip family is required");
  const auto systems = described_systems(d);
  switch (systems.size()) {
    case 1:
      return build<1>(d, systems, grains);
    case 3:
      return build<3>(d, systems, grains);
    case 6:
      return build<6>(d, systems, grains);
    case 12:
      return build<12>(d, systems, grains);
    case 24:
      return build<24>(d, systems, grains);
    case 48:
      return build<48>(d, systems, grains);
    default:
      if (systems.empty() || systems.size() > static_cast<size_t>(kMaxSlipSystems))
        throw std::invalid_argument("a phase needs 1 to " + std::to_string(kMaxSlipSystems) +
                                    " slip systems, got " + std::to_string(systems.size()));
      return build<Eigen::Dynamic>(d, systems, grains);
  }
}

}  // namespace subslip::crystal
