#include "subslip/io/crystal_output.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <optional>
#include <span>
#include <stdexcept>
#include <utility>

#include "subslip/crystal/grain_fields_table.hpp"
#include "subslip/crystal/rotation.hpp"
#include "subslip/driver/checkpoint_policy.hpp"
#include "subslip/io/case_group.hpp"
#include "subslip/io/checkpoint.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/law_block.hpp"
#include "subslip/law/parameter_table.hpp"

namespace subslip::io {

using driver::CrystalSummary;

namespace {

using crystal::Mat3;

// Every second-order tensor of the file, macro or per grain, is stored with two trailing axes
// of 3 ([n, 3, 3], [n, G, 3, 3]; symmetric ones in full), and says so in `components`.
constexpr const char* kTensorComponents = h5::kTensorConvention;
constexpr std::size_t kMacroBlockRows = 256;
// Per-grain rows can be large (grains x slip systems): chunks of about 1 MiB, and about 4 MiB
// gathered in memory between writes.
constexpr std::size_t kGrainChunkBytes = std::size_t{1} << 20;
constexpr std::size_t kGrainBlockBytes = std::size_t{4} << 20;

struct FieldSpec {
  std::vector<std::size_t> shape;  // of a row (macro) or of a grain's value (grains); {}: scalar
  h5::Type type;
  std::string unit;
  std::string description;
  std::string components;  // the meaning of the trailing axes ("" for scalars)
};

// Values per row (macro) or per grain (grains).
std::size_t width_of(const FieldSpec& spec) {
  std::size_t n = 1;
  for (std::size_t d : spec.shape) n *= d;
  return n;
}

const std::vector<std::size_t> kTensorShape = {3, 3};

FieldSpec macro_spec(MacroField f, const Units& u) {
  const std::string one(kDimensionless);
  switch (f) {
    case MacroField::time:
      return {{}, h5::Type::float64, u.time, "time since the start of the loading history", ""};
    case MacroField::L:
      return {kTensorShape, h5::Type::float64, "1/" + u.time,
              "velocity gradient L of the last increment (free components as solved)",
              kTensorComponents};
    case MacroField::F:
      return {kTensorShape, h5::Type::float64, one, "deformation gradient F", kTensorComponents};
    case MacroField::strain:
      return {kTensorShape, h5::Type::float64, one,
              "strain: logarithmic ln V (finite_rotation) or the integral of D (small_strain)",
              kTensorComponents};
    case MacroField::stress:
      return {kTensorShape, h5::Type::float64, u.stress,
              "volume-averaged Cauchy stress (Taylor aggregate, sample frame)", kTensorComponents};
    case MacroField::segment:
      return {
          {}, h5::Type::int32, "index", "loading segment of the state (-1: the initial state)", ""};
  }
  return {{}, h5::Type::float64, one, "", ""};
}

// From the field table (crystal/grain_fields_table.hpp): shape, unit, description, components.
FieldSpec grain_spec(GrainField f, const Units& u, std::size_t slip_count) {
  const crystal::GrainFieldInfo& field = crystal::info(f);
  std::vector<std::size_t> shape;
  std::string components(field.components);
  switch (field.stored) {
    case crystal::GrainFieldShape::tensor:
      shape = kTensorShape;
      components = kTensorComponents;
      break;
    case crystal::GrainFieldShape::quaternion:
      shape = {4};
      break;
    case crystal::GrainFieldShape::per_system:
      shape = {slip_count};
      break;
  }
  std::string unit(kDimensionless);
  if (field.unit == crystal::GrainFieldUnit::stress) unit = u.stress;
  if (field.unit == crystal::GrainFieldUnit::per_time) unit = "1/" + u.time;
  return {shape, h5::Type::float64, unit, std::string(field.description), components};
}

std::array<double, 9> row_major(const Mat3& m) {
  std::array<double, 9> v{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) v[static_cast<std::size_t>(3 * i + j)] = m(i, j);
  return v;
}

// The settings of every slip system, in output order.
std::vector<crystal::SlipGroupSettings> system_settings(const CrystalCase& c) {
  std::vector<crystal::SlipGroupSettings> out;
  for (const auto& sys : crystal::described_systems(c.phase)) {
    out.push_back(c.phase.custom_systems.empty()
                      ? c.phase.family_settings[static_cast<std::size_t>(sys.group)]
                      : c.phase.custom_settings);
  }
  return out;
}

template <class Get>
std::vector<double> per_system(const std::vector<crystal::SlipGroupSettings>& s, Get&& get) {
  std::vector<double> v;
  for (const auto& x : s) v.push_back(get(x));
  return v;
}

template <class Get>
std::vector<std::string> per_system_names(const std::vector<crystal::SlipGroupSettings>& s,
                                          Get&& get) {
  std::vector<std::string> v;
  for (const auto& x : s) v.emplace_back(get(x));
  return v;
}

// Law constants as arrays over slip systems (families may differ): the same names as a contact
// case, in the crystal reading's units (slip is dimensionless).
void write_law_parameters(const h5::Group& g, const CrystalCase& c, const Units& u) {
  const auto s = system_settings(c);
  const std::string_view one = kDimensionless;
  set_with_unit(g, "tau0", per_system(s, [](const auto& x) { return x.tau0; }), u.stress);
  set_with_unit(g, "initial_mu", per_system(s, [](const auto& x) { return x.initial_mu; }), one);
  for (const auto& b : law::kLawBlocks) {
    if (b.choice) {
      g.set_attribute(std::string(b.choice_attribute),
                      per_system_names(s, [&b](const auto& x) { return b.choice(x.law); }));
    }
    for (const auto& k : law::kLawParameters) {
      if (k.block != b.block) continue;
      // NaN for rate-independent systems, which have no overstress constants.
      set_with_unit(g, std::string(k.name),
                    per_system(s,
                               [&k](const auto& x) {
                                 return k.rate_dependent_only &&
                                                x.law.overstress.form ==
                                                    law::OverstressForm::rate_independent
                                            ? std::nan("")
                                            : k.value(x.law);
                               }),
                    law_unit_name(k.unit, true, u));
    }
  }
}

std::string_view latent_kind(const crystal::LatentHardening& l) {
  switch (l.kind) {
    case crystal::LatentHardening::Kind::none:
      return "none";
    case crystal::LatentHardening::Kind::ratio:
      return "ratio";
    case crystal::LatentHardening::Kind::coplanar:
      return "coplanar";
  }
  return "?";
}

void write_phase_parameters(const h5::Group& g, const CrystalCase& c, const Units& u) {
  const crystal::PhaseDescription& d = c.phase;
  std::vector<std::string> families;
  for (auto f : d.families) families.emplace_back(crystal::to_string(f));
  if (families.empty()) families.emplace_back("custom");
  g.set_attribute("slip_families", families);
  g.set_attribute("slip_count", static_cast<long long>(crystal::described_systems(d).size()));
  const bool hexagonal =
      !d.families.empty() && crystal::lattice_of(d.families.front()) == crystal::LatticeKind::hcp;
  if (hexagonal) set_with_unit(g, "c_over_a", d.c_over_a, kDimensionless);
  g.set_attribute("elasticity", c.elasticity_type);
  std::vector<double> c_mandel;
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j) c_mandel.push_back(d.stiffness(i, j));
  const std::size_t mandel_shape[2] = {6, 6};
  g.set_attribute("stiffness_mandel", c_mandel, mandel_shape);
  g.set_attribute("stiffness_mandel.unit", u.stress);
  g.set_attribute("latent", latent_kind(d.latent));
  if (d.latent.kind == crystal::LatentHardening::Kind::ratio)
    set_with_unit(g, "latent_ratio", d.latent.ratio, kDimensionless);
  if (d.latent.kind == crystal::LatentHardening::Kind::coplanar) {
    set_with_unit(g, "latent_coplanar", d.latent.coplanar, kDimensionless);
    set_with_unit(g, "latent_non_coplanar", d.latent.non_coplanar, kDimensionless);
  }
  g.set_attribute("pressure_sensitive", d.pressure_sensitive ? 1 : 0);
  g.set_attribute("kinematics", d.kinematics == crystal::Kinematics::finite_rotation
                                    ? "finite_rotation"
                                    : "small_strain");
}

void write_run_parameters(const h5::Group& g, const CrystalCase& c) {
  g.set_attribute("grains", static_cast<long long>(c.grain_count()));
  g.set_attribute("orientations", c.orientation_source.kind);
  g.set_attribute("orientations_source", c.orientation_source.description);
  const auto& o = c.options;
  g.set_attribute("integrator",
                  o.method == crystal::CrystalMethod::implicit ? "implicit" : "forward_euler");
  // What the steps are solved to (with a tolerance, tied to it unless the scene names its own).
  g.set_attribute("residual_tolerance", crystal::with_effective_grain_tolerance(o).grain.tolerance);
  g.set_attribute("tolerance", o.tolerance);  // 0: fixed increments
  g.set_attribute("order", o.order);          // 1: backward Euler's estimate
  g.set_attribute("max_iterations", o.grain.max_iterations);
  g.set_attribute("max_cutbacks", o.max_cutbacks);
  g.set_attribute("stress_tolerance", o.stress_tolerance);
  g.set_attribute("max_mixed_iterations", o.max_mixed_iterations);
  g.set_attribute("predictor", o.predictor == crystal::MixedPredictor::trend ? "trend" : "last");
}

// The weights of the grains held, normalised by the sum over every grain of the case (summed
// in grain order, also where this process holds a block only).
std::vector<double> normalised_weights(const CrystalCase& c) {
  double total = 0.0;
  if (c.orientation_block) {
    total = c.orientation_block->weight_sum;
  } else {
    for (const auto& o : c.orientations) total += o.weight;
  }
  std::vector<double> w;
  for (const auto& o : c.orientations) w.push_back(o.weight / total);
  return w;
}

// The initial orientations of the grains held: quaternions (w, x, y, z), [grains x 4].
std::vector<double> initial_quaternions(const CrystalCase& c) {
  std::vector<double> q;
  for (const auto& o : c.orientations) {
    const auto v = o.q.canonical().as_vector();
    q.insert(q.end(), v.data(), v.data() + 4);
  }
  return q;
}

constexpr const char* kWeightDescription =
    "volume fraction of each grain (orientation weights normalised to sum 1)";
constexpr const char* kInitialOrientationDescription =
    "initial orientation quaternion (w, x, y, z) of each grain";
constexpr const char* kQuaternionConvention = "passive, Rowenhorst P=-1, w>=0";

void write_grain_statics(const h5::Group& g, const CrystalCase& c,
                         const std::vector<crystal::DescribedSystem>& systems) {
  const std::size_t n = c.grain_count();
  const std::size_t w_shape[1] = {n};
  const std::size_t q_shape[2] = {n, 4};
  if (c.orientation_block) {
    // Each rank holds its block only: they write them (write_grain_block_statics) together.
    g.reserve_array("weight", w_shape, kDimensionless, kWeightDescription);
    g.reserve_array("initial_orientation", q_shape, kDimensionless, kInitialOrientationDescription)
        .set_attribute("convention", kQuaternionConvention);
  } else {
    g.write_array("weight", w_shape, normalised_weights(c), kDimensionless, kWeightDescription);
    g.write_array("initial_orientation", q_shape, initial_quaternions(c), kDimensionless,
                  kInitialOrientationDescription)
        .set_attribute("convention", kQuaternionConvention);
  }
  std::vector<double> sm;
  std::vector<std::string> labels;
  for (const auto& sys : systems) {
    sm.insert(sm.end(), sys.s.data(), sys.s.data() + 3);
    sm.insert(sm.end(), sys.m.data(), sys.m.data() + 3);
    labels.push_back(sys.label);
  }
  const std::size_t s_shape[2] = {systems.size(), 6};
  g.write_array("slip_systems", s_shape, sm, kDimensionless,
                "unit slip direction s (columns 0-2) and slip-plane normal m (columns 3-5), "
                "lattice frame")
      .set_attribute("labels", labels);
}

std::size_t rows_within(std::size_t bytes, std::size_t row_bytes, std::size_t most) {
  return std::clamp<std::size_t>(bytes / std::max<std::size_t>(row_bytes, 1), 1, most);
}

// The per-grain values of `f` for the current state, [grains x k] row-major, in `out`, in the
// shape the table stores it (from the values as the aggregate gives them, through `matrices`).
void fill(GrainField f, const crystal::GrainFields& g, std::vector<double>& matrices,
          std::vector<double>& out) {
  switch (crystal::info(f).stored) {
    case crystal::GrainFieldShape::tensor: {
      // [grains x 6] (11 22 33 23 13 12) from the aggregate, stored as full 3x3 tensors.
      g.values(f, matrices.data());
      constexpr int kRow[6] = {0, 1, 2, 1, 0, 0}, kColumn[6] = {0, 1, 2, 2, 2, 1};
      for (std::size_t k = 0; k < static_cast<std::size_t>(g.grain_count()); ++k) {
        const double* voigt = matrices.data() + 6 * k;
        double* t = out.data() + 9 * k;
        for (int c = 0; c < 6; ++c) {
          t[3 * kRow[c] + kColumn[c]] = voigt[c];
          t[3 * kColumn[c] + kRow[c]] = voigt[c];
        }
      }
      return;
    }
    case crystal::GrainFieldShape::quaternion: {
      // [grains x 9] (row-major orientation matrices), stored as quaternions.
      g.values(f, matrices.data());
      for (int k = 0; k < g.grain_count(); ++k) {
        const auto base = static_cast<std::size_t>(k);
        const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> m(matrices.data() +
                                                                               9 * base);
        const auto v = crystal::matrix_to_quaternion(m).canonical().as_vector();
        std::copy(v.data(), v.data() + 4, out.begin() + static_cast<std::ptrdiff_t>(4 * base));
      }
      return;
    }
    case crystal::GrainFieldShape::per_system:  // as the aggregate gives it
      g.values(f, out.data());
      return;
  }
}

}  // namespace

