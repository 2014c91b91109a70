// The law's constants, each once: its key in a scene's `law:` block (also its attribute name in
// a result file), the kind of its unit, its bounds, a description and where it lives in
// LawParameters. The scene parser (io/law_block.cpp), the sweep units (io/case_group.cpp) and
// both case writers (io/contact_output.cpp, io/crystal_output.cpp) read this table, so a new
// constant is added here and nowhere else; the Python package reads names and units back from
// the file's attributes (`<name>`, `<name>.unit`).
#pragma once

#include <Eigen/Core>
#include <array>
#include <string_view>

#include "subslip/law/subloading_friction.hpp"

namespace subslip::law {

// A constant's unit in terms of the slip measure, which is a length for a contact and
// dimensionless for a slip system (io/law_block.hpp turns it into a unit of a scene).
enum class ParameterUnit {
  none,           // mu_s, mu_k, n, r_hat
  per_slip,       // kappa, u_tilde: 1/length (contact), 1 (crystal)
  per_time,       // xi
  time_per_slip,  // eta_v: time/length (contact), time (crystal)
};

// The values a constant may take (what the parser checks; validate() holds the same).
enum class ParameterBound { positive, non_negative, above_one };

// The blocks of a `law:` block, in scene and file order.
enum class LawBlock { friction, subloading, overstress };

struct LawParameterInfo {
  LawBlock block;
  std::string_view name;
  ParameterUnit unit;
  ParameterBound bound;
  // Only the rate-dependent overstress forms have it (absent or NaN under rate_independent).
  bool rate_dependent_only;
  std::string_view description;
  const double& (*value)(const LawParameters&);
  double& (*ref)(LawParameters&);
};

namespace detail {
template <auto Block, auto Member>
const double& value_of(const LawParameters& p) {
  return (p.*Block).*Member;
}
template <auto Block, auto Member>
double& ref_of(LawParameters& p) {
  return (p.*Block).*Member;
}
template <auto Block, auto Member>
constexpr LawParameterInfo entry(LawBlock block, std::string_view name, ParameterUnit unit,
                                 ParameterBound bound, bool rate_dependent_only,
                                 std::string_view description) {
  return {block,
          name,
          unit,
          bound,
          rate_dependent_only,
          description,
          &value_of<Block, Member>,
          &ref_of<Block, Member>};
}
}  // namespace detail

// In the order the parser reads them and the writers write them.
inline constexpr std::array<LawParameterInfo, 8> kLawParameters = {
    detail::entry<&LawParameters::friction, &FrictionCoefficientEvolution::mu_s>(
        LawBlock::friction, "mu_s", ParameterUnit::none, ParameterBound::positive, false,
        "static friction coefficient (target of recovery with time)"),
    detail::entry<&LawParameters::friction, &FrictionCoefficientEvolution::mu_k>(
        LawBlock::friction, "mu_k", ParameterUnit::none, ParameterBound::positive, false,
        "kinetic friction coefficient (target of sliding)"),
    detail::entry<&LawParameters::friction, &FrictionCoefficientEvolution::kappa>(
        LawBlock::friction, "kappa", ParameterUnit::per_slip, ParameterBound::non_negative, false,
        "sliding-softening rate"),
    detail::entry<&LawParameters::friction, &FrictionCoefficientEvolution::xi>(
        LawBlock::friction, "xi", ParameterUnit::per_time, ParameterBound::non_negative, false,
        "recovery (creep-hardening) rate"),
    detail::entry<&LawParameters::subloading, &SubloadingEvolution::u_tilde>(
        LawBlock::subloading, "u_tilde", ParameterUnit::per_slip, ParameterBound::positive, false,
        "rate of approach of r_s to 1"),
    detail::entry<&LawParameters::overstress, &Overstress::eta_v>(
        LawBlock::overstress, "eta_v", ParameterUnit::time_per_slip, ParameterBound::positive, true,
        "viscoplastic coefficient"),
    detail::entry<&LawParameters::overstress, &Overstress::n>(
        LawBlock::overstress, "n", ParameterUnit::none, ParameterBound::positive, true,
        "viscoplastic exponent"),
    detail::entry<&LawParameters::overstress, &Overstress::r_hat>(
        LawBlock::overstress, "r_hat", ParameterUnit::none, ParameterBound::above_one, true,
        "limit dynamic loading ratio"),
};

inline constexpr int kParameterCount = static_cast<int>(kLawParameters.size());
// The derivatives of one value with respect to the constants, a row in the order of
// kLawParameters (forward sensitivities: contact/contact_point.hpp).
using ParameterGradient = Eigen::Matrix<double, 1, kParameterCount>;

// A block's key in a scene, and its named choice (the key in the block and the attribute a
// result file writes it as, before the block's numbers; empty: none).
struct LawBlockInfo {
  LawBlock block;
  std::string_view key;
  std::string_view choice_key;
  std::string_view choice_attribute;
  std::string_view (*choice)(const LawParameters&);  // nullptr without a choice
};

inline constexpr std::array<LawBlockInfo, 3> kLawBlocks = {{
    {LawBlock::friction, "friction", "", "", nullptr},
    {LawBlock::subloading, "subloading", "function", "subloading_function",
     [](const LawParameters& p) { return to_string(p.subloading.function); }},
    {LawBlock::overstress, "overstress", "form", "overstress_form",
     [](const LawParameters& p) { return to_string(p.overstress.form); }},
}};

// The table entry of a constant named `name`, or nullptr.
constexpr const LawParameterInfo* find_law_parameter(std::string_view name) {
  for (const auto& p : kLawParameters) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

}  // namespace subslip::law
