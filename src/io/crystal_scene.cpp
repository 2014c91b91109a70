#include "subslip/io/crystal_scene.hpp"

#include "subslip/io/law_block.hpp"
#include "subslip/io/output_points.hpp"
#include "subslip/io/scene_compose.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <numbers>
#include <optional>
#include <span>
#include <stdexcept>
#include <utility>

#include "subslip/crystal/elasticity.hpp"
#include "subslip/crystal/slip_systems.hpp"
#include "subslip/crystal/texture.hpp"
#include "subslip/io/orientation_file.hpp"

namespace subslip::io {

namespace {

using crystal::LatticeKind;
using crystal::SlipFamily;
using law::OverstressForm;

// |s . m| / (|s| |m|) above this: a custom slip direction that does not lie in its plane.
constexpr double kMaxSlipPlaneCosine = 1e-6;
// Generated orientation sets larger than this would not fit in memory once the grain states
// are allocated (about 2 kB a grain); larger sets are surely a typo.
constexpr int kMaxGeneratedGrains = 10'000'000;
// c/a of real hexagonal metals lies in 1.57 (Be) .. 1.89 (Cd); far outside, the Miller-Bravais
// conversions overflow or degenerate.
constexpr double kMinCOverA = 0.1, kMaxCOverA = 10.0;

// ---------------------------------------------------------------- slip systems

std::vector<std::string_view> family_names() {
  std::vector<std::string_view> names;
  for (SlipFamily f : crystal::all_slip_families()) names.push_back(crystal::to_string(f));
  return names;
}

std::string_view lattice_name(LatticeKind k) {
  switch (k) {
    case LatticeKind::fcc:
      return "fcc";
    case LatticeKind::bcc:
      return "bcc";
    case LatticeKind::hcp:
      return "hcp";
  }
  return "?";
}

std::vector<SlipFamily> parse_families(const CheckedNode& node) {
  if (node.size() == 0) node.fail("needs at least one slip family");
  const auto names = family_names();
  std::vector<SlipFamily> families;
  for (const CheckedNode& element : node.elements()) {
    const SlipFamily f = crystal::parse_slip_family(element.as_choice(names));
    if (std::find(families.begin(), families.end(), f) != families.end())
      element.fail("slip family '" + std::string(crystal::to_string(f)) + "' listed twice");
    if (!families.empty() && crystal::lattice_of(f) != crystal::lattice_of(families.front())) {
      element.fail("'" + std::string(crystal::to_string(f)) + "' is a " +
                   std::string(lattice_name(crystal::lattice_of(f))) + " family but '" +
                   std::string(crystal::to_string(families.front())) + "' is " +
                   std::string(lattice_name(crystal::lattice_of(families.front()))) +
                   "; a phase has one lattice");
    }
    families.push_back(f);
  }
  return families;
}

// A direction, returned normalised; stableNorm so that [1e-200, 0, 0] and [1e200, 1e200, 0]
// neither underflow to zero nor overflow.
crystal::Vec3 read_vec3(const CheckedNode& node) {
  const auto v = node.as_doubles(Range::any(), 3);
  const crystal::Vec3 out(v[0], v[1], v[2]);
  if (!(out.stableNorm() > 0.0)) node.fail("must be non-zero");
  return out.stableNormalized();
}

std::vector<crystal::CustomSlipSystem> parse_custom_systems(const CheckedNode& node) {
  const std::size_t n = node.size();
  if (n == 0 || n > static_cast<std::size_t>(crystal::kMaxSlipSystems)) {
    node.fail("needs 1 to " + std::to_string(crystal::kMaxSlipSystems) + " slip systems, got " +
              std::to_string(n));
  }
  std::vector<crystal::CustomSlipSystem> systems;
  for (const CheckedNode& element : node.elements()) {
    element.allow_keys({"s", "m"});
    const crystal::Vec3 s = read_vec3(element.required("s"));
    const crystal::Vec3 m = read_vec3(element.required("m"));
    const double cosine = std::abs(s.dot(m));  // both are unit vectors
    if (cosine > kMaxSlipPlaneCosine) {
      element.fail(
          "the slip direction s must lie in the slip plane (s . m = 0); the angle "
          "between s and m is " +
          std::to_string(std::acos(std::min(cosine, 1.0)) * 180.0 / std::numbers::pi) + " deg");
    }
    systems.push_back({s, m});
  }
  return systems;
}

// ---------------------------------------------------------------- elasticity

// Reads the constants of `type`; the constructors check positive definiteness.
crystal::Mat6 stiffness_of(const CheckedNode& node, const std::string& type, SceneValues& v) {
  auto constant = [&](std::string_view key) {
    return v.get_noted(node, key, dimension::stress, Magnitude::elastic_constant);
  };
  if (type == "cubic") {
    node.allow_keys({"type", "C11", "C12", "C44"});
    const double c11 = constant("C11"), c12 = constant("C12"), c44 = constant("C44");
    return crystal::cubic_stiffness(c11, c12, c44);
  }
  if (type == "hexagonal") {
    node.allow_keys({"type", "C11", "C12", "C13", "C33", "C44"});
    const double c11 = constant("C11"), c12 = constant("C12"), c13 = constant("C13");
    const double c33 = constant("C33"), c44 = constant("C44");
    return crystal::hexagonal_stiffness(c11, c12, c13, c33, c44);
  }
  node.allow_keys({"type", "E", "G", "nu"});
  const double nu = node.get_double("nu");
  if (*node.one_of({"E", "G"}, true) == "E") return crystal::isotropic_from_E_nu(constant("E"), nu);
  return crystal::isotropic_from_G_nu(constant("G"), nu);
}

// A cubic stiffness on a hexagonal crystal (or the reverse) is a mistake; custom systems and
// isotropic elasticity go with anything.
void check_elastic_symmetry(const CheckedNode& type_node, const std::string& type,
                            const std::vector<SlipFamily>& families) {
  if (families.empty() || type == "isotropic") return;
  const bool hexagonal = crystal::lattice_of(families.front()) == LatticeKind::hcp;
  if ((type == "hexagonal") != hexagonal) {
    type_node.fail("'" + type + "' elasticity does not fit the " +
                   std::string(lattice_name(crystal::lattice_of(families.front()))) +
                   " slip families; use " + (hexagonal ? "hexagonal" : "cubic") + " or isotropic");
  }
}

crystal::Mat6 parse_elasticity(const CheckedNode& node, const std::vector<SlipFamily>& families,
                               std::string& type, SceneValues& v) {
  node.expect_map();
  const CheckedNode type_node = node.required("type");
  type = type_node.as_choice({"cubic", "hexagonal", "isotropic"});
  check_elastic_symmetry(type_node, type, families);
  try {
    return stiffness_of(node, type, v);
  } catch (const std::invalid_argument& e) {
    node.fail(e.what());
  }
}

// ---------------------------------------------------------------- phase

crystal::LatentHardening parse_latent(const CheckedNode& node) {
  node.allow_keys({"ratio", "coplanar", "non_coplanar"});
  crystal::LatentHardening latent;
  if (node.has("ratio")) {
    for (const char* other : {"coplanar", "non_coplanar"}) {
      if (auto v = node.optional(other))
        v->fail("give either 'ratio' or 'coplanar' and 'non_coplanar', not both");
    }
    latent.kind = crystal::LatentHardening::Kind::ratio;
    latent.ratio = node.get_double("ratio", Range::non_negative());
    return latent;
  }
  if (!node.has("coplanar") && !node.has("non_coplanar"))
    throw node.missing("ratio", "needs 'ratio', or 'coplanar' and 'non_coplanar'");
  latent.kind = crystal::LatentHardening::Kind::coplanar;
  latent.coplanar = node.get_double("coplanar", Range::non_negative());
  latent.non_coplanar = node.get_double("non_coplanar", Range::non_negative());
  return latent;
}

void parse_c_over_a(const CheckedNode& phase, crystal::PhaseDescription& d) {
  const bool hexagonal =
      !d.families.empty() && crystal::lattice_of(d.families.front()) == LatticeKind::hcp;
  if (hexagonal) {
    d.c_over_a = phase.get_double("c_over_a", Range::in_closed_interval(kMinCOverA, kMaxCOverA));
  } else if (auto c = phase.optional("c_over_a")) {
    c->fail("c_over_a is used by hcp slip families only; remove it");
  }
}

// The settings of one family: the phase settings with the family's overrides.
crystal::SlipGroupSettings family_settings(const std::optional<CheckedNode>& node,
                                           const crystal::SlipGroupSettings& phase,
                                           bool phase_initial_mu, SceneValues& v) {
  crystal::SlipGroupSettings s = phase;
  bool own_initial_mu = phase_initial_mu;
  if (node) {
    node->allow_keys({"tau0", "initial_mu", "law"});
    if (auto tau0 = node->optional("tau0"))
      s.tau0 = v.read_noted(*tau0, dimension::stress, Magnitude::tau0, Range::positive());
    if (auto l = node->optional("law"))
      s.law = parse_law_block(*l, crystal_law_units(v.units()), phase.law, true);
    if (auto mu = node->optional("initial_mu")) {
      s.initial_mu = mu->as_double(Range::positive());
      own_initial_mu = true;
    }
  }
  // Resolved here (not left 0 for the builder) so that the result file records the value.
  if (!own_initial_mu) s.initial_mu = s.law.friction.mu_s;
  return s;
}

void parse_per_family(const CheckedNode& phase, const crystal::SlipGroupSettings& settings,
                      bool phase_initial_mu, crystal::PhaseDescription& d, SceneValues& v) {
  const auto per_family = phase.optional("per_family");
  if (per_family && !d.custom_systems.empty())
    per_family->fail("per_family needs slip families; custom slip systems share the phase law");
  std::vector<std::string_view> listed;
  for (SlipFamily f : d.families) listed.push_back(crystal::to_string(f));
  if (per_family) per_family->allow_keys(listed);
  for (SlipFamily f : d.families) {
    const auto node = per_family ? per_family->optional(crystal::to_string(f)) : std::nullopt;
    d.family_settings.push_back(family_settings(node, settings, phase_initial_mu, v));
  }
  if (!d.custom_systems.empty())
    d.custom_settings = family_settings({}, settings, phase_initial_mu, v);
}

}  // namespace

// Every independent part is read, each error reported; a part that needs a failed one (the
// elasticity and c/a need the families, per_family the law) is skipped.
crystal::PhaseDescription parse_crystal_phase(const CheckedNode& node, SceneValues& v,
                                              std::string& elasticity_type) {
  node.allow_keys({"families", "slip_systems", "c_over_a", "elasticity", "tau0", "law",
                   "initial_mu", "per_family", "latent", "pressure_sensitive", "kinematics"});
  crystal::PhaseDescription d;
  InputErrorList errors;
  const bool systems = errors.attempt([&] {
    if (*node.one_of({"families", "slip_systems"}, true) == "families") {
      d.families = parse_families(node.required("families"));
    } else {
      d.custom_systems = parse_custom_systems(node.required("slip_systems"));
    }
  });
  if (systems) {
    errors.attempt([&] { parse_c_over_a(node, d); });
    errors.attempt([&] {
      d.stiffness = parse_elasticity(node.required("elasticity"), d.families, elasticity_type, v);
    });
  }
  crystal::SlipGroupSettings settings;
  bool group = errors.attempt([&] {
    settings.tau0 =
        v.get_noted(node, "tau0", dimension::stress, Magnitude::tau0, Range::positive());
  });
  group = errors.attempt([&] {
    settings.law = parse_law_block(node.required("law"), crystal_law_units(v.units()), {}, false);
  }) && group;
  const auto initial_mu = node.optional("initial_mu");
  group = errors.attempt([&] {
    if (initial_mu) settings.initial_mu = initial_mu->as_double(Range::positive());
  }) && group;
  if (systems && group)
    errors.attempt([&] { parse_per_family(node, settings, initial_mu.has_value(), d, v); });
  errors.attempt([&] {
    if (auto latent = node.optional("latent")) d.latent = parse_latent(*latent);
  });
  errors.attempt([&] {
    if (auto p = node.optional("pressure_sensitive")) d.pressure_sensitive = p->as_bool();
  });
  errors.attempt([&] {
    if (auto k = node.optional("kinematics")) {
      d.kinematics = k->as_enum<crystal::Kinematics>(
          {{"finite_rotation", crystal::Kinematics::finite_rotation},
           {"small_strain", crystal::Kinematics::small_strain}});
    }
  });
  errors.throw_if_any();
  return d;
}

namespace {

void parse_phase(const CheckedNode& node, CrystalCase& c, SceneValues& v) {
  c.phase = parse_crystal_phase(node, v, c.elasticity_type);
}

// ---------------------------------------------------------------- orientations

// `file` relative to `directory` (that of the scene file, or of the base scene, naming it).
std::filesystem::path resolve_relative(const std::string& file,
                                       const std::filesystem::path& directory) {
  const std::filesystem::path p(file);
  if (p.is_absolute()) return p;
  return directory / p;
}

// Where a scene names an orientation file: errors about the file as a whole are reported here.
struct SceneKey {
  std::string file;
  int line = 0;
  std::string path;
  [[noreturn]] void fail(const std::string& message) const {
    throw InputError(file, line, path, message);
  }
};

// The orientation file `node` names, to be read when asked. Errors inside the file keep its
// file and line and say which scene key named it; a missing or empty file has no line of its
// own and is reported at the scene key.
model::OrientationFile orientation_file(const CheckedNode& node,
                                        const OrientationFileLayout& layout,
                                        OrientationSource& source) {
  const std::string path = resolve_relative(node.as_string(), node.directory()).string();
  source = {"file", path};
  const SceneKey key{node.file(), node.line(), node.path()};
  const auto given_at = [key](const std::string& message) {
    return message + " (orientation file given at " + key.file + ":" + std::to_string(key.line) +
           ": " + key.path + ")";
  };
  // What `read` throws: the file's error with the scene key that named it.
  const auto situated = [key, given_at](const auto& read) {
    try {
      return read();
    } catch (const InputError& e) {
      if (e.line == 0) key.fail(e.what());
      throw InputError(e.file, e.line, e.key, given_at(e.message));
    }
  };
  model::OrientationFile file;
  file.path = path;
  file.read = [path, layout, situated](const model::OrientationVisitor& each,
                                       double& largest_euler_deg) {
    return situated([&] { return read_orientation_file(path, each, &largest_euler_deg, layout); });
  };
  file.read_start = [path, layout, situated](const model::OrientationVisitor& first) {
    return situated([&] { return read_orientation_file_start(path, first, layout); });
  };
  file.read_lines = [path, layout, given_at](const std::string& start, std::uint64_t begin,
                                             std::uint64_t end,
                                             const model::OrientationVisitor& each) {
    model::OrientationLines out;
    try {
      const OrientationLines read =
          read_orientation_file_lines(path, start, begin, end, each, layout);
      out.orientations = read.orientations;
      out.lines = read.lines;
      out.complete = read.complete;
      out.largest_euler_deg = read.largest_euler_deg;
    } catch (const InputError& e) {  // (a line's: its number counted from the range's first)
      out.problem_line = e.line;
      out.problem_key = e.key;
      out.problem_message = given_at(e.message);
    }
    return out;
  };
  file.fail_line = [path](int line, const std::string& key, const std::string& message) {
    throw InputError(path, line, key, message);
  };
  file.fail_weights = [key] { key.fail("the orientation weights sum to more than 1.8e308"); };
  file.fail_changed = [key, path] {
    key.fail("the orientation file " + path + " changed while it was read; run again");
  };
  return file;
}

}  // namespace

EulerDegrees parse_euler_degrees(const CheckedNode& node, bool weighted) {
  const auto v = node.as_doubles();
  if (weighted ? (v.size() != 3 && v.size() != 4) : v.size() != 3)
    node.fail(weighted ? "expected [phi1, Phi, phi2] or [phi1, Phi, phi2, weight] in degrees"
                       : "expected [phi1, Phi, phi2] in degrees");
  // The ranges of orientation files (docs/orientations.md).
  if (!(v[1] >= 0.0 && v[1] <= 180.0)) node.fail("Phi must be in [0, 180] degrees");
  if (std::abs(v[0]) > 360.0 || std::abs(v[2]) > 360.0)
    node.fail("phi1 and phi2 must be in [-360, 360] degrees");
  if (v.size() == 4 && !(v[3] > 0.0)) node.fail("the weight must be > 0");
  EulerDegrees out;
  out.degrees = crystal::Vec3(v[0], v[1], v[2]);
  out.orientation = crystal::Orientation::from_euler(crystal::degrees_to_radians(out.degrees),
                                                     v.size() == 4 ? v[3] : 1.0);
  return out;
}

namespace {

std::vector<crystal::Orientation> inline_euler(const CheckedNode& node, OrientationSource& source) {
  if (node.size() == 0) node.fail("needs at least one orientation");
  std::vector<crystal::Orientation> out;
  double largest = 0.0;
  for (const CheckedNode& element : node.elements()) {
    const EulerDegrees e = parse_euler_degrees(element, true);
    largest =
        std::max({largest, std::abs(e.degrees[0]), std::abs(e.degrees[1]), std::abs(e.degrees[2])});
    out.push_back(e.orientation);
  }
  source = {"euler_deg", std::to_string(out.size()) + " inline Bunge Euler angle sets", largest};
  return out;
}

std::uint64_t read_seed(const CheckedNode& node) {
  return static_cast<std::uint64_t>(node.get_int("seed", 1, Range::non_negative()));
}

crystal::OrientationRequest generated(const CheckedNode& node, bool component,
                                      OrientationSource& source) {
  crystal::OrientationRequest request;
  if (component) {
    node.allow_keys({"name", "count", "spread_deg", "seed"});
    request.component = crystal::parse_texture_component(
        node.required("name").as_choice({"cube", "goss", "brass", "copper", "s"}));
    request.spread_deg = node.get_double("spread_deg", 0.0, Range::in_closed_interval(0, 180));
  } else {
    node.allow_keys({"count", "seed"});
  }
  request.count = static_cast<std::size_t>(
      node.get_int("count", Range::in_closed_interval(1, kMaxGeneratedGrains)));
  request.seed = read_seed(node);
  source = {component ? "component" : "random", crystal::describe(request)};
  return request;
}

// How the file named by orientations.file is laid out: subslip's own header, or the format and
// units of a file another tool wrote (docs/orientations.md).
OrientationFileLayout file_layout(const CheckedNode& node) {
  OrientationFileLayout layout;
  layout.kind = node.optional("format") ? node.required("format").as_enum<OrientationFileKind>(
                                              {{"subslip", OrientationFileKind::subslip},
                                               {"euler", OrientationFileKind::euler},
                                               {"mtex", OrientationFileKind::mtex},
                                               {"damask", OrientationFileKind::damask}})
                                        : OrientationFileKind::subslip;
  if (auto angles = node.optional("angles")) {
    if (layout.kind == OrientationFileKind::subslip) {
      angles->fail(
          "applies to format euler, mtex or damask; a subslip file states its units in "
          "its header");
    }
    layout.angles =
        angles->as_enum<AngleUnit>({{"deg", AngleUnit::degrees}, {"rad", AngleUnit::radians}});
  } else if (layout.kind == OrientationFileKind::euler) {
    node.fail("format euler needs the unit of its angles: angles: deg or angles: rad");
  }
  if (auto column = node.optional("column")) {
    if (layout.kind != OrientationFileKind::damask) {
      column->fail("applies to format damask only (the label of its orientation column)");
    }
    layout.column = column->as_string();
  }
  return layout;
}

// Where the orientations come from; inline Euler angles are read here (the scene holds them),
// a file and a generated texture when the run model is read (model::read_all_orientations,
// driver::read_orientations).
model::OrientationOrigin parse_orientations(const CheckedNode& node, OrientationSource& source) {
  node.allow_keys({"file", "format", "angles", "column", "euler_deg", "random", "component"});
  const std::string kind = *node.one_of({"file", "euler_deg", "random", "component"}, true);
  const CheckedNode value = node.required(kind);
  if (kind != "file") {
    for (std::string_view file_key : {"format", "angles", "column"}) {
      if (auto extra = node.optional(file_key)) {
        extra->fail("applies to orientations.file only");
      }
    }
  }
  model::OrientationOrigin origin;
  if (kind == "file") {
    origin.file = orientation_file(value, file_layout(node), source);
  } else if (kind == "euler_deg") {
    origin.given = inline_euler(value, source);
    // Weights are normalised by their sum, which must not overflow.
    double total = 0.0;
    for (const auto& g : origin.given) total += g.weight;
    if (!std::isfinite(total)) value.fail("the orientation weights sum to more than 1.8e308");
  } else {
    origin.generated = generated(value, kind == "component", source);
  }
  return origin;
}

// ---------------------------------------------------------------- loading

// A 3x3 matrix of numbers and `x` (free), rows i and columns j as written.
struct MatrixInput {
  crystal::Mat3 value = crystal::Mat3::Zero();
  crystal::Mask3 free = crystal::Mask3::Constant(false);
  std::vector<CheckedNode> entries;  // row-major, for error locations
};

bool is_free_marker(const CheckedNode& entry) {
  return entry.is_scalar() && entry.yaml().Scalar() == "x";
}

// Entries in `d` (1/time for L, stress for stress targets); non-zero entries of a matrix of
// kind `noted` are recorded for the plausibility warnings.
MatrixInput read_matrix(const CheckedNode& node, Dimension d, SceneValues& v,
                        std::optional<Magnitude> noted) {
  const char* shape = "expected 3 rows of 3 entries, [[a, b, c], [d, e, f], [g, h, i]]";
  if (!node.is_sequence() || node.size() != 3) node.fail(shape);
  MatrixInput m;
  for (int i = 0; i < 3; ++i) {
    const CheckedNode row = node.element(static_cast<std::size_t>(i));
    if (!row.is_sequence() || row.size() != 3) row.fail(shape);
    for (int j = 0; j < 3; ++j) {
      const CheckedNode entry = row.element(static_cast<std::size_t>(j));
      m.entries.push_back(entry);
      if (is_free_marker(entry)) {
        m.free(i, j) = true;
      } else {
        m.value(i, j) = v.read(entry, d);
        if (noted && m.value(i, j) != 0.0) v.note(entry, *noted, std::abs(m.value(i, j)));
      }
    }
  }
  return m;
}

std::string component_name(int i, int j) {
  return std::to_string(i + 1) + std::to_string(j + 1);
}

// The keys a segment gives its rate and its stress targets by: L or dot_F, stress (Cauchy) or
// P (first Piola-Kirchhoff).
struct ControlKeys {
  std::string rate = "L";
  std::string stress = "stress";
  bool cauchy() const { return stress == "stress"; }
};

// Every component is prescribed either through the rate or through the stress, never both; a
// free pair L_ij, L_ji under a Cauchy target has one unknown (D_ij), so its two stress targets
// must agree (under P each free component is its own unknown and its own target).
void check_mixed_control(const MatrixInput& l, const std::optional<MatrixInput>& stress,
                         const ControlKeys& keys) {
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      const std::string ij = component_name(i, j);
      const std::string rate_ij = keys.rate + "_" + ij, stress_ij = keys.stress + "_" + ij;
      const std::size_t k = static_cast<std::size_t>(3 * i + j);
      if (!stress) {
        if (l.free(i, j))
          l.entries[k].fail(rate_ij +
                            " is free (x) but the segment has no 'stress' or 'P' to "
                            "prescribe stress_" +
                            ij);
        continue;
      }
      if (l.free(i, j) == stress->free(i, j)) {
        stress->entries[k].fail("component " + ij + ": " +
                                (l.free(i, j) ? rate_ij + " and " + stress_ij + " are both x"
                                              : rate_ij + " and " + stress_ij + " are both given") +
                                "; exactly one of them must be x");
      }
    }
  }
  if (!stress || !keys.cauchy()) return;
  for (int i = 0; i < 3; ++i) {
    for (int j = i + 1; j < 3; ++j) {
      if (l.free(i, j) && l.free(j, i) && stress->value(i, j) != stress->value(j, i)) {
        stress->entries[static_cast<std::size_t>(3 * j + i)].fail(
            "L_" + component_name(i, j) + " and L_" + component_name(j, i) +
            " are both free, so stress_" + component_name(j, i) + " must equal stress_" +
            component_name(i, j) + " (the Cauchy stress is symmetric)");
      }
    }
  }
}

