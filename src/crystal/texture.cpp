#include "subslip/crystal/texture.hpp"

#include <Eigen/Geometry>
#include <array>
#include <cmath>
#include <numbers>
#include <sstream>
#include <stdexcept>

namespace subslip::crystal {

namespace {

constexpr double kTwoPi = 2.0 * std::numbers::pi;

struct ComponentData {
  TextureComponent component;
  std::string_view name;
  Eigen::Vector3d plane;      // {hkl} parallel to the sheet
  Eigen::Vector3d direction;  // <uvw> along RD
};

const std::array<ComponentData, 5>& components() {
  static const std::array<ComponentData, 5> table{{
      {TextureComponent::cube, "cube", {0, 0, 1}, {1, 0, 0}},
      {TextureComponent::goss, "goss", {0, 1, 1}, {1, 0, 0}},
      {TextureComponent::brass, "brass", {0, 1, 1}, {2, -1, 1}},
      {TextureComponent::copper, "copper", {1, 1, 2}, {-1, -1, 1}},
      {TextureComponent::s, "s", {2, 1, 3}, {-3, -6, 4}},
  }};
  return table;
}

const ComponentData& data_of(TextureComponent component) {
  for (const ComponentData& data : components()) {
    if (data.component == component) return data;
  }
  throw std::invalid_argument("texture component out of range");
}

// The orientation whose sample axes x, y, z have the crystal components x_c, y_c, z_c: these are
// the columns of g (v_crystal = g v_sample).
Orientation orientation_from_sample_axes(const Eigen::Vector3d& x_c, const Eigen::Vector3d& y_c,
                                         const Eigen::Vector3d& z_c) {
  Eigen::Matrix3d g;
  g.col(0) = x_c;
  g.col(1) = y_c;
  g.col(2) = z_c;
  return Orientation::from_matrix(g);
}

void require_perpendicular(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const char* what) {
  if (!(a.norm() > 0.0) || !(b.norm() > 0.0)) {
    throw std::invalid_argument(std::string(what) + ": directions must be non-zero");
  }
  if (std::abs(a.normalized().dot(b.normalized())) > 1e-9) {
    throw std::invalid_argument(std::string(what) + ": directions must be perpendicular");
  }
}

}  // namespace

std::string_view to_string(TextureComponent component) {
  return data_of(component).name;
}

TextureComponent parse_texture_component(std::string_view name) {
  std::string valid;
  for (const ComponentData& data : components()) {
    if (data.name == name) return data.component;
    valid += (valid.empty() ? "" : ", ") + std::string(data.name);
  }
  throw std::invalid_argument("unknown texture component '" + std::string(name) +
                              "'; valid names: " + valid);
}

Orientation ideal_orientation(TextureComponent component) {
  const ComponentData& data = data_of(component);
  return orientation_from_plane_and_direction(data.plane, data.direction);
}

Orientation orientation_from_plane_and_direction(const Eigen::Vector3d& hkl,
                                                 const Eigen::Vector3d& uvw) {
  require_perpendicular(hkl, uvw, "texture component {hkl}<uvw>");
  const Eigen::Vector3d rd = uvw.normalized();
  const Eigen::Vector3d nd = hkl.normalized();
  return orientation_from_sample_axes(rd, nd.cross(rd), nd);
}

Orientation single_crystal_orientation(const Eigen::Vector3d& along_x,
                                       const Eigen::Vector3d& along_y) {
  require_perpendicular(along_x, along_y, "single crystal orientation");
  const Eigen::Vector3d x = along_x.normalized();
  const Eigen::Vector3d y = along_y.normalized();
  return orientation_from_sample_axes(x, y, x.cross(y));
}

double uniform01(std::mt19937_64& engine) {
  return double(engine() >> 11) * 0x1.0p-53;
}

double standard_normal(std::mt19937_64& engine) {
  const double u1 = 1.0 - uniform01(engine);  // (0, 1]: log is finite
  const double u2 = uniform01(engine);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(kTwoPi * u2);
}

Quaternion random_quaternion(std::mt19937_64& engine) {
  const double u1 = uniform01(engine);
  const double u2 = uniform01(engine);
  const double u3 = uniform01(engine);
  const double a = std::sqrt(1.0 - u1);
  const double b = std::sqrt(u1);
  const Quaternion q{b * std::cos(kTwoPi * u3), a * std::sin(kTwoPi * u2),
                     a * std::cos(kTwoPi * u2), b * std::sin(kTwoPi * u3)};
  return q.canonical();
}

Eigen::Vector3d random_rotation_vector(std::mt19937_64& engine, double spread) {
  const double sigma = spread / std::sqrt(3.0);
  const double x = standard_normal(engine);
  const double y = standard_normal(engine);
  const double z = standard_normal(engine);
  return sigma * Eigen::Vector3d(x, y, z);
}

namespace {

void require_spread(double spread_deg) {
  if (!(spread_deg >= 0.0 && spread_deg <= 180.0)) {
    throw std::invalid_argument("texture spread must be in [0, 180] degrees, got " +
                                std::to_string(spread_deg));
  }
}

// Each orientation draws a fixed number of numbers from one engine, in order, so that a set is
// the same whether it is kept whole or visited one orientation at a time.
template <class Each>
void visit_random(std::size_t count, std::uint64_t seed, Each&& each) {
  std::mt19937_64 engine(seed);
  for (std::size_t i = 0; i < count; ++i) each(Orientation::from_quaternion(random_quaternion(engine)));
}

template <class Each>
void visit_component(TextureComponent component, std::size_t count, double spread_deg,
                     std::uint64_t seed, Each&& each) {
  require_spread(spread_deg);
  const Eigen::Matrix3d ideal = ideal_orientation(component).g;
  const double spread = spread_deg * std::numbers::pi / 180.0;
  std::mt19937_64 engine(seed);
  for (std::size_t i = 0; i < count; ++i) {
    const Eigen::Vector3d turn = random_rotation_vector(engine, spread);
    each(Orientation::from_matrix(apply_sample_spin(ideal, turn)));
  }
}

template <class Each>
void visit_generated(const OrientationRequest& request, Each&& each) {
  if (request.count == 0) throw std::invalid_argument("orientation count must be at least 1");
  if (request.component)
    visit_component(*request.component, request.count, request.spread_deg, request.seed, each);
  else
    visit_random(request.count, request.seed, each);
}

}  // namespace

std::vector<Orientation> random_orientations(std::size_t count, std::uint64_t seed) {
  std::vector<Orientation> orientations;
  orientations.reserve(count);
  visit_random(count, seed, [&](const Orientation& o) { orientations.push_back(o); });
  return orientations;
}

std::vector<Orientation> component_orientations(TextureComponent component, std::size_t count,
                                                double spread_deg, std::uint64_t seed) {
  std::vector<Orientation> orientations;
  orientations.reserve(count);
  visit_component(component, count, spread_deg, seed,
                  [&](const Orientation& o) { orientations.push_back(o); });
  return orientations;
}

std::vector<Orientation> generate_orientations(const OrientationRequest& request) {
  std::vector<Orientation> orientations;
  if (request.count > 0) orientations.reserve(request.count);
  visit_generated(request, [&](const Orientation& o) { orientations.push_back(o); });
  return orientations;
}

void for_each_generated_orientation(const OrientationRequest& request,
                                    const std::function<void(const Orientation&)>& each) {
  visit_generated(request, each);
}

std::string describe(const OrientationRequest& request) {
  std::ostringstream text;
  if (request.component) {
    text << "component=" << to_string(*request.component) << " spread_deg=" << request.spread_deg
         << " ";
  } else {
    text << "random ";
  }
  text << "count=" << request.count << " seed=" << request.seed;
  return text.str();
}

}  // namespace subslip::crystal
