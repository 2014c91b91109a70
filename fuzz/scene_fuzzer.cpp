// libFuzzer target: the scene parsers (YAML checking layer, sweeps, law block, contact and
// crystal scenes) on arbitrary bytes.
//
// Expected outcome of a bad input: one subslip::InputError. Anything else is a finding: another
// exception (libFuzzer reports it as an uncaught exception), a crash or sanitizer report, or an
// accepted scene whose values break an invariant (non-finite numbers, zero-length increments, a
// law the law's constructor refuses, slip systems that are not unit and orthogonal). Inputs that
// are only slow (many sweep cases, huge generated orientation sets) are skipped: too_costly().
//
// Build and run: docs/internals.md, "Sanitizers and fuzzing".
#include <yaml-cpp/yaml.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "fuzz_checks.hpp"
#include "subslip/crystal/slip_systems.hpp"
#include "subslip/io/contact_scene.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/scene_common.hpp"
#include "subslip/io/yaml_checked.hpp"
#include "subslip/law/subloading_friction.hpp"

namespace {

using namespace subslip;
using subslip::fuzz::all_finite;

// Increment lengths are computed for segments up to this size.
constexpr int kMaxIncrementsToExpand = 100000;
// Inputs that only cost time are skipped so that the fuzzer keeps its pace (and its -timeout
// means a hang): more sweep cases than this (each case is a full parse), generated orientation
// sets larger than this, or YAML trees larger than this (aliases make cycles).
constexpr double kMaxSweepCases = 16;
constexpr double kMaxGeneratedGrains = 10000;
constexpr int kMaxNodesToScan = 20000;

// Walks the raw YAML tree; `key` is the mapping key (or sweep path) the node belongs to.
bool asks_for_many_grains(const YAML::Node& node, const std::string& key, int& budget) {
  if (--budget < 0) return true;
  if (node.IsScalar()) {
    if (key.size() < 5 || key.compare(key.size() - 5, 5, "count") != 0) return false;
    char* end = nullptr;
    const double value = std::strtod(node.Scalar().c_str(), &end);
    return !(value <= kMaxGeneratedGrains);  // NaN and unparsable strings are the parser's
  }
  if (node.IsSequence()) {
    for (const auto& element : node)
      if (asks_for_many_grains(element, key, budget)) return true;
  } else if (node.IsMap()) {
    for (const auto& kv : node) {
      const std::string name = kv.first.IsScalar() ? kv.first.Scalar() : std::string();
      if (asks_for_many_grains(kv.second, name, budget)) return true;
    }
  }
  return false;
}

bool too_costly(const io::YamlDocument& document) {
  const YAML::Node root = document.root().yaml();  // a copy: root() is a temporary
  if (!root.IsMap()) return false;
  int budget = kMaxNodesToScan;
  if (asks_for_many_grains(root, "", budget)) return true;
  const YAML::Node sweep = root["sweep"];
  if (!sweep.IsDefined() || !sweep.IsMap()) return false;  // a missing key is a "zombie" node
  double cases = 1.0;
  for (const auto& kv : sweep) cases *= kv.second.IsSequence() ? double(kv.second.size()) : 1.0;
  return cases > kMaxSweepCases;
}

void check_law(const law::LawParameters& p) {
  try {
    const law::SubloadingFrictionLaw law(p);
    (void)law;
  } catch (const std::invalid_argument& e) {
    fuzz::violated(e.what(), __FILE__, __LINE__);
  }
}

// The increment lengths the drivers step with, computed as contact::increment_lengths and
// crystal::increment_lengths do (those live in the driver sources, which this target does not
// link): `increments` terms in geometric progression scaled to sum to `duration`.
void check_lengths(double duration, int increments, double growth) {
  if (increments > kMaxIncrementsToExpand) return;
  std::vector<double> dt(static_cast<std::size_t>(increments));
  double sum = 0.0, h = 1.0;
  for (auto& d : dt) {
    d = h;
    sum += h;
    h *= growth;
  }
  double total = 0.0;
  for (auto& d : dt) {
    d *= duration / sum;
    FUZZ_REQUIRE(std::isfinite(d) && d > 0.0);
    total += d;
  }
  FUZZ_REQUIRE(std::abs(total - duration) <= 1e-9 * duration);
}

// Output times of a segment (output.at): increasing, in (0, duration], and finite.
void check_output_times(bool at_times, const std::vector<double>& times, double duration) {
  if (!at_times) {
    FUZZ_REQUIRE(times.empty());
    return;
  }
  double before = 0.0;
  for (double t : times) {
    FUZZ_REQUIRE(std::isfinite(t) && t > before && t <= duration);
    before = t;
  }
}

void check_contact_case(const io::ContactCase& c) {
  check_law(c.model.law);
  FUZZ_REQUIRE(std::isfinite(c.model.stiffness.alpha_n) && c.model.stiffness.alpha_n > 0.0);
  FUZZ_REQUIRE(std::isfinite(c.model.stiffness.alpha_t) && c.model.stiffness.alpha_t > 0.0);
  FUZZ_REQUIRE(std::isfinite(c.model.initial_normal_traction) &&
               c.model.initial_normal_traction > 0.0);
  FUZZ_REQUIRE(std::isfinite(c.model.initial_law_state.mu) && c.model.initial_law_state.mu > 0.0);
  FUZZ_REQUIRE(!c.segments.empty());
  for (const contact::Segment& s : c.segments) {
    FUZZ_REQUIRE(all_finite(s.velocity) && std::isfinite(s.velocity.norm()));
    FUZZ_REQUIRE(std::isfinite(s.duration) && s.duration > 0.0);
    FUZZ_REQUIRE(std::isfinite(s.normal_traction) && std::isfinite(s.normal_velocity));
    FUZZ_REQUIRE(s.increments >= 1 && s.output_every >= 1);
    FUZZ_REQUIRE(std::isfinite(s.growth) && s.growth > 0.0);
    check_lengths(s.duration, s.increments, s.growth);
    check_output_times(s.output_at_times, s.output_times, s.duration);
  }
  FUZZ_REQUIRE(std::isfinite(c.integrator.residual_tolerance) &&
               c.integrator.residual_tolerance > 0.0);
  FUZZ_REQUIRE(c.integrator.max_cutbacks >= 0);
  FUZZ_REQUIRE(!c.fields.empty() && c.fields.front() == io::ContactField::time);
}

void check_phase(const crystal::PhaseDescription& d) {
  FUZZ_REQUIRE(all_finite(d.stiffness));
  FUZZ_REQUIRE(d.stiffness.llt().info() == Eigen::Success);  // positive definite
  FUZZ_REQUIRE(std::isfinite(d.c_over_a) && d.c_over_a > 0.0);
  auto check_group = [](const crystal::SlipGroupSettings& g) {
    check_law(g.law);
    FUZZ_REQUIRE(std::isfinite(g.tau0) && g.tau0 > 0.0);
    FUZZ_REQUIRE(std::isfinite(g.initial_mu) && g.initial_mu > 0.0);
  };
  if (d.custom_systems.empty()) {
    FUZZ_REQUIRE(d.families.size() == d.family_settings.size());
    for (const auto& g : d.family_settings) check_group(g);
  } else {
    check_group(d.custom_settings);
  }
  // The slip systems the phase builder will use (crystal::described_systems).
  std::vector<std::pair<crystal::Vec3, crystal::Vec3>> systems;
  if (d.custom_systems.empty()) {
    try {
      for (const auto& s : crystal::slip_systems(d.families, d.c_over_a))
        systems.emplace_back(s.s, s.m);
    } catch (const std::exception& e) {
      fuzz::violated(e.what(), __FILE__, __LINE__);
    }
  } else {
    for (const auto& c : d.custom_systems) systems.emplace_back(c.s.normalized(), c.m.normalized());
  }
  FUZZ_REQUIRE(!systems.empty() && systems.size() <= 48);
  for (const auto& [s, m] : systems) {
    FUZZ_REQUIRE(all_finite(s) && all_finite(m));
    FUZZ_REQUIRE(std::abs(s.norm() - 1.0) < 1e-12 && std::abs(m.norm() - 1.0) < 1e-12);
    FUZZ_REQUIRE(std::abs(s.dot(m)) <= 1e-6);
  }
  FUZZ_REQUIRE(std::isfinite(d.latent.ratio) && std::isfinite(d.latent.coplanar) &&
               std::isfinite(d.latent.non_coplanar));
}

void check_crystal_case(const io::CrystalCase& c) {
  check_phase(c.phase);
  FUZZ_REQUIRE(!c.orientations.empty());
  double total_weight = 0.0;
  for (const auto& o : c.orientations) {
    fuzz::check_orientation(o);
    total_weight += o.weight;
  }
  FUZZ_REQUIRE(std::isfinite(total_weight));
  FUZZ_REQUIRE(!c.segments.empty());
  for (const crystal::LoadSegment& s : c.segments) {
    FUZZ_REQUIRE(all_finite(s.velocity_gradient) && all_finite(s.stress_target));
    FUZZ_REQUIRE(std::isfinite(s.duration) && s.duration > 0.0);
    FUZZ_REQUIRE(s.increments >= 1 && s.output_every >= 1);
    FUZZ_REQUIRE(std::isfinite(s.growth) && s.growth > 0.0);
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        if (s.free(i, j)) FUZZ_REQUIRE(s.velocity_gradient(i, j) == 0.0);
    check_lengths(s.duration, s.increments, s.growth);
    check_output_times(s.output_at_times, s.output_times, s.duration);
  }
  // output.grains_at: a flag for every output row, or none.
  if (!c.output.grain_rows.empty())
    FUZZ_REQUIRE(c.output.grain_rows.size() == io::crystal_output_count(c.segments));
  FUZZ_REQUIRE(std::isfinite(c.options.grain.tolerance) && c.options.grain.tolerance > 0.0);
  FUZZ_REQUIRE(std::isfinite(c.options.stress_tolerance) && c.options.stress_tolerance > 0.0);
  FUZZ_REQUIRE(!c.output.macro.empty() && c.output.macro.front() == io::MacroField::time);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    // Relative orientation files resolve against the working directory.
    const io::YamlDocument document = io::YamlDocument::from_string(text, "fuzz.yaml");
    if (too_costly(document)) return 0;
    if (io::scene_kind(document, {"contact", "crystal"}) == "contact") {
      for (const auto& c : io::parse_contact_scene(document).cases) check_contact_case(c);
    } else {
      for (const auto& c : io::parse_crystal_scene(document).cases) check_crystal_case(c);
    }
  } catch (const InputError&) {
    // The expected outcome of a bad scene.
  }
  return 0;
}