// The largest |L_ij| (or |dot_F_ij|) among the prescribed components (0 when none is non-zero).
double driving_rate(const crystal::LoadSegment& seg) {
  const crystal::Mat3& prescribed = crystal::prescribed_rate(seg);
  double rate = 0.0;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (!seg.free(i, j)) rate = std::max(rate, std::abs(prescribed(i, j)));
  return rate;
}

// `duration`, or `strain`: the integral of the largest prescribed |L_ij| (|dot_F_ij|: the
// change of F_ij) over the segment, so that a swept rate keeps the amount of deformation
// (duration = strain / rate).
void parse_duration(const CheckedNode& node, crystal::LoadSegment& seg, SceneValues& v) {
  if (*node.one_of({"duration", "strain"}, true) == "duration") {
    seg.duration =
        v.get_noted(node, "duration", dimension::time, Magnitude::duration, Range::positive());
    return;
  }
  const CheckedNode strain = node.required("strain");
  const double amount = strain.as_double(Range::positive());
  const double rate = driving_rate(seg);
  if (!(rate > 0.0))
    strain.fail("needs a non-zero prescribed component of L or dot_F to reach it; give a duration");
  seg.duration = amount / rate;
  if (!(std::isfinite(seg.duration) && seg.duration > 0.0))
    strain.fail("strain / rate is not a usable duration (over- or underflow)");
}