// ---------------------------------------------------------------- CrystalCaseWriter

namespace {

void lay_out_macro(const h5::Group& group, const CrystalCase& c, const Units& units) {
  const h5::Group macro = group.create_group("macro");
  const std::size_t rows = crystal_output_count(c.segments);
  const std::size_t chunk_rows = std::clamp<std::size_t>(rows, 16, 4096);
  for (MacroField f : c.output.macro) {
    const FieldSpec spec = macro_spec(f, units);
    const h5::Series series =
        macro.create_series({std::string(to_string(f)), 0, spec.type, spec.unit, spec.description,
                             chunk_rows, kMacroBlockRows, rows, spec.shape});
    if (!spec.components.empty()) series.dataset().set_attribute("components", spec.components);
  }
}

// The per-grain rows among the first `rows` output rows (output.grains_at; else all of them).
std::size_t grain_rows_of(const CrystalCase& c, std::size_t rows) {
  const auto& mask = c.output.grain_rows;
  if (mask.empty()) return rows;
  return static_cast<std::size_t>(std::count(
      mask.begin(), mask.begin() + static_cast<std::ptrdiff_t>(std::min(rows, mask.size())), true));
}

void lay_out_grains(const h5::Group& group, const CrystalCase& c, const Units& units) {
  const h5::Group grains = group.create_group("grains");
  const auto systems = crystal::described_systems(c.phase);
  write_grain_statics(grains, c, systems);
  const std::size_t n_grains = c.grain_count();
  const std::size_t rows = grain_rows_of(c, crystal_output_count(c.segments));
  grains.create_series({"row", 0, h5::Type::int32, "index",
                        "the output row (of macro/time and the other macro series) of each "
                        "per-grain row",
                        std::clamp<std::size_t>(rows, 16, 4096), kMacroBlockRows, rows});
  for (GrainField f : c.output.grains) {
    const FieldSpec spec = grain_spec(f, units, systems.size());
    const std::size_t row_bytes = n_grains * width_of(spec) * sizeof(double);
    std::vector<std::size_t> row_shape{n_grains};
    row_shape.insert(row_shape.end(), spec.shape.begin(), spec.shape.end());
    const h5::SeriesSpec s{std::string(to_string(f)),
                           0,
                           spec.type,
                           spec.unit,
                           spec.description,
                           rows_within(kGrainChunkBytes, row_bytes, rows),
                           rows_within(kGrainBlockBytes, row_bytes, kMacroBlockRows),
                           rows,
                           row_shape};
    grains.create_series(s).dataset().set_attribute("components", spec.components);
  }
}

// The summary attributes. `with_units`: also their ".unit" siblings (the layout, which writes
// placeholders); the end of the case rewrites the numbers only, in place.
void write_summary(const h5::Group& g, const CrystalSummary& summary, const Units& units,
                   bool with_units) {
  const auto& st = summary.stats;
  g.set_attribute("increments", st.increments);
  g.set_attribute("substeps", st.substeps);
  g.set_attribute("grain_steps", st.grain_steps);
  g.set_attribute("grain_solves", st.grain_solves);
  g.set_attribute("newton_iterations", st.newton_iterations);
  g.set_attribute("cutbacks", st.cutbacks);
  g.set_attribute("rejected_steps", st.rejected);
  g.set_attribute("mixed_iterations", st.mixed_iterations);
  const std::string one(kDimensionless);
  const std::pair<const char*, std::string> numbers[] = {{"wall_seconds", "s"},
                                                         {"grain_steps_per_second", "1/s"},
                                                         {"final_time", units.time},
                                                         {"final_von_mises_stress", units.stress},
                                                         {"final_von_mises_strain", one}};
  const double values[] = {st.wall_seconds, summary.grain_steps_per_second,
                           summary.final_state.time, summary.final_von_mises_stress,
                           summary.final_von_mises_strain};
  for (std::size_t k = 0; k < std::size(values); ++k) {
    g.set_attribute(numbers[k].first, values[k]);
    if (with_units) g.set_attribute(std::string(numbers[k].first) + ".unit", numbers[k].second);
  }
  g.set_attribute("final_stress", row_major(summary.final_state.stress), kTensorShape);
  g.set_attribute("final_strain", row_major(summary.final_state.strain), kTensorShape);
  if (with_units) {
    g.set_attribute("final_stress.unit", units.stress);
    g.set_attribute("final_strain.unit", one);
  }
}

// What a case's summary attributes hold until it ends.
CrystalSummary placeholder_crystal_summary() {
  const double nan = std::nan("");
  CrystalSummary s;
  s.final_state.time = nan;
  s.final_state.stress = Mat3::Constant(nan);
  s.final_state.strain = Mat3::Constant(nan);
  s.final_von_mises_stress = nan;
  s.final_von_mises_strain = nan;
  s.grain_steps_per_second = nan;
  s.stats.wall_seconds = nan;
  return s;
}

}  // namespace

