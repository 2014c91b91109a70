#include "subslip/io/case_group.hpp"

namespace subslip::io {

namespace {

void write_sweep_overrides(const h5::Group& g, std::span<const SweepOverride> overrides) {
  for (const SweepOverride& o : overrides) {
    if (o.number) {
      g.set_attribute("sweep:" + o.path, *o.number);
    } else {
      g.set_attribute("sweep:" + o.path, o.value);
    }
  }
}

}  // namespace

h5::Group create_case_group(const h5::Group& cases, const std::string& name, int index,
                            std::span<const SweepOverride> overrides) {
  h5::Group group = cases.create_group(name);
  group.set_attribute("name", name);
  group.set_attribute("index", index);
  write_sweep_overrides(group, overrides);
  return group;
}

}  // namespace subslip::io