// The duration (a strain needs the segment's L), increments, growth and output_every, each
// error reported; the increment lengths are checked once the first three are read.
void parse_stepping(const CheckedNode& node, crystal::LoadSegment& seg, SceneValues& v,
                    bool rate_known) {
  InputErrorList errors;
  const bool duration_known = rate_known && errors.attempt([&] { parse_duration(node, seg, v); });
  parse_increments(node, seg, duration_known, errors);
  errors.throw_if_any();
}

// Which keys the segment gives its rate and stress by; dot_F with a Cauchy `stress` is refused
// at the `stress` key.
ControlKeys control_keys(const CheckedNode& node) {
  ControlKeys keys;
  keys.rate = *node.one_of({"L", "dot_F"}, true);
  if (auto stress = node.one_of({"stress", "P"}, false)) keys.stress = *stress;
  if (keys.rate == "dot_F" && keys.cauchy() && node.has("stress")) {
    node.required("stress").fail(
        "dot_F takes its stress targets as P (first Piola-Kirchhoff), as DAMASK's load cases "
        "do: a Cauchy target is symmetric, one condition for a free pair dot_F_ij, dot_F_ji, "
        "and no rule splits it between them (L's pair is D_ij, without spin); give P, or the "
        "rate as L");
  }
  return keys;
}

