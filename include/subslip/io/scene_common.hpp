// Pieces every scene kind shares: the `scene:` kind, the `units:` block, unit strings and the
// stepping of loading segments.
#pragma once

#include <cstddef>
#include <initializer_list>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "subslip/io/yaml_checked.hpp"

namespace subslip::io {

// The units a scene is written in. No conversion happens anywhere: every value of the scene is
// read in these units and every output carries them.
struct Units {
  std::string stress = "MPa";  // Pa | kPa | MPa | GPa
  std::string length = "mm";   // m | mm | um | nm
  std::string time = "min";    // s | ms | min | h

  std::string velocity() const { return length + "/" + time; }         // sliding speed
  std::string per_length() const { return "1/" + length; }             // kappa, u_tilde
  std::string per_time() const { return "1/" + time; }                 // xi
  std::string time_per_length() const { return time + "/" + length; }  // eta_v
  std::string stiffness() const { return stress + "/" + length; }      // alpha_n, alpha_t
  // (name, unit) pairs, for the /units group of a result file.
  std::vector<std::pair<std::string, std::string>> entries() const;
};

inline constexpr std::string_view kDimensionless = "1";

// Reads `units: {stress: MPa, length: mm, time: min}` (all three required).
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

// The value of the root `scene:` key, checked against `known` kinds (with a suggestion).
std::string scene_kind(const YamlDocument& document, std::initializer_list<std::string_view> known);

}  // namespace subslip::io