void CrystalCaseWriter::lay_out(const h5::Group& cases, const CrystalCase& c, int index,
                                const Units& units) {
  const h5::Group group =
      create_case_group(cases, c.name, index, c.overrides, SceneKind::crystal, units);
  write_phase_parameters(group, c, units);
  write_law_parameters(group, c, units);
  write_run_parameters(group, c);
  group.set_attribute("orientations_digest", c.orientations_digest());
  write_summary(group, placeholder_crystal_summary(), units, true);
  group.reserve_string_attribute("failed", h5::kFailureMessageBytes);
  lay_out_macro(group, c, units);
  if (!c.output.grains.empty()) lay_out_grains(group, c, units);
}

CrystalCaseWriter::CrystalCaseWriter(const h5::Group& cases, const CrystalCase& c, int index,
                                     const Units& units, h5::CaseProgress& progress,
                                     std::size_t rows, const parallel::Block* block)
    : group_(cases.open_group(case_group_name(c.name))),
      units_(units),
      progress_(progress),
      index_(static_cast<std::size_t>(index)) {
  if (group_.attribute_string("orientations_digest") != c.orientations_digest()) {
    throw InputError(c.orientation_source.description, 0, "orientations",
                     "case '" + c.name +
                         "': the orientations differ from those the interrupted run used; "
                         "restore them or start a new run");
  }
  // The counts first: from here on, rows beyond them are left-overs to be overwritten.
  const std::size_t grain_rows = grain_rows_of(c, rows);
  progress_.set_rows(index_, rows);
  progress_.set_grain_rows(index_, grain_rows);
  grain_mask_ = c.output.grain_rows;
  const h5::Group macro = group_.open_group("macro");
  for (MacroField f : c.output.macro) {
    const FieldSpec spec = macro_spec(f, units_);
    macro_[static_cast<std::size_t>(f)].emplace(
        macro.open_series(to_string(f), spec.type, rows, kMacroBlockRows));
  }
  if (c.output.grains.empty()) return;
  const h5::Group grains = group_.open_group("grains");
  grain_row_.emplace(grains.open_series("row", h5::Type::int32, grain_rows, kMacroBlockRows));
  const std::size_t n_grains = block != nullptr ? block->count : c.grain_count();
  const std::size_t slip_count = crystal::described_systems(c.phase).size();
  std::size_t widest = 9;  // the orientation matrices are read before conversion
  for (GrainField f : c.output.grains) {
    const FieldSpec spec = grain_spec(f, units_, slip_count);
    const std::size_t row_bytes = c.grain_count() * width_of(spec) * sizeof(double);
    h5::Series& series = grains_[static_cast<std::size_t>(f)].emplace(
        grains.open_series(to_string(f), spec.type, grain_rows,
                           rows_within(kGrainBlockBytes, row_bytes, kMacroBlockRows)));
    if (block != nullptr) series.select_grains(block->offset, block->count);
    grain_width_[static_cast<std::size_t>(f)] = n_grains * width_of(spec);
    widest = std::max(widest, width_of(spec));
  }
  matrices_.resize(n_grains * 9);
  row_.resize(n_grains * widest);
}