crystal::LoadSegment parse_segment(const CheckedNode& node, SceneValues& v) {
  node.allow_keys(
      {"L", "dot_F", "stress", "P", "duration", "strain", "increments", "growth", "output_every"});
  InputErrorList errors;
  ControlKeys keys;
  const bool have_keys = errors.attempt([&] { keys = control_keys(node); });
  MatrixInput l;
  const bool have_l = have_keys && errors.attempt([&] {
    l = read_matrix(node.required(keys.rate), dimension::per_time, v, Magnitude::strain_rate);
  });
  std::optional<MatrixInput> stress;
  const bool have_stress = have_keys && errors.attempt([&] {
    if (auto s = node.optional(keys.stress)) stress = read_matrix(*s, dimension::stress, v, {});
  });
  const bool controlled =
      have_l && have_stress && errors.attempt([&] { check_mixed_control(l, stress, keys); });
  crystal::LoadSegment seg;
  if (keys.rate == "dot_F") {
    seg.rate_control = crystal::RateControl::deformation_rate;
    seg.deformation_rate = l.value;
  } else {
    seg.velocity_gradient = l.value;
  }
  seg.free = l.free;
  if (!keys.cauchy()) seg.stress_measure = crystal::StressMeasure::first_piola;
  if (stress) seg.stress_target = stress->value;
  errors.attempt([&] { parse_stepping(node, seg, v, controlled); });
  errors.throw_if_any();
  return seg;
}

