#include "subslip/io/scene_common.hpp"

#include "subslip/integrators/extrapolation.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace subslip::io {

WrittenValue written_value(const CheckedNode& node, Magnitude kind, double value) {
  WrittenValue w{kind, value, node.path(), node.line(), std::nullopt};
  if (node.is_scalar()) w.bare_number = parse_number(node.yaml().Scalar());
  return w;
}

namespace {

// A base unit name of the kind of `key`, stored canonically ("um" for "µm").
std::string read_unit_name(const CheckedNode& node, std::string_view key,
                           const std::vector<std::string_view>& names) {
  return base_unit(node.required(key).as_choice(names))->name;
}

// `length_required == false`: a missing length is left empty (scene kinds without lengths).
Units read_units(const CheckedNode& node, bool length_required) {
  node.allow_keys({"stress", "length", "time"});
  Units u;
  u.stress = read_unit_name(node, "stress", stress_unit_names());
  u.length = length_required || node.has("length")
                 ? read_unit_name(node, "length", length_unit_names())
                 : std::string();
  u.time = read_unit_name(node, "time", time_unit_names());
  return u;
}

}  // namespace

Units parse_units(const CheckedNode& node) {
  return read_units(node, true);
}

model::SeriesCompression parse_compression(const std::optional<CheckedNode>& output) {
  model::SeriesCompression compression;
  if (!output) return compression;
  const auto method = output->optional("compression");
  const bool gzip = !method || method->as_choice({"gzip", "none"}) == "gzip";
  const auto level = output->optional("compression_level");
  if (!gzip) {
    if (level) level->fail("sets the level of gzip compression; drop it with 'compression: none'");
    compression.gzip_level = 0;
    return compression;
  }
  if (level) compression.gzip_level = level->as_int(Range::in_closed_interval(1, 9));
  return compression;
}

Units parse_units_without_length(const CheckedNode& node) {
  return read_units(node, false);
}

void check_increment_lengths(const CheckedNode& segment, double duration, int increments,
                             double growth) {
  // ln(growth^(n-1)) beyond this would overflow the increment lengths.
  constexpr double kMaxLogGrowth = 600.0;
  const double n = increments;
  const double log_growth = std::log(growth);
  if (std::abs(log_growth) * (n - 1) > kMaxLogGrowth)
    segment.required("growth").fail("growth^(increments - 1) overflows; use a growth closer to 1");
  // The lengths are duration * growth^k / sum, sum = (growth^n - 1) / (growth - 1); the
  // smallest is the first (growth >= 1) or the last one.
  const double sum = growth == 1.0 ? n : std::expm1(n * log_growth) / (growth - 1.0);
  const double smallest = duration * std::exp(std::min(0.0, (n - 1) * log_growth)) / sum;
  if (!(smallest >= std::numeric_limits<double>::min())) {
    segment.required("increments")
        .fail(
            "the smallest increment underflows double precision; use fewer increments, a "
            "growth closer to 1 or a longer segment");
  }
}

int parse_adaptive_order(const CheckedNode& integrator, double tolerance) {
  // With a tolerance the default is the lowest order whose error follows the tolerance
  // (docs/integrators.md); backward Euler's own estimate (order 1), whose error follows its
  // square root, is there by name. Without one, no estimate is made and the order is 1.
  const int default_order = tolerance > 0.0 ? kDefaultAdaptiveOrder : 1;
  const auto order = integrator.optional("order");
  if (!order) return default_order;
  if (!(tolerance > 0.0))
    order->fail("order is that of adaptive stepping: give a tolerance (method: implicit)");
  return integrator.get_int("order", default_order,
                            Range::in_closed_interval(1, integrators::kMaxExtrapolationOrder));
}

std::string scene_kind(const YamlDocument& document,
                       std::initializer_list<std::string_view> known) {
  const CheckedNode root = document.root();
  root.expect_map();
  // A fit file (io/fit_file.hpp) is no scene: say which command reads it.
  if (root.has("fit") && !root.has("scene"))
    root.required("fit").fail("this is a fit file, not a scene: run it with 'subslip fit'");
  return root.get_choice("scene", known);
}

}  // namespace subslip::io
