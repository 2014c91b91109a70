// Pieces every scene kind shares: the `scene:` kind, the `units:` block, unit strings and the
// stepping of loading segments.
#pragma once

#include <cstddef>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "subslip/io/units.hpp"
#include "subslip/io/yaml_checked.hpp"

namespace subslip::io {

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

// A value whose magnitude the plausibility warnings check (scene_warnings.hpp): what it is,
// its value in the scene's units, and where it was written.
enum class Magnitude {
  elastic_constant,  // C11 ... C44, E, G of a crystal phase [stress]
  tau0,              // a reference stress of slip systems [stress]
  normal_traction,   // f_n of a contact, initial or ramped to [stress]
  sliding_speed,     // a non-zero sliding speed [length/time]
  strain_rate,       // a non-zero prescribed velocity-gradient component [1/time]
  duration,          // a segment duration as written [time]
};

struct WrittenValue {
  Magnitude kind;
  double value = 0.0;                 // in the scene's units
  std::string key;                    // the key path
  int line = 0;                       // 1-based line in the scene file
  std::optional<double> bare_number;  // the number as written, when it was written without a unit
};

// The record of `value` (in the scene's units) read from `node`.
WrittenValue written_value(const CheckedNode& node, Magnitude kind, double value);

// Reads the values of one scene case in the scene's units (converting those written with a
// unit) and keeps the magnitudes the plausibility warnings check.
class SceneValues {
 public:
  explicit SceneValues(const Units& units) : units_(units) {}
  const Units& units() const { return units_; }
  Unit unit(Dimension d) const { return units_.unit(d); }

  double read(const CheckedNode& node, Dimension d, const Range& range = Range::any()) const {
    return node.as_quantity(units_.unit(d), range);
  }
  double get(const CheckedNode& map, std::string_view key, Dimension d,
             const Range& range = Range::any()) const {
    return map.get_quantity(key, units_.unit(d), range);
  }
  // Records `value` (in the scene's units, read from `node`) for the plausibility warnings.
  void note(const CheckedNode& node, Magnitude kind, double value) {
    magnitudes_.push_back(written_value(node, kind, value));
  }
  // read() and note().
  double read_noted(const CheckedNode& node, Dimension d, Magnitude kind,
                    const Range& range = Range::any()) {
    const double v = read(node, d, range);
    note(node, kind, v);
    return v;
  }
  double get_noted(const CheckedNode& map, std::string_view key, Dimension d, Magnitude kind,
                   const Range& range = Range::any()) {
    return read_noted(map.required(key), d, kind, range);
  }
  std::vector<WrittenValue> take_magnitudes() { return std::move(magnitudes_); }

 private:
  const Units& units_;
  std::vector<WrittenValue> magnitudes_;
};

// Reads `units: {stress: MPa, length: mm, time: min}` (all three required; `um` may be written
// as `µm`, and is stored as `um`).
Units parse_units(const CheckedNode& node);
// The same for a scene kind without lengths (crystals: slip is dimensionless): `length` is
// accepted and checked when given, else left empty.
Units parse_units_without_length(const CheckedNode& node);

// Checks the stepping of a loading segment (a mapping with `increments` and optionally
// `growth`): `increments` lengths in geometric progression with ratio `growth`, summing to
// `duration`, must all be usable numbers. growth^(increments - 1) must not overflow (reported at
// `growth`) and the smallest increment must not underflow (reported at `increments`).
void check_increment_lengths(const CheckedNode& segment, double duration, int increments,
                             double growth);

// How many states a loading history writes: the initial one, then every `output_every`-th
// increment of each segment and always its last, or one per output time when the segment
// lists them (for any segment type with `increments`, `output_every` and output times).
template <class Segment>
std::size_t count_output_states(const std::vector<Segment>& segments) {
  std::size_t n = 1;  // the initial state
  for (const auto& s : segments) {
    if (s.output_at_times) {
      n += s.output_times.size();
      continue;
    }
    const auto inc = static_cast<std::size_t>(s.increments);
    const auto every = static_cast<std::size_t>(s.output_every);
    n += inc / every + (inc % every != 0 ? 1 : 0);
  }
  return n;
}

// The `order` of an `integrator` block (1: backward Euler's own estimate, 2 .. 4: extrapolated;
// integrators/extrapolation.hpp), given its adaptive tolerance (0: fixed increments, where an
// order is an error).
int parse_adaptive_order(const CheckedNode& integrator, double tolerance);

// The value of the root `scene:` key, checked against `known` kinds (with a suggestion).
std::string scene_kind(const YamlDocument& document, std::initializer_list<std::string_view> known);

}  // namespace subslip::io