// Every segment is read, each error reported.
std::vector<crystal::LoadSegment> parse_loading(const CheckedNode& node, SceneValues& v) {
  if (node.size() == 0) node.fail("needs at least one segment");
  std::vector<crystal::LoadSegment> segments;
  InputErrorList errors;
  for (const CheckedNode& element : node.elements())
    errors.attempt([&] { segments.push_back(parse_segment(element, v)); });
  errors.throw_if_any();
  return segments;
}

// ---------------------------------------------------------------- integrator and output

bool uses_rate_independent(const crystal::PhaseDescription& d) {
  auto ri = [](const crystal::SlipGroupSettings& s) {
    return s.law.overstress.form == OverstressForm::rate_independent;
  };
  if (!d.custom_systems.empty()) return ri(d.custom_settings);
  return std::any_of(d.family_settings.begin(), d.family_settings.end(), ri);
}

crystal::AggregateOptions parse_integrator(const std::optional<CheckedNode>& node,
                                           const crystal::PhaseDescription& phase) {
  crystal::AggregateOptions opt;
  if (!node) return opt;
  node->allow_keys({"method", "tolerance", "residual_tolerance", "max_iterations", "max_cutbacks",
                    "stress_tolerance", "max_mixed_iterations", "order", "predictor"});
  if (auto m = node->optional("method")) {
    opt.method = m->as_enum<crystal::CrystalMethod>(
        {{"implicit", crystal::CrystalMethod::implicit},
         {"forward_euler", crystal::CrystalMethod::forward_euler}});
    if (opt.method == crystal::CrystalMethod::forward_euler && uses_rate_independent(phase))
      m->fail("forward_euler cannot integrate the rate_independent form; use implicit");
  }
  if (auto tol = node->optional("tolerance")) {
    if (opt.method != crystal::CrystalMethod::implicit)
      tol->fail("adaptive stepping needs method: implicit");
    opt.tolerance = node->get_double("tolerance", 0.0, Range::in_open_interval(0.0, 1.0));
  }
  opt.order = parse_adaptive_order(*node, opt.tolerance);
  opt.grain.tolerance =
      node->get_double("residual_tolerance", opt.grain.tolerance, Range::positive());
  // A residual tolerance the scene names is used as given, not tied to the tolerance.
  opt.grain_tolerance_follows_tolerance = !node->has("residual_tolerance");
  opt.grain.max_iterations =
      node->get_int("max_iterations", opt.grain.max_iterations, Range::in_closed_interval(1, 1000));
  opt.max_cutbacks =
      node->get_int("max_cutbacks", opt.max_cutbacks, Range::in_closed_interval(0, 200));
  opt.stress_tolerance =
      node->get_double("stress_tolerance", opt.stress_tolerance, Range::positive());
  opt.stress_tolerance_follows_tolerance = !node->has("stress_tolerance");
  opt.max_mixed_iterations = node->get_int("max_mixed_iterations", opt.max_mixed_iterations,
                                           Range::in_closed_interval(1, 1000));
  if (auto p = node->optional("predictor")) {
    opt.predictor = p->as_enum<crystal::MixedPredictor>(
        {{"last", crystal::MixedPredictor::last}, {"trend", crystal::MixedPredictor::trend}});
  }
  return opt;
}