void CrystalCaseWriter::append(const crystal::MacroState& m, const crystal::GrainFields& grains) {
  const std::size_t row = rows();  // the output row this state is
  for (std::size_t k = 0; k < macro_.size(); ++k) {
    if (!macro_[k]) continue;
    h5::Series& out = *macro_[k];
    switch (kAllMacroFields[k]) {
      case MacroField::time:
        out.append(m.time);
        break;
      case MacroField::L:
        out.append(row_major(m.velocity_gradient));
        break;
      case MacroField::F:
        out.append(row_major(m.deformation_gradient));
        break;
      case MacroField::strain:
        out.append(row_major(m.strain));
        break;
      case MacroField::stress:
        out.append(row_major(m.stress));
        break;
      case MacroField::segment:
        out.append_int(m.segment);
        break;
    }
  }
  if (!grain_row_ || !(grain_mask_.empty() || (row < grain_mask_.size() && grain_mask_[row])))
    return;
  grain_row_->append_int(static_cast<int>(row));
  for (std::size_t k = 0; k < grains_.size(); ++k) {
    if (!grains_[k]) continue;
    fill(kAllGrainFields[k], grains, matrices_, row_);
    grains_[k]->append(std::span<const double>(row_.data(), grain_width_[k]));
  }
}

void CrystalCaseWriter::commit() {
  std::size_t rows = 0;
  for (auto& s : macro_) {
    if (!s) continue;
    s->commit();
    rows = s->rows();
  }
  for (auto& s : grains_) {
    if (s) s->commit();
  }
  if (grain_row_) {
    grain_row_->commit();
    progress_.set_grain_rows(index_, grain_row_->rows());
  } else {
    progress_.set_grain_rows(index_, rows);
  }
  progress_.set_rows(index_, rows);  // after the rows it counts are in the file
}

