#include "subslip/io/scene_common.hpp"

namespace subslip::io {

std::vector<std::pair<std::string, std::string>> Units::entries() const {
  return {{"stress", stress}, {"length", length}, {"time", time}};
}

Units parse_units(const CheckedNode& node) {
  node.allow_keys({"stress", "length", "time"});
  Units u;
  u.stress = node.get_choice("stress", {"Pa", "kPa", "MPa", "GPa"});
  u.length = node.get_choice("length", {"m", "mm", "um", "nm"});
  u.time = node.get_choice("time", {"s", "ms", "min", "h"});
  return u;
}

std::string scene_kind(const YamlDocument& document,
                       std::initializer_list<std::string_view> known) {
  const CheckedNode root = document.root();
  root.expect_map();
  return root.get_choice("scene", known);
}

}  // namespace subslip::io