// The fields of `all` named in `node`, in the order of `all`; each may appear once.
template <class Field, std::size_t K>
std::vector<Field> parse_field_list(const CheckedNode& node, const std::array<Field, K>& all) {
  std::vector<std::string_view> names;
  for (Field f : all) names.push_back(to_string(f));
  std::vector<bool> wanted(K, false);
  for (const CheckedNode& element : node.elements()) {
    const std::string name = element.as_choice(names);
    const auto k =
        static_cast<std::size_t>(std::find(names.begin(), names.end(), name) - names.begin());
    if (wanted[k]) element.fail("field '" + name + "' listed twice");
    wanted[k] = true;
  }
  std::vector<Field> out;
  for (std::size_t k = 0; k < K; ++k) {
    if (wanted[k]) out.push_back(all[k]);
  }
  return out;
}

CrystalOutputSelection parse_crystal_output(const std::optional<CheckedNode>& node) {
  CrystalOutputSelection out;
  out.macro.assign(kAllMacroFields.begin(), kAllMacroFields.end());
  if (!node) return out;
  node->allow_keys({"macro", "grains", "checkpoint_every", "at", "grains_at", kCompressionKeys[0],
                    kCompressionKeys[1]});
  out.checkpoint_every = node->get_int("checkpoint_every", -1, Range::at_least(0));
  if (auto macro = node->optional("macro")) {
    if (macro->size() == 0) macro->fail("needs at least 'time'");
    out.macro = parse_field_list(*macro, kAllMacroFields);
    if (out.macro.front() != MacroField::time) macro->fail("must include 'time'");
  }
  if (auto grains = node->optional("grains")) {
    grains->expect_sequence();
    out.grains = parse_field_list(*grains, kAllGrainFields);
  }
  return out;
}

