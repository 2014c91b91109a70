// Orientation sets: uniformly random orientations, standard rolling-texture components with a
// spread, and single crystals with a chosen crystal direction along the sample x (tension) axis.
//
// All orientations follow rotation.hpp: g maps sample components to crystal components. Sample
// axes for texture components: x = RD (rolling direction), y = TD, z = ND (sheet normal).
//
// Reproducibility: the generators draw from std::mt19937_64, whose output sequence is fixed by
// the standard, and turn its 64-bit integers into uniform and normal numbers with explicit
// formulas (53-bit mantissa; Box-Muller) rather than std::uniform_real_distribution or
// std::normal_distribution, whose algorithms differ between standard libraries. The same seed
// therefore gives the same orientations on every platform (up to the last bits of libm).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <optional>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "subslip/crystal/rotation.hpp"

namespace subslip::crystal {

// Ideal components {hkl}<uvw>: the plane {hkl} is parallel to the sheet (normal along ND) and
// the direction <uvw> is the rolling direction. Bunge Euler angles (phi1, Phi, phi2) in degrees
// as commonly tabulated for fcc rolling textures (passive Bunge convention, sample axes RD, TD,
// ND; e.g. Engler & Randle, Introduction to Texture Analysis, 2nd ed., CRC 2010):
//   cube    {001}<100>    0      0      0
//   goss    {011}<100>    0      45     0
//   brass   {011}<211>    35.26  45     0
//   copper  {112}<111>    90     35.26  45
//   s       {123}<634>    58.98  36.70  63.43
// The generator builds each from its indices (variants (0 0 1)[1 0 0], (0 1 1)[1 0 0],
// (0 1 1)[2 -1 1], (1 1 2)[-1 -1 1], (2 1 3)[-3 -6 4]), so the angles are exact; a test checks
// that they reproduce the table.
enum class TextureComponent { cube, goss, brass, copper, s };

std::string_view to_string(TextureComponent component);
// Throws std::invalid_argument listing the valid names (cube, goss, brass, copper, s).
TextureComponent parse_texture_component(std::string_view name);
// The ideal orientation of a component.
Orientation ideal_orientation(TextureComponent component);

// The orientation with the crystal plane normal `hkl` along ND (sample z) and the crystal
// direction `uvw` along RD (sample x). Throws std::invalid_argument unless uvw is perpendicular
// to hkl (cubic crystal: indices are Cartesian lattice-frame vectors).
Orientation orientation_from_plane_and_direction(const Eigen::Vector3d& hkl,
                                                 const Eigen::Vector3d& uvw);
// The orientation with the crystal direction `along_x` parallel to sample x (the tension axis)
// and `along_y` parallel to sample y (sample z = x cross y). Throws std::invalid_argument unless
// they are non-zero and perpendicular.
Orientation single_crystal_orientation(const Eigen::Vector3d& along_x,
                                       const Eigen::Vector3d& along_y);

// Uniform number in [0, 1) from the top 53 bits of one engine output.
double uniform01(std::mt19937_64& engine);
// Standard normal number (Box-Muller, one engine pair per number).
double standard_normal(std::mt19937_64& engine);
// Uniformly distributed on SO(3) (Shoemake 1992, "Uniform random rotations").
Quaternion random_quaternion(std::mt19937_64& engine);
// Rotation vector with independent N(0, (spread/sqrt3)^2) components (spread in radians): an
// isotropic Gaussian in the tangent space, whose rotation angle has root-mean-square `spread`.
Eigen::Vector3d random_rotation_vector(std::mt19937_64& engine, double spread);

std::vector<Orientation> random_orientations(std::size_t count, std::uint64_t seed);
// `count` orientations scattered about the ideal component: g = g_ideal R^T with
// R = rotation_exp(random_rotation_vector(spread)), i.e. the crystal turned about a random axis
// in the sample frame. spread_deg is the root-mean-square misorientation angle to the ideal
// orientation (degrees, 0 <= spread_deg <= 180; exact in the Gaussian tangent-space sense,
// slightly less in practice once spreads reach tens of degrees, because angles beyond 180 deg
// wrap around). spread 0 repeats the ideal orientation.
std::vector<Orientation> component_orientations(TextureComponent component, std::size_t count,
                                                double spread_deg, std::uint64_t seed);

// What `subslip orientations` asks for: a random set (no component) or a component with spread.
struct OrientationRequest {
  std::size_t count = 1;
  std::uint64_t seed = 1;
  std::optional<TextureComponent> component;  // empty: uniformly random
  double spread_deg = 0.0;                    // components only
};
// Throws std::invalid_argument for count 0 or a spread outside [0, 180].
std::vector<Orientation> generate_orientations(const OrientationRequest& request);
// The same orientations, in the same order, handed to `each` one at a time: a process that keeps
// only a block of a large set never holds the rest (driver/orientation_sharing.hpp).
void for_each_generated_orientation(const OrientationRequest& request,
                                    const std::function<void(const Orientation&)>& each);
// One line for the file header, e.g. "random count=100 seed=100" or
// "component=goss spread_deg=5 count=50 seed=1".
std::string describe(const OrientationRequest& request);

}  // namespace subslip::crystal