std::size_t CrystalCaseWriter::rows() const {
  return macro_[0]->rows();  // `time` is always written
}

void CrystalCaseWriter::close_series() {
  commit();
  for (auto& s : macro_) {
    if (s) s->finish();
  }
  for (auto& s : grains_) {
    if (s) s->finish();
  }
  if (grain_row_) grain_row_->finish();
}

void CrystalCaseWriter::finish(const CrystalSummary& summary) {
  close_series();
  write_summary(group_, summary, units_, false);
}

void CrystalCaseWriter::mark_failed(const CrystalSummary& summary, const std::string& why) {
  finish(summary);
  group_.write_reserved_string("failed", why);
}

// ---------------------------------------------------------------- the sink

namespace {

Mat3 matrix_attribute(const h5::Group& g, const char* name) {
  const auto v = g.attribute_doubles(name);
  Mat3 m = Mat3::Zero();
  for (int i = 0; i < 3 && v.size() == 9; ++i)
    for (int j = 0; j < 3; ++j) m(i, j) = v[static_cast<std::size_t>(3 * i + j)];
  return m;
}

// Everything the run will write into, before it computes anything (h5_writer.hpp, crash
// safety): the header, every case group, /progress and the checkpoint store.
CrystalRunFiles lay_out(const CrystalScene& scene, h5::File& file,
                        const CrystalSinkOptions& options) {
  const h5::Group root = file.root();
  h5::ResultHeader header{"crystal",
                          scene.file,
                          scene.text,
                          scene.title,
                          crystal_units(scene.units),
                          options.computed_with,
                          scene.compression.gzip_level};
  header.makeup = scene.makeup;
  h5::write_result_header(file, header);
  h5::Group cases = root.create_group("cases");
  std::vector<std::string> names;
  for (const auto& c : scene.cases) names.push_back(case_group_name(c.name));
  cases.set_attribute("names", names);
  for (std::size_t k = 0; k < scene.cases.size(); ++k)
    CrystalCaseWriter::lay_out(cases, scene.cases[k], static_cast<int>(k), scene.units);
  h5::CaseProgress progress = h5::CaseProgress::create(root, names.size(), true);
  CrystalRunFiles run{std::move(cases), std::move(progress)};
  // The restart file is complete before the result says its layout is.
  if (options.checkpoint_capacity > 0 && !options.restart_file.empty()) {
    run.restart_file.emplace(create_restart_file(
        options.restart_file, root.attribute_string("run_id"), options.checkpoint_capacity));
  }
  h5::mark_layout_complete(file);
  return run;
}

// A restart: the run's restart file, or a new one when it has none (deleted, or checkpoints
// were off) and a case now writes checkpoints.
std::optional<h5::File> reopen_restart_file(const h5::File& file,
                                            const CrystalSinkOptions& options) {
  if (options.restart_file.empty()) return std::nullopt;
  const std::string run_id = file.root().attribute_string("run_id");
  const h5::MpiAccess* mpi = options.mpi ? &*options.mpi : nullptr;
  if (auto existing = open_restart_file(options.restart_file, run_id, mpi)) return existing;
  if (options.checkpoint_capacity == 0) return std::nullopt;
  // (the ranks of a collective run reopen what one process made: it is made first)
  if (mpi != nullptr)
    throw std::logic_error(
        "CrystalResultSink: the restart file must exist before MPI ranks open it");
  return create_restart_file(options.restart_file, run_id, options.checkpoint_capacity);
}

CrystalRunFiles reopen(h5::File& file, const CrystalSinkOptions& options) {
  h5::mark_running(file);
  const h5::Group root = file.root();
  return {root.open_group("cases"), h5::CaseProgress::open(root),
          reopen_restart_file(file, options)};
}

}  // namespace