// `output.at`, `output.grains_at`: output at chosen times or loading strains instead of at
// increments, per-grain fields at those of grains_at only; the segments' steps end on all of
// them (crystal::LoadSegment::output_times).
void parse_output_at(const CheckedNode& root, CrystalCase& c, const Units& units) {
  const auto output = root.optional("output");
  const auto at = output ? output->optional("at") : std::nullopt;
  const auto grains_at = output ? output->optional("grains_at") : std::nullopt;
  if (!at) {
    if (grains_at) grains_at->fail("needs output.at (per-grain rows are at some of its points)");
    return;
  }
  auto clock_of = [&](const std::string& clock) {
    std::vector<ClockSegment> segments;
    for (const auto& s : c.segments)
      segments.push_back({clock == "time" ? 1.0 : driving_rate(s), s.duration});
    return segments;
  };
  auto unit_of = [&](const std::string& clock) {
    return units.unit(clock == "time" ? dimension::time : dimension::none);
  };
  const OutputPoints macro = parse_output_points(*at, {"time", "strain"}, clock_of, unit_of);
  const auto macro_times = segment_times(macro.values, clock_of(macro.clock));
  std::vector<std::vector<double>> grain_times(c.segments.size());
  if (grains_at) {
    if (c.output.grains.empty()) grains_at->fail("needs per-grain fields (output.grains)");
    const OutputPoints g = parse_output_points(*grains_at, {"time", "strain"}, clock_of, unit_of);
    grain_times = segment_times(g.values, clock_of(g.clock));
  }
  std::vector<ClockSegment> durations;
  for (const auto& s : c.segments) durations.push_back({1.0, s.duration});
  const MergedTimes merged = merge_segment_times(macro_times, grain_times, durations);
  const CheckedNode loading = root.required("loading");
  if (grains_at) c.output.grain_rows.push_back(true);  // the initial state
  for (std::size_t k = 0; k < c.segments.size(); ++k) {
    if (auto every = loading.element(k).optional("output_every"))
      every->fail("output.at chooses the output points; drop output_every");
    c.segments[k].output_at_times = true;
    c.segments[k].output_times = merged.times[k];
    if (grains_at) {
      for (const bool g : merged.in_b[k]) c.output.grain_rows.push_back(g);
    }
  }
}

