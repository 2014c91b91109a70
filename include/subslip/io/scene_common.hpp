// Pieces every scene parser shares: the `scene:` kind, the `units:` block, values read in the
// scene's units and the stepping of loading segments (the units and values themselves are the
// run model's: model/units.hpp, model/case_common.hpp).
#pragma once

#include <cstddef>
#include <initializer_list>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "subslip/io/input_error.hpp"
#include "subslip/io/units.hpp"
#include "subslip/io/yaml_checked.hpp"
#include "subslip/model/case_common.hpp"
#include "subslip/model/series_compression.hpp"

namespace subslip::io {

using model::count_output_states;
using model::Magnitude;
using model::WrittenValue;

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

// The finished file's series storage from a scene's `output` block: `compression: gzip` (the
// default, level model::SeriesCompression{}.gzip_level) or `none`, and with gzip
// `compression_level: 1 ... 9`.
model::SeriesCompression parse_compression(const std::optional<CheckedNode>& output);
inline constexpr std::string_view kCompressionKeys[] = {"compression", "compression_level"};

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

// A loading segment's `increments`, `growth` and `output_every` into `seg`, each error into
// `errors`; the increment lengths are checked once these and the duration (`duration_known`)
// are read, so that an error there is not reported again as a length problem.
template <class Segment>
void parse_increments(const CheckedNode& node, Segment& seg, bool duration_known,
                      InputErrorList& errors) {
  bool lengths = errors.attempt([&] {
    seg.increments = node.get_int("increments", Range::at_least(1));
  }) && duration_known;
  lengths = errors.attempt([&] {
    seg.growth = node.get_double("growth", 1.0, Range::positive());
  }) && lengths;
  errors.attempt([&] { seg.output_every = node.get_int("output_every", 1, Range::at_least(1)); });
  if (lengths)
    errors.attempt(
        [&] { check_increment_lengths(node, seg.duration, seg.increments, seg.growth); });
}

// The order a tolerance gets when a scene names none: the lowest whose error follows the
// tolerance (backward Euler advanced with its extrapolated solution; backward Euler's own
// estimate, order 1, keeps the local error of a first-order method at the tolerance, and its
// error follows the square root of it). docs/integrators.md, "Which to pick".
inline constexpr int kDefaultAdaptiveOrder = 2;

// The `order` of an `integrator` block (1: backward Euler's own estimate, 2 .. 4: extrapolated;
// integrators/extrapolation.hpp), given its adaptive tolerance (0: fixed increments, where an
// order is an error). With a tolerance and no `order`: kDefaultAdaptiveOrder; without
// one, 1 (no estimate), what the options' default records.
int parse_adaptive_order(const CheckedNode& integrator, double tolerance);

// The value of the root `scene:` key, checked against `known` kinds (with a suggestion). A fit
// file (`fit:` instead of `scene:`, io/fit_file.hpp) is refused with the command that reads it.
std::string scene_kind(const YamlDocument& document, std::initializer_list<std::string_view> known);

}  // namespace subslip::io