namespace {

const CrystalSinkOptions& checked(const CrystalSinkOptions& options, const h5::File& file) {
  if (options.mpi.has_value() != file.collective() || (options.mpi && !options.restart))
    throw std::logic_error(
        "CrystalResultSink: MPI ranks continue a file laid out before, opened by all of them");
  return options;
}

}  // namespace

CrystalResultSink::CrystalResultSink(const CrystalScene& scene, h5::File& file,
                                     const CrystalSinkOptions& options)
    : scene_(scene),
      file_(file),
      options_(checked(options, file)),
      run_(options.restart ? reopen(file, options) : lay_out(scene, file, options)) {
  if (options_.restart) write_grain_statics_again();
}

// The weights and initial orientations of the grains, written again whenever a file is
// reopened. Where the layout could not write them (no process held them all:
// CrystalCase::orientation_block) every rank writes its block of every such case,
// collectively. Where it did, a run killed before its first flush (the first checkpoint or
// output row) may have left them off the disk while the case's layout is there: a 2-rank run
// killed early and restarted serially had every weight and orientation at the fill value
// (Mpi.RunKilledUnderTwoRanksContinuesUnderOne under load, SUBSLIP_KILL_SEED=2713552083).
// The values are the scene's, which a restart has checked is the file's.
void CrystalResultSink::write_grain_statics_again() {
  const bool writes_all = !options_.mpi || options_.mpi->rank == 0;
  for (const CrystalCase& c : scene_.cases) {
    if (c.output.grains.empty()) continue;
    const h5::Group grains = run_.cases.open_group(case_group_name(c.name)).open_group("grains");
    const bool block = c.orientation_block.has_value();
    const std::size_t first = block ? c.orientation_block->offset : 0;
    const bool writes = block || writes_all;  // (under MPI every rank takes part, collectively)
    grains.open_dataset("weight").write_rows(
        first, writes ? normalised_weights(c) : std::vector<double>{});
    grains.open_dataset("initial_orientation")
        .write_rows(first, writes ? initial_quaternions(c) : std::vector<double>{});
  }
}