// ---------------------------------------------------------------- the scene

void check_crystal_top_level(const CheckedNode& root) {
  root.allow_keys({"scene", "title", "units", "phase", "orientations", "loading", "integrator",
                   "output", "sweep"});
}

// Every block is read and each error reported; a block that needs a failed one (the
// integrator's checks need the phase, output.at the loading) is skipped.
CrystalCase parse_crystal_case(SweepCase swept, const Units& units) {
  const CheckedNode root = swept.document.root();
  CrystalCase c;
  c.name = std::move(swept.name);
  c.overrides = std::move(swept.overrides);
  SceneValues values(units);
  InputErrorList errors;
  const bool phase = errors.attempt([&] { parse_phase(root.required("phase"), c, values); });
  errors.attempt([&] {
    c.orientation_origin = parse_orientations(root.required("orientations"), c.orientation_source);
  });
  const bool loading =
      errors.attempt([&] { c.segments = parse_loading(root.required("loading"), values); });
  if (phase)
    errors.attempt([&] { c.options = parse_integrator(root.optional("integrator"), c.phase); });
  const bool output =
      errors.attempt([&] { c.output = parse_crystal_output(root.optional("output")); });
  if (loading && output) errors.attempt([&] { parse_output_at(root, c, units); });
  errors.throw_if_any();
  c.magnitudes = values.take_magnitudes();
  return c;
}

}  // namespace

CrystalScene load_crystal_scene(const std::filesystem::path& path) {
  return parse_crystal_scene(compose_scene(YamlDocument::from_file(path)));
}

CrystalScene parse_crystal_scene(const YamlDocument& document) {
  CrystalScene scene = describe_crystal_scene(document);
  model::read_all_orientations(scene);
  return scene;
}

CrystalScene describe_crystal_scene(const YamlDocument& document) {
  const CheckedNode root = document.root();
  CrystalScene scene;
  scene.file = document.file();
  scene.text = document.text();
  scene.makeup = makeup_of(document);
  InputErrorList errors;
  root.get_choice("scene", {"crystal"});  // a scene of another kind is read no further
  errors.attempt([&] { check_crystal_top_level(root); });
  errors.attempt([&] { scene.title = root.get_string("title", ""); });
  const bool units =
      errors.attempt([&] { scene.units = parse_units_without_length(root.required("units")); });
  errors.attempt([&] { scene.compression = parse_compression(root.optional("output")); });
  if (units) {
    const Units& u = scene.units;
    errors.attempt([&] {
      scene.cases = parse_sweep_cases(document, kCrystalSweepable, [&u](SweepCase swept) {
        return parse_crystal_case(std::move(swept), u);
      });
    });
  }
  errors.throw_if_any();
  return scene;
}

}  // namespace subslip::io
