// Physical units of scene values: the base units of stress, length and time, the units built
// from them (mm/min, 1/s, MPa/mm, min/mm), and exact conversions between them.
//
// Every scene names its unit system in its `units` block; a bare number is in that system, and
// a number followed by a unit ("168.4 GPa", "60 min", "1 mm/min") is converted into it when
// the scene is read. Every unit of a dimension is 10^a 60^b times the SI one (Pa, m, s), so the
// factor between two units is an exact ratio of integers, and a conversion is one
// correctly-rounded multiplication or division whenever that ratio or its inverse is an integer
// (GPa -> MPa, mm -> um, h -> s, mm/s -> mm/min), else a multiplication and a division.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace subslip::model {

// The exponents of stress, length and time in a quantity: velocity is {0, 1, -1}.
struct Dimension {
  int stress = 0;
  int length = 0;
  int time = 0;
  friend constexpr bool operator==(const Dimension&, const Dimension&) = default;
};

namespace dimension {
inline constexpr Dimension none{};
inline constexpr Dimension stress{1, 0, 0};
inline constexpr Dimension length{0, 1, 0};
inline constexpr Dimension time{0, 0, 1};
inline constexpr Dimension velocity{0, 1, -1};         // sliding speeds
inline constexpr Dimension per_length{0, -1, 0};       // kappa, u_tilde of a contact
inline constexpr Dimension per_time{0, 0, -1};         // xi, velocity gradients
inline constexpr Dimension time_per_length{0, -1, 1};  // eta_v of a contact
inline constexpr Dimension stiffness{1, -1, 0};        // alpha_n, alpha_t
}  // namespace dimension

// "stress", "length/time", "1/time", "stress/length", "1" (dimensionless).
std::string describe(Dimension d);

// An exact factor 10^pow10 * 60^pow60 (a unit relative to its SI unit: mm = 10^-3, h = 60^2).
struct Scale {
  int pow10 = 0;
  int pow60 = 0;
  friend constexpr bool operator==(const Scale&, const Scale&) = default;
};

// A unit: its dimension, its factor to SI, and its name as the scene writes it after reading
// (canonical: "um" for "µm" or "μm").
struct Unit {
  Dimension dimension;
  Scale scale;
  std::string name;
};

// The base units of each kind, in increasing size (the names a `units` block takes).
const std::vector<std::string_view>& stress_unit_names();  // Pa kPa MPa GPa
const std::vector<std::string_view>& length_unit_names();  // m cm mm um nm (and µm, μm)
const std::vector<std::string_view>& time_unit_names();    // s ms min h

// A base unit by name (one of the lists above), or nullopt.
std::optional<Unit> base_unit(std::string_view name);

// Parses a unit: a base unit ("MPa"), a quotient of base units ("mm/min", "MPa/mm", "min/mm")
// or a reciprocal ("1/s"). nullopt when `text` is not one.
std::optional<Unit> parse_unit(std::string_view text);

// The units a quantity of dimension `d` can be written in, as spelled in messages and
// suggestions (for "1/time": 1/s, 1/ms, 1/min, 1/h). Empty for the dimensionless.
std::vector<std::string> unit_names_of(Dimension d);

// The units a quantity of dimension `d` takes, for messages: "Pa, kPa, MPa or GPa",
// "1/s, 1/ms, 1/min or 1/h", "a length unit (m, cm, mm, um, nm) / a time unit (s, ms, min, h)".
std::string units_for(Dimension d);

// One line listing every supported unit, for error messages.
std::string supported_units();

// `value` given in a unit of scale `from`, expressed in a unit of scale `to` (same dimension).
// Exact when the result is representable and the ratio is an integer or its inverse one; a
// multiplication then a division otherwise.
double convert(double value, Scale from, Scale to);

// The SI value of `value` given in a unit of scale `from`.
double to_si(double value, Scale from);

// The unit system of a scene (its `units` block): every value is computed and every output
// written in it. A bare number in the scene is in these units; a number written with a unit
// ("168.4 GPa", "60 min", "1 mm/min") is converted into them when the scene is read.
struct Units {
  std::string stress = "MPa";  // Pa | kPa | MPa | GPa
  std::string length = "mm";   // m | cm | mm | um | nm; empty for a scene kind without lengths
  std::string time = "min";    // s | ms | min | h

  // The unit of this system for a quantity of dimension `d`: {stress/length, 10^3, "MPa/mm"}.
  // "1" for the dimensionless; a dimension with a length needs `length`.
  Unit unit(Dimension d) const;

  std::string velocity() const { return length + "/" + time; }         // sliding speed
  std::string per_length() const { return "1/" + length; }             // kappa, u_tilde
  std::string per_time() const { return "1/" + time; }                 // xi
  std::string time_per_length() const { return time + "/" + length; }  // eta_v
  std::string stiffness() const { return stress + "/" + length; }      // alpha_n, alpha_t
  // (name, unit) pairs, for the /units group of a result file.
  std::vector<std::pair<std::string, std::string>> entries() const;
};

inline constexpr std::string_view kDimensionless = "1";

}  // namespace subslip::model