std::optional<parallel::Block> CrystalResultSink::grains_of(std::size_t index) const {
  if (!options_.mpi) return std::nullopt;
  return parallel::block_of(scene_.cases[index].grain_count(), options_.mpi->rank, options_.ranks);
}

driver::CaseStatus CrystalResultSink::status(std::size_t index) const {
  return case_status(run_.progress.state(index));
}

// Read back from the case's summary attributes.
driver::StoredCrystalCase CrystalResultSink::stored_case(std::size_t index) const {
  const h5::Group g = run_.cases.open_group(case_group_name(scene_.cases[index].name));
  auto count = [&](const char* name) {
    return g.has_attribute(name) ? static_cast<long>(g.attribute_int(name)) : 0L;
  };
  driver::StoredCrystalCase stored;
  crystal::AggregateStats& st = stored.stats;
  st.increments = count("increments");
  st.substeps = count("substeps");
  st.grain_steps = count("grain_steps");
  st.grain_solves = count("grain_solves");
  st.newton_iterations = count("newton_iterations");
  st.cutbacks = count("cutbacks");
  st.rejected = count("rejected_steps");
  st.mixed_iterations = count("mixed_iterations");
  st.wall_seconds = g.has_attribute("wall_seconds") ? g.attribute_double("wall_seconds") : 0.0;
  if (g.has_attribute("final_time")) {
    stored.final_state.time = g.attribute_double("final_time");
    stored.final_state.stress = matrix_attribute(g, "final_stress");
    stored.final_state.strain = matrix_attribute(g, "final_strain");
  }
  stored.failure = h5::failure_message(g);
  return stored;
}

std::optional<driver::ResumePoint> CrystalResultSink::latest_checkpoint(std::size_t index) const {
  if (!run_.restart_file) return std::nullopt;
  const int rank = options_.mpi ? options_.mpi->rank : 0;
  auto latest = CheckpointStore(run_.restart_file->root()).latest(index, rank, options_.ranks);
  if (!latest) return std::nullopt;
  return driver::ResumePoint{std::move(latest->state), latest->rows, latest->last_output};
}

std::size_t CrystalResultSink::checkpoint_capacity() const {
  return run_.restart_file ? CheckpointStore(run_.restart_file->root()).capacity() : 0;
}

void CrystalResultSink::begin_case(std::size_t index, const driver::ResumePoint* resume) {
  index_ = index;
  checkpoints_.reset();
  if (run_.restart_file) checkpoints_.emplace(run_.restart_file->root());
  const std::optional<parallel::Block> mine = grains_of(index);
  writer_.emplace(run_.cases, scene_.cases[index], static_cast<int>(index), scene_.units,
                  run_.progress, resume ? resume->rows : 0, mine ? &*mine : nullptr);
  run_.progress.set_state(index, h5::CaseState::running);
  // (collective writes: every output step, as the ranks' clocks would pace them apart)
  if (options_.mpi)
    pacer_.emplace(std::chrono::duration<double>(0.0), 0.0);
  else
    pacer_.emplace(options_.flush_interval, options_.write_cost_ratio);
}

void CrystalResultSink::write_state(const crystal::MacroState& state,
                                    const driver::GrainBlock& grains) {
  // This process's block: every grain, or its share when MPI ranks write the file together.
  const std::optional<parallel::Block> mine = grains_of(index_);
  if (mine ? grains.range.offset != mine->offset || grains.range.count != mine->count
           : !grains.range.whole())
    throw std::logic_error("CrystalResultSink: grains of another block");
  writer_->append(state, grains.fields);
  if (pacer_->due()) pacer_->commit([&] { writer_->commit(); });
}

