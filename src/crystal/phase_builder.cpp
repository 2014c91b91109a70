#include "subslip/crystal/phase_builder.hpp"

#include <set>
#include <stdexcept>

#include "grain_step_isa.hpp"
#include "subslip/crystal/flow_point_batch.hpp"

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

}  // namespace

template <int N>
BuiltPhase<N> build_phase(const PhaseDescription& d) {
  if (has_isa_grain_steps(N)) detail::require_grain_step_isa();
  const auto systems = described_systems(d);
  const int n = static_cast<int>(systems.size());
  BuiltPhase<N> out;
  Phase<N>& ph = out.phase;
  ph.kinematics = d.kinematics;
  ph.pressure_sensitive = d.pressure_sensitive;
  ph.has_latent = d.latent.kind != LatentHardening::Kind::none;
  ph.latent = latent_matrix<N>(d, systems);
  ph.tau0.resize(n);
  out.initial_mu.resize(n);
  std::vector<Vec3> s, m;
  for (int a = 0; a < n; ++a) {
    const auto& sys = systems[static_cast<size_t>(a)];
    const SlipGroupSettings& g = d.custom_systems.empty()
                                     ? d.family_settings[static_cast<size_t>(sys.group)]
                                     : d.custom_settings;
    ph.laws.emplace_back(g.law);
    ph.tau0(a) = g.tau0;
    out.initial_mu(a) = g.initial_mu > 0.0 ? g.initial_mu : g.law.friction.mu_s;
    s.push_back(sys.s);
    m.push_back(sys.m);
  }
  ph.assemble(s, m, d.stiffness);
  return out;
}

int checked_slip_count(const PhaseDescription& d) {
  if (d.custom_systems.empty() && d.families.size() != d.family_settings.size())
    throw std::invalid_argument("one settings entry per slip family is required");
  const size_t n = described_systems(d).size();
  if (n == 0 || n > static_cast<size_t>(kMaxSlipSystems))
    throw std::invalid_argument("a phase needs 1 to " + std::to_string(kMaxSlipSystems) +
                                " slip systems, got " + std::to_string(n));
  return static_cast<int>(n);
}

std::unique_ptr<Aggregate> build_taylor_aggregate(const PhaseDescription& d,
                                                  const std::vector<Orientation>& grains,
                                                  const parallel::Team& team,
                                                  const parallel::Block* held) {
  const parallel::Block block =
      held != nullptr ? *held : parallel::block_of(grains.size(), team.rank(), team.size());
  if (held != nullptr && held->count != grains.size())
    throw std::invalid_argument("build_taylor_aggregate: the grains held are not the block");
  const std::size_t first = held != nullptr ? 0 : block.offset;
  std::vector<Mat3> g;
  std::vector<double> w;
  for (std::size_t k = first; k < first + block.count; ++k) {
    g.push_back(grains[k].g);
    w.push_back(grains[k].weight);
  }
  const GrainShare share{&team, block.offset, block.total};
  return visit_phase(d, [&](auto built) -> std::unique_ptr<Aggregate> {
    return make_taylor_aggregate(std::move(built.phase), g, w, built.initial_mu, share);
  });
}

#define SUBSLIP_INSTANTIATE_BUILD_PHASE(N) \
  template BuiltPhase<N> build_phase<N>(const PhaseDescription&);

SUBSLIP_FOR_EACH_SLIP_COUNT(SUBSLIP_INSTANTIATE_BUILD_PHASE)

}  // namespace subslip::crystal
