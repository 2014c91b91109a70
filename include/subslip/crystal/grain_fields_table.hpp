// The per-grain output fields, each once: its name (in a scene's `output.grains` and as the
// dataset grains/<name> of a result file), how many values a grain has as the aggregate gives
// them (GrainFields, aggregate.hpp) and as the file stores them, its unit kind, its description
// and the meaning of its trailing axis. The scene parser checks `output.grains` against it, the
// aggregate, the driver's gathering and the crystal writer size and label their rows from it,
// and the Python package reads names, units and descriptions back from the datasets.
#pragma once

#include <array>
#include <cstddef>
#include <string_view>

namespace subslip::crystal {

// In output order.
enum class GrainField { stress, orientation, slip, slip_rate, crss, strength, r, r_s, tau };

// How the file stores a grain's value of a field.
enum class GrainFieldShape {
  tensor,      // a 3x3 tensor (symmetric ones in full), the file's tensor convention
  quaternion,  // 4 values (w x y z)
  per_system,  // one value per slip system
};

enum class GrainFieldUnit { none, stress, per_time };

struct GrainFieldInfo {
  GrainField field;
  std::string_view name;
  // Values per grain as GrainFields gives them: 6 (Voigt stress), 9 (orientation matrix);
  // 0: one per slip system.
  int given_width;
  GrainFieldShape stored;
  GrainFieldUnit unit;
  std::string_view description;
  std::string_view components;  // the trailing axis ("" for a tensor: the file's convention)
};

inline constexpr std::string_view kPerSystemComponents =
    "one value per slip system, in the order of slip_systems";

inline constexpr std::array<GrainFieldInfo, 9> kGrainFieldTable = {{
    {GrainField::stress, "stress", 6, GrainFieldShape::tensor, GrainFieldUnit::stress,
     "Cauchy stress of each grain, sample frame", ""},
    {GrainField::orientation, "orientation", 9, GrainFieldShape::quaternion, GrainFieldUnit::none,
     "orientation of each grain (passive, Rowenhorst P=-1, w>=0; maps sample to crystal)",
     "w x y z"},
    {GrainField::slip, "slip", 0, GrainFieldShape::per_system, GrainFieldUnit::none,
     "accumulated signed slip", kPerSystemComponents},
    {GrainField::slip_rate, "slip_rate", 0, GrainFieldShape::per_system, GrainFieldUnit::per_time,
     "signed slip rate over the last increment", kPerSystemComponents},
    {GrainField::crss, "crss", 0, GrainFieldShape::per_system, GrainFieldUnit::stress,
     "critical resolved shear stress mu tau0", kPerSystemComponents},
    {GrainField::strength, "strength", 0, GrainFieldShape::per_system, GrainFieldUnit::stress,
     "yield traction mu f_n (the CRSS mu tau0 without the pressure-sensitive reading; at most 0 "
     "where the plane is open)",
     kPerSystemComponents},
    {GrainField::r, "r", 0, GrainFieldShape::per_system, GrainFieldUnit::none,
     "dynamic loading ratio r = |tau| / (mu f_n)", kPerSystemComponents},
    {GrainField::r_s, "r_s", 0, GrainFieldShape::per_system, GrainFieldUnit::none,
     "subloading ratio r_s", kPerSystemComponents},
    {GrainField::tau, "tau", 0, GrainFieldShape::per_system, GrainFieldUnit::stress,
     "resolved shear stress tau = P : sigma (signed, along the slip direction)",
     kPerSystemComponents},
}};

// Every field, in output order (the table's order).
inline constexpr std::array<GrainField, kGrainFieldTable.size()> kAllGrainFields = [] {
  std::array<GrainField, kGrainFieldTable.size()> all{};
  for (std::size_t k = 0; k < all.size(); ++k) all[k] = kGrainFieldTable[k].field;
  return all;
}();

constexpr const GrainFieldInfo& info(GrainField f) {
  return kGrainFieldTable[static_cast<std::size_t>(f)];
}
constexpr std::string_view to_string(GrainField f) {
  return info(f).name;
}

// Values per grain as GrainFields gives them, for a phase of `slip_count` systems.
constexpr std::size_t given_width(GrainField f, std::size_t slip_count) {
  return info(f).given_width > 0 ? static_cast<std::size_t>(info(f).given_width) : slip_count;
}

// Values per grain as the file stores them.
constexpr std::size_t stored_width(GrainField f, std::size_t slip_count) {
  switch (info(f).stored) {
    case GrainFieldShape::tensor:
      return 9;
    case GrainFieldShape::quaternion:
      return 4;
    case GrainFieldShape::per_system:
      break;
  }
  return slip_count;
}

// The table is indexed by the enum: each entry at its own value.
static_assert([] {
  for (std::size_t k = 0; k < kGrainFieldTable.size(); ++k) {
    if (static_cast<std::size_t>(kGrainFieldTable[k].field) != k) return false;
  }
  return true;
}());

}  // namespace subslip::crystal