void CrystalResultSink::write_checkpoint(const driver::CheckpointBlock& checkpoint,
                                         const crystal::MacroState& last_output) {
  const std::optional<parallel::Block> mine = grains_of(index_);
  if (!checkpoints_ ||
      (mine ? checkpoint.range.offset != mine->offset || checkpoint.range.count != mine->count
            : !checkpoint.range.whole()))
    throw std::logic_error("CrystalResultSink: no store for this checkpoint");
  pacer_->commit([&] { writer_->commit(); });  // the rows a checkpoint counts come first
  checkpoints_->write(index_, checkpoint.state, writer_->rows(), last_output,
                      mine ? &*mine : nullptr);
}

void CrystalResultSink::complete_case(const driver::CrystalSummary& summary) {
  writer_->finish(summary);
  end_case(h5::CaseState::completed);
}

void CrystalResultSink::fail_case(const driver::CrystalSummary& summary, const std::string& why) {
  writer_->mark_failed(summary, why);
  end_case(h5::CaseState::failed);
}

void CrystalResultSink::end_case(h5::CaseState state) {
  file_.flush();  // the summary attributes first: the state says they are complete
  run_.progress.set_state(index_, state);
  writer_.reset();
  checkpoints_.reset();
  pacer_.reset();
}

void CrystalResultSink::end_run() {
  if (run_.restart_file) run_.restart_file->close();
}

namespace {

// Bytes a case's group takes besides its series (attributes, grain statics' headers, B-trees).
constexpr double kCaseOverheadBytes = 64e3;
// Copies of a grain's checkpoint values (x 8 bytes) a running case holds (committed and trial
// states, the checkpoint): measured, peak RSS grows by 2.0 kB per FCC grain
// (2e4 -> 2e5 grains), against 4 x 504 + 128 bytes = 2.1 kB estimated.
constexpr double kStateCopies = 4.0;

// The further copies the extrapolated integrator of order k holds (AggregateOptions::order): the
// step's start state and its k solutions (integrators/extrapolation.hpp).
double extrapolation_copies(const crystal::AggregateOptions& o) {
  return o.tolerance > 0.0 && o.order >= 2 ? static_cast<double>(o.order + 1) : 0.0;
}

// The output rows of each of the case's segments.
std::vector<std::size_t> segment_rows(const CrystalCase& c) {
  std::vector<std::size_t> rows;
  for (const auto& s : c.segments) {
    const std::vector<crystal::LoadSegment> one{s};
    rows.push_back(crystal_output_count(one) - 1);
  }
  return rows;
}

}  // namespace

RunSize estimate_crystal_run(const CrystalScene& scene, std::optional<long> checkpoint_every) {
  RunSize size;
  double largest_case = -1.0;
  for (const auto& c : scene.cases) {
    const std::size_t slip_count = crystal::described_systems(c.phase).size();
    const double rows = static_cast<double>(crystal_output_count(c.segments));
    const double grains = static_cast<double>(c.grain_count());
    double macro_values = 0.0, grain_values = 0.0;
    for (MacroField f : c.output.macro)
      macro_values += static_cast<double>(width_of(macro_spec(f, scene.units)));
    for (GrainField f : c.output.grains)
      grain_values += static_cast<double>(width_of(grain_spec(f, scene.units, slip_count)));
    // Grain series reserve whole chunks of up to kGrainChunkBytes each.
    const double chunk_slack = static_cast<double>(c.output.grains.size() * kGrainChunkBytes);
    const double grain_rows = static_cast<double>(
        grain_rows_of(c, static_cast<std::size_t>(crystal_output_count(c.segments))));
    const double bytes = 8.0 * (rows * macro_values + grain_rows * grains * grain_values) +
                         chunk_slack + 8.0 * grains * 16.0 + kCaseOverheadBytes;
    size.result_bytes += bytes;
    // The finished file, written before the working one goes: no reserved chunk space.
    size.finish_bytes += bytes - chunk_slack;
    const double per_grain = 8.0 * crystal::state_values_per_grain(static_cast<int>(slip_count));
    const double copies = kStateCopies + extrapolation_copies(c.options);
    // (+ the slip-rate trend, one vector per grain)
    const double memory = grains * (copies * per_grain + 8.0 * (16.0 + slip_count)) +
                          static_cast<double>(c.output.grains.size() * kGrainBlockBytes);
    if (memory > size.memory_bytes) {
      size.memory_bytes = memory;
      size.grains = c.grain_count();
    }
    if (bytes > largest_case) {
      largest_case = bytes;
      size.rows = static_cast<std::size_t>(rows);
      const auto per_segment = segment_rows(c);
      size.rows_segment = static_cast<std::size_t>(
          std::max_element(per_segment.begin(), per_segment.end()) - per_segment.begin());
    }
  }
  // Two slots, each of the largest case's grain values (in the restart file).
  size.checkpoint_bytes =
      2.0 * 8.0 * static_cast<double>(driver::checkpoint_capacity(scene, checkpoint_every));
  size.result_bytes += size.checkpoint_bytes;
  return size;
}

}  // namespace subslip::io
