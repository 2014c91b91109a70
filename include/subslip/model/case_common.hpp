// What every case of a run model carries besides its physics, whatever the scene kind: the
// values a sweep set, the magnitudes the plausibility warnings check, and how many states a
// loading history writes.
#pragma once

#include <cstddef>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace subslip::model {

// One value a sweep set in a case (io/sweep.hpp expands the `sweep:` block).
struct SweepOverride {
  std::string path;              // as written in the sweep block
  std::string value;             // the value's text (flow style for non-scalars)
  std::optional<double> number;  // the value when it is a number
};

// What a scene was made of besides its own file (io/scene_compose.hpp): the base scenes it
// names, one over another (file, text), and the `--set PATH=VALUE` settings, in order.
struct SceneMakeup {
  std::vector<std::pair<std::string, std::string>> bases;
  std::vector<std::string> settings;
  bool empty() const { return bases.empty() && settings.empty(); }
};

// A value whose magnitude the plausibility warnings check (io/scene_warnings.hpp): what it is,
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

}  // namespace subslip::model
