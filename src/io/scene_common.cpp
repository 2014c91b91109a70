#include "subslip/io/scene_common.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace subslip::io {

std::vector<std::pair<std::string, std::string>> Units::entries() const {
  return {{"stress", stress}, {"length", length}, {"time", time}};
}

namespace {

// `length_required == false`: a missing length is left empty (scene kinds without lengths).
Units read_units(const CheckedNode& node, bool length_required) {
  node.allow_keys({"stress", "length", "time"});
  Units u;
  u.stress = node.get_choice("stress", {"Pa", "kPa", "MPa", "GPa"});
  u.length = length_required || node.has("length")
                 ? node.get_choice("length", {"m", "mm", "um", "nm"})
                 : std::string();
  u.time = node.get_choice("time", {"s", "ms", "min", "h"});
  return u;
}

}  // namespace

Units parse_units(const CheckedNode& node) {
  return read_units(node, true);
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

std::string scene_kind(const YamlDocument& document,
                       std::initializer_list<std::string_view> known) {
  const CheckedNode root = document.root();
  root.expect_map();
  return root.get_choice("scene", known);
}

}  // namespace subslip::io
