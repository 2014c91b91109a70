#include "subslip/io/case_group.hpp"

#include <string>
#include <vector>

#include "subslip/io/law_block.hpp"
#include "subslip/law/parameter_table.hpp"

namespace subslip::io {

namespace {

// The keys of a sweep path, indices dropped: "loading[0].L[0][1]" -> {"loading", "L"}.
std::vector<std::string> keys_of(std::string_view path) {
  std::vector<std::string> keys(1);
  int depth = 0;
  for (char ch : path) {
    if (ch == '[') ++depth;
    if (depth == 0 && ch == '.') {
      keys.emplace_back();
    } else if (depth == 0) {
      keys.back() += ch;
    }
    if (ch == ']') --depth;
  }
  return keys;
}

bool has(const std::vector<std::string>& keys, std::string_view key) {
  for (const auto& k : keys) {
    if (k == key) return true;
  }
  return false;
}

// The law's constants (law/parameter_table.hpp): the same keys in both kinds, with slip
// dimensionless for crystals; "" for function and form, which are names.
std::string law_unit(SceneKind kind, const std::string& key, const Units& u) {
  const law::LawParameterInfo* c = law::find_law_parameter(key);
  return c ? law_unit_name(c->unit, kind == SceneKind::crystal, u) : std::string();
}

std::string contact_unit(const std::vector<std::string>& keys, const Units& u) {
  const std::string& key = keys.back();
  if (keys.front() == "law") return law_unit(SceneKind::contact, key, u);
  if (key == "alpha_n" || key == "alpha_t") return u.stiffness();
  if (key == "normal_traction" || key == "traction") return u.stress;
  if (key == "speed" || key == "velocity") return u.velocity();
  if (key == "distance") return u.length;
  if (key == "duration") return u.time;
  if (key == "mu" || key == "direction" || key == "increments" || key == "growth" ||
      key == "output_every" || key == "tolerance" || key == "order" ||
      key == "residual_tolerance" || key == "max_cutbacks")
    return "1";
  return "";
}

std::string crystal_unit(const std::vector<std::string>& keys, const Units& u) {
  const std::string& key = keys.back();
  if (has(keys, "law")) return law_unit(SceneKind::crystal, key, u);
  if (has(keys, "elasticity")) return key == "nu" ? "1" : key == "type" ? "" : u.stress;
  if (key == "tau0" || key == "stress") return u.stress;
  if (key == "L") return u.per_time();
  if (key == "duration") return u.time;
  if (key == "spread_deg" || key == "euler_deg") return "deg";
  if (key == "initial_mu" || key == "c_over_a" || key == "ratio" || key == "coplanar" ||
      key == "non_coplanar" || key == "strain" || key == "increments" || key == "growth" ||
      key == "output_every" || key == "count" || key == "seed" || key == "tolerance" ||
      key == "order" || key == "residual_tolerance" || key == "stress_tolerance" ||
      key == "max_iterations" || key == "max_cutbacks" || key == "max_mixed_iterations" ||
      key == "checkpoint_every")
    return "1";
  return "";
}

void write_sweep_overrides(const h5::Group& g, std::span<const SweepOverride> overrides,
                           SceneKind kind, const Units& units) {
  for (const SweepOverride& o : overrides) {
    const std::string name = "sweep:" + o.path;
    if (o.number) {
      g.set_attribute(name, *o.number);
    } else {
      g.set_attribute(name, o.value);
    }
    const std::string unit = sweep_unit(kind, o.path, units);
    if (!unit.empty()) g.set_attribute(name + ".unit", unit);
  }
}

}  // namespace

std::string sweep_unit(SceneKind kind, std::string_view path, const Units& units) {
  const auto keys = keys_of(path);
  return kind == SceneKind::contact ? contact_unit(keys, units) : crystal_unit(keys, units);
}

h5::Group create_case_group(const h5::Group& cases, const std::string& name, int index,
                            std::span<const SweepOverride> overrides, SceneKind kind,
                            const Units& units) {
  h5::Group group = cases.create_group(case_group_name(name));
  group.set_attribute("name", name);
  group.set_attribute("index", index);
  write_sweep_overrides(group, overrides, kind, units);
  return group;
}

driver::CaseStatus case_status(h5::CaseState s) {
  switch (s) {
    case h5::CaseState::running:
      return driver::CaseStatus::interrupted;
    case h5::CaseState::completed:
      return driver::CaseStatus::completed;
    case h5::CaseState::failed:
      return driver::CaseStatus::failed;
    case h5::CaseState::not_started:
      break;
  }
  return driver::CaseStatus::pending;
}

}  // namespace subslip::io
