#include "subslip/model/crystal_case.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>

namespace subslip::model {

std::string_view to_string(MacroField f) {
  switch (f) {
    case MacroField::time:
      return "time";
    case MacroField::L:
      return "L";
    case MacroField::F:
      return "F";
    case MacroField::strain:
      return "strain";
    case MacroField::stress:
      return "stress";
    case MacroField::segment:
      return "segment";
  }
  return "?";
}

void OrientationDigest::add(const crystal::Orientation& o) {
  const auto mix = [this](double x) {
    unsigned char bytes[sizeof x];
    std::memcpy(bytes, &x, sizeof x);
    for (unsigned char b : bytes) hash_ = (hash_ ^ b) * 1099511628211ull;
  };
  for (double v : {o.q.w, o.q.x, o.q.y, o.q.z, o.weight}) mix(v);
}

std::string OrientationDigest::text() const {
  char text[40];
  std::snprintf(text, sizeof text, "fnv1a64:%016llx", static_cast<unsigned long long>(hash_));
  return text;
}

std::string orientations_digest(const std::vector<crystal::Orientation>& orientations) {
  OrientationDigest d;
  for (const auto& o : orientations) d.add(o);
  return d.text();
}

std::string CrystalCase::orientations_digest() const {
  return orientation_block ? orientation_block->digest : model::orientations_digest(orientations);
}

void read_all_orientations(CrystalCase& c) {
  const OrientationOrigin& origin = c.orientation_origin;
  c.orientation_block.reset();
  if (origin.file) {
    std::vector<crystal::Orientation> read;
    origin.file->read([&](const crystal::Orientation& o) { read.push_back(o); },
                      c.orientation_source.largest_euler_deg);
    // Weights are normalised by their sum, which must not overflow.
    double sum = 0.0;
    for (const auto& o : read) sum += o.weight;
    if (!std::isfinite(sum)) origin.file->fail_weights();
    c.orientations = std::move(read);
  } else if (origin.generated) {
    c.orientations = crystal::generate_orientations(*origin.generated);
  } else {
    c.orientations = origin.given;
  }
}

void read_all_orientations(CrystalScene& scene) {
  for (CrystalCase& c : scene.cases) read_all_orientations(c);
}

std::vector<std::pair<std::string, std::string>> crystal_units(const Units& units) {
  return {{"stress", units.stress}, {"time", units.time}};
}

std::size_t crystal_output_count(const std::vector<crystal::LoadSegment>& segments) {
  return count_output_states(segments);
}

}  // namespace subslip::model
