// From a runtime description of a phase (what a scene file says) to the compile-time kernel:
// the slip count picks the template instance, so a scene pays only for the slip systems it
// declares (fixed-size vectors for the counts of SUBSLIP_FOR_EACH_SLIP_COUNT, crystal_kernel.hpp:
// 12, 24 and 48 systems; other counts use a fixed-capacity dynamic size, still with no
// allocation per grain-step).
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "subslip/crystal/aggregate.hpp"
#include "subslip/crystal/rotation.hpp"
#include "subslip/crystal/slip_systems.hpp"

namespace subslip::crystal {

// The law and reference stress of one group of slip systems (a family, or custom systems).
struct SlipGroupSettings {
  law::LawParameters law;
  double tau0 = 1.0;        // reference stress (plays f_n) [stress]
  double initial_mu = 0.0;  // 0: start from mu_s
};

// A slip system given directly by its vectors (lattice frame), e.g. the single-slip check.
struct CustomSlipSystem {
  Vec3 s, m;
};

// Latent hardening matrix q_ab for the mu evolution: identity (independent systems), a scalar
// latent ratio (q_aa = 1, q_ab = ratio), or separate coplanar / non-coplanar values.
struct LatentHardening {
  enum class Kind { none, ratio, coplanar } kind = Kind::none;
  double ratio = 1.0;         // kind == ratio: every off-diagonal entry
  double coplanar = 1.0;      // kind == coplanar: systems sharing a slip plane
  double non_coplanar = 1.0;  // kind == coplanar: all other pairs
};

struct PhaseDescription {
  std::vector<SlipFamily> families;                // in this order in every per-system output
  std::vector<SlipGroupSettings> family_settings;  // one per family
  std::vector<CustomSlipSystem> custom_systems;    // used instead of families when non-empty
  SlipGroupSettings custom_settings;
  double c_over_a = kIdealCOverA;
  Mat6 stiffness = Mat6::Identity();  // lattice frame, Mandel
  LatentHardening latent;
  bool pressure_sensitive = false;
  Kinematics kinematics = Kinematics::finite_rotation;
};

// Slip systems of a description, in output order, with a readable label each.
struct DescribedSystem {
  Vec3 s, m;
  std::string label;
  int group;  // index into family_settings (or 0 for custom)
};
std::vector<DescribedSystem> described_systems(const PhaseDescription& d);

// The Taylor aggregate of `grains`; shared by a team, this rank's block of them
// (parallel::block_of) with the weights normalised over all. `held`: `grains` is only that
// block of the team's grains (a rank that never held the others).
std::unique_ptr<Aggregate> build_taylor_aggregate(
    const PhaseDescription& d, const std::vector<Orientation>& grains,
    const parallel::Team& team = parallel::serial_team(), const parallel::Block* held = nullptr);

// The kernel phase of a description for N slip systems, with the initial mu of each system, for
// drivers other than the Taylor aggregate (the CVODE peer, the material-point API). visit_phase
// picks N from the slip count exactly as build_taylor_aggregate does (SUBSLIP_FOR_EACH_SLIP_COUNT)
// and calls visitor(BuiltPhase<N>).
template <int N>
struct BuiltPhase {
  Phase<N> phase;
  typename SlipTypes<N>::VecN initial_mu;
};
template <int N>
BuiltPhase<N> build_phase(const PhaseDescription& d);

// The number of slip systems of a description (checked: 1 to kMaxSlipSystems, one settings
// entry per family); throws std::invalid_argument otherwise.
int checked_slip_count(const PhaseDescription& d);

template <class Visitor>
decltype(auto) visit_phase(const PhaseDescription& d, Visitor&& visitor) {
  switch (checked_slip_count(d)) {
    case 12:
      return visitor(build_phase<12>(d));
    case 24:
      return visitor(build_phase<24>(d));
    case 48:
      return visitor(build_phase<48>(d));
    default:
      return visitor(build_phase<Eigen::Dynamic>(d));
  }
}

}  // namespace subslip::crystal
