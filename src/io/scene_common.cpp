#include "subslip/io/scene_common.hpp"

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

std::string scene_kind(const YamlDocument& document,
                       std::initializer_list<std::string_view> known) {
  const CheckedNode root = document.root();
  root.expect_map();
  return root.get_choice("scene", known);
}

}  // namespace subslip::io
