// Crystal result files: the documented layout of a tiny run (2 grains, 3 increments), values
// equal to what the aggregate reported to its observer, only the requested fields, and the
// command line (subslip run on inputs/default.yaml, subslip orientations).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "scratch_dir.hpp"
#include "shell_command.hpp"
#include "subslip/crystal/flow_point_batch.hpp"
#include "subslip/crystal/measures.hpp"
#include "subslip/crystal/rotation.hpp"
#include "subslip/driver/crystal_run.hpp"
#include "subslip/io/crystal_output.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/orientation_file.hpp"
#include "subslip/io/result_file.hpp"
#include "subslip/io/result_protocol.hpp"

namespace fs = std::filesystem;
using namespace subslip;
using namespace subslip::io;

namespace {

const fs::path kSource = SUBSLIP_SOURCE_DIR;
const std::string kBinary = SUBSLIP_BINARY;

const std::string kScene = R"(scene: crystal
title: "tiny crystal run"
units: {stress: MPa, time: s}
phase:
  families: [fcc_111_110]
  elasticity: {type: cubic, C11: 168400, C12: 121400, C44: 75400}
  tau0: 10.0
  law:
    friction: {mu_s: 1.0, mu_k: 3.0, kappa: 5.0, xi: 0.0}
    subloading: {function: cot, u_tilde: 200}
    overstress: {form: exponential, eta_v: 1.0e-3, n: 16, r_hat: 1.6}
orientations:
  euler_deg: [[10, 20, 30], [45, 30, 10, 3]]
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 3
    increments: 3
)";

const std::string kAllGrains =
    "output:\n  grains: [stress, orientation, slip, slip_rate, crss, strength, r, r_s, tau]\n";

fs::path scratch_dir() {
  return subslip::testing::scratch_dir("crystal");
}

// What the aggregate handed to the observer at one output step.
struct Reported {
  crystal::MacroState macro;
  std::vector<double> stress, orientation, slip, slip_rate, crss, strength, r, r_s, tau;
};

Reported copy_of(const crystal::MacroState& m, const crystal::GrainFields& g) {
  const auto n = static_cast<std::size_t>(g.grain_count());
  const auto k = static_cast<std::size_t>(g.slip_count());
  Reported r{m,
             std::vector<double>(n * 6),
             std::vector<double>(n * 9),
             std::vector<double>(n * k),
             std::vector<double>(n * k),
             std::vector<double>(n * k),
             std::vector<double>(n * k),
             std::vector<double>(n * k),
             std::vector<double>(n * k),
             std::vector<double>(n * k)};
  g.values(crystal::GrainField::stress, r.stress.data());
  g.values(crystal::GrainField::orientation, r.orientation.data());
  g.values(crystal::GrainField::slip, r.slip.data());
  g.values(crystal::GrainField::slip_rate, r.slip_rate.data());
  g.values(crystal::GrainField::crss, r.crss.data());
  g.values(crystal::GrainField::strength, r.strength.data());
  g.values(crystal::GrainField::r, r.r.data());
  g.values(crystal::GrainField::r_s, r.r_s.data());
  g.values(crystal::GrainField::tau, r.tau.data());
  return r;
}

// Runs `text` into `out`, returning what the observer saw.
std::vector<Reported> run_into(const std::string& text, const fs::path& out) {
  const CrystalScene scene = parse_crystal_scene(YamlDocument::from_string(text, "tiny.yaml"));
  h5::File file = h5::File::create(out, true);
  std::vector<Reported> seen;
  driver::CrystalRunOptions options;
  options.on_state = [&](std::size_t, const crystal::MacroState& m, const crystal::GrainFields& g) {
    seen.push_back(copy_of(m, g));
  };
  CrystalResultSink sink(scene, file, {});
  const auto results = driver::run_crystal_scene(scene, sink, options);
  EXPECT_EQ(results.size(), 1u);
  EXPECT_TRUE(results[0].failure.empty()) << results[0].failure;
  close_and_finish(file);
  return seen;
}

std::vector<double> row_major(const Eigen::Matrix3d& m) {
  std::vector<double> v;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) v.push_back(m(i, j));
  return v;
}

// Row `step` of an [n, ...] dataset read as doubles.
std::vector<double> step_of(const std::vector<double>& all, std::size_t step, std::size_t width) {
  return {all.begin() + static_cast<std::ptrdiff_t>(step * width),
          all.begin() + static_cast<std::ptrdiff_t>((step + 1) * width)};
}

std::vector<std::string> sorted(std::vector<std::string> v) {
  std::sort(v.begin(), v.end());
  return v;
}

}  // namespace

TEST(CrystalOutput, TinyRunHasTheDocumentedLayoutAndTheObservedValues) {
  const fs::path out = scratch_dir() / "tiny.h5";
  const std::vector<Reported> seen = run_into(kScene + kAllGrains, out);
  ASSERT_EQ(seen.size(), 4u);  // the initial state and 3 increments
  const std::size_t n = 4, grains = 2, systems = 12;

  const h5::File file = h5::File::open_read(out);
  const h5::Group root = file.root();
  EXPECT_EQ(root.attribute_string("scene_kind"), "crystal");
  EXPECT_EQ(root.attribute_int("completed"), 1);
  EXPECT_EQ(root.attribute_string("title"), "tiny crystal run");
  const h5::Group units = root.open_group("units");
  EXPECT_EQ(units.attribute_string("stress"), "MPa");
  EXPECT_EQ(units.attribute_string("time"), "s");
  EXPECT_FALSE(units.has_attribute("length"));
  const h5::Group cases = root.open_group("cases");
  EXPECT_EQ(cases.attribute_strings("names"), std::vector<std::string>{"base"});
  const h5::Group c = cases.open_group("base");

  // macro
  const h5::Group macro = c.open_group("macro");
  EXPECT_EQ(sorted(macro.members()), sorted({"time", "L", "F", "strain", "stress", "segment"}));
  const auto time = macro.open_dataset("time");
  EXPECT_EQ(time.shape(), (std::vector<std::size_t>{n}));
  EXPECT_EQ(time.attribute_string("unit"), "s");
  const auto stress = macro.open_dataset("stress");
  // Every tensor [n, 3, 3], [n, i, j] = component ij, saying so in `components`.
  for (const char* tensor : {"L", "F", "strain", "stress"}) {
    SCOPED_TRACE(tensor);
    const auto d = macro.open_dataset(tensor);
    EXPECT_EQ(d.shape(), (std::vector<std::size_t>{n, 3, 3}));
    EXPECT_EQ(d.attribute_string("components"), h5::kTensorConvention);
    EXPECT_FALSE(d.has_attribute("layout"));
  }
  EXPECT_EQ(stress.attribute_string("unit"), "MPa");
  EXPECT_EQ(macro.open_dataset("L").attribute_string("unit"), "1/s");
  EXPECT_EQ(macro.open_dataset("F").attribute_string("unit"), "1");
  EXPECT_EQ(macro.open_dataset("segment").read_ints(), (std::vector<long long>{-1, 0, 0, 0}));
  const auto t = time.read_doubles();
  const auto s = stress.read_doubles();
  const auto l = macro.open_dataset("L").read_doubles();
  const auto f = macro.open_dataset("F").read_doubles();
  const auto e = macro.open_dataset("strain").read_doubles();
  for (std::size_t k = 0; k < n; ++k) {
    EXPECT_EQ(t[k], seen[k].macro.time);
    EXPECT_EQ(step_of(s, k, 9), row_major(seen[k].macro.stress));
    EXPECT_EQ(step_of(l, k, 9), row_major(seen[k].macro.velocity_gradient));
    EXPECT_EQ(step_of(f, k, 9), row_major(seen[k].macro.deformation_gradient));
    EXPECT_EQ(step_of(e, k, 9), row_major(seen[k].macro.strain));
  }
  EXPECT_GT(s.back(), 0.0);  // sigma33 in tension

  // grains: statics
  const h5::Group g = c.open_group("grains");
  EXPECT_EQ(g.open_dataset("weight").read_doubles(), (std::vector<double>{0.25, 0.75}));
  const auto q0 = g.open_dataset("initial_orientation");
  EXPECT_EQ(q0.shape(), (std::vector<std::size_t>{grains, 4}));
  EXPECT_EQ(q0.attribute_string("convention"), "passive, Rowenhorst P=-1, w>=0");
  const auto expected_q0 =
      crystal::euler_to_quaternion(crystal::degrees_to_radians(Eigen::Vector3d(10, 20, 30)));
  EXPECT_NEAR(q0.read_doubles()[0], expected_q0.canonical().w, 1e-14);
  const auto slip_systems = g.open_dataset("slip_systems");
  EXPECT_EQ(slip_systems.shape(), (std::vector<std::size_t>{systems, 6}));
  EXPECT_EQ(slip_systems.attribute_strings("labels").size(), systems);

  // grains: series, [n, G, k], equal to the observed fields
  struct Expect {
    const char* name;
    std::size_t k;
    std::vector<double> Reported::*field;
    const char* unit;
  };
  const Expect expect[] = {{"slip", systems, &Reported::slip, "1"},
                           {"slip_rate", systems, &Reported::slip_rate, "1/s"},
                           {"crss", systems, &Reported::crss, "MPa"},
                           {"strength", systems, &Reported::strength, "MPa"},
                           {"r", systems, &Reported::r, "1"},
                           {"r_s", systems, &Reported::r_s, "1"},
                           {"tau", systems, &Reported::tau, "MPa"}};
  for (const Expect& x : expect) {
    SCOPED_TRACE(x.name);
    const auto d = g.open_dataset(x.name);
    EXPECT_EQ(d.shape(), (std::vector<std::size_t>{n, grains, x.k}));
    EXPECT_EQ(d.attribute_string("unit"), x.unit);
    EXPECT_FALSE(d.attribute_string("description").empty());
    const auto values = d.read_doubles();
    for (std::size_t k = 0; k < n; ++k)
      EXPECT_EQ(step_of(values, k, grains * x.k), seen[k].*x.field);
  }
  // The resolved shear is the one r reports: |tau| = r mu tau0 = r CRSS (no plane pressure).
  for (std::size_t k = 0; k < n; ++k) {
    for (std::size_t i = 0; i < grains * systems; ++i) {
      const double resolved = seen[k].r[i] * seen[k].crss[i];
      EXPECT_NEAR(std::abs(seen[k].tau[i]), resolved, 1e-13 * (1.0 + resolved)) << k << " " << i;
    }
  }
  EXPECT_NE(seen.back().tau[0], 0.0);
  // Without the pressure-sensitive reading the yield traction is the CRSS.
  for (std::size_t k = 0; k < n; ++k) EXPECT_EQ(seen[k].strength, seen[k].crss) << k;
  // The grain stress as full 3x3 tensors [n, G, 3, 3]: the kernel's 11 22 33 23 13 12 at (i, j)
  // and (j, i).
  const auto grain_stress = g.open_dataset("stress");
  EXPECT_EQ(grain_stress.shape(), (std::vector<std::size_t>{n, grains, 3, 3}));
  EXPECT_EQ(grain_stress.attribute_string("components"), h5::kTensorConvention);
  EXPECT_EQ(grain_stress.attribute_string("unit"), "MPa");
  const auto sigma = grain_stress.read_doubles();
  const int voigt_i[6] = {0, 1, 2, 1, 0, 0}, voigt_j[6] = {0, 1, 2, 2, 2, 1};
  for (std::size_t k = 0; k < n; ++k) {
    for (std::size_t grain = 0; grain < grains; ++grain) {
      const double* t = sigma.data() + (k * grains + grain) * 9;
      const double* v = seen[k].stress.data() + 6 * grain;
      for (int c = 0; c < 6; ++c) {
        EXPECT_EQ(t[3 * voigt_i[c] + voigt_j[c]], v[c]);
        EXPECT_EQ(t[3 * voigt_j[c] + voigt_i[c]], v[c]);
      }
    }
  }
  EXPECT_NE(sigma[(n - 1) * grains * 9 + 8], 0.0);  // sigma_33 of grain 0 in tension

  const auto orientation = g.open_dataset("orientation");
  EXPECT_EQ(orientation.shape(), (std::vector<std::size_t>{n, grains, 4}));
  const auto q = orientation.read_doubles();
  for (std::size_t k = 0; k < n; ++k) {
    for (std::size_t grain = 0; grain < grains; ++grain) {
      const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> m(
          seen[k].orientation.data() + 9 * grain);
      const auto v = crystal::matrix_to_quaternion(m).canonical().as_vector();
      for (int a = 0; a < 4; ++a)
        EXPECT_EQ(q[(k * grains + grain) * 4 + static_cast<std::size_t>(a)], v(a));
    }
  }

  // case attributes
  EXPECT_EQ(c.attribute_int("increments"), 3);
  EXPECT_EQ(c.attribute_int("grain_steps"), 6);
  EXPECT_GE(c.attribute_int("grain_solves"), 6);
  EXPECT_GT(c.attribute_int("newton_iterations"), 0);
  EXPECT_GT(c.attribute_int("mixed_iterations"), 0);
  EXPECT_TRUE(c.has_attribute("wall_seconds"));
  EXPECT_TRUE(c.has_attribute("grain_steps_per_second"));
  EXPECT_EQ(c.attribute_string("final_von_mises_stress.unit"), "MPa");
  EXPECT_EQ(c.attribute_doubles("final_stress"), row_major(seen.back().macro.stress));  // [3, 3]
  EXPECT_EQ(c.attribute_size("stiffness_mandel"), 36u);
  EXPECT_NEAR(c.attribute_double("final_von_mises_stress"),
              crystal::von_mises_stress(seen.back().macro.stress), 1e-12);
  EXPECT_EQ(c.attribute_doubles("tau0"), std::vector<double>(systems, 10.0));
  EXPECT_EQ(c.attribute_string("tau0.unit"), "MPa");
  EXPECT_EQ(c.attribute_string("eta_v.unit"), "s");
  EXPECT_EQ(c.attribute_string("kappa.unit"), "1");
  EXPECT_EQ(c.attribute_string("xi.unit"), "1/s");
  EXPECT_EQ(c.attribute_strings("slip_families"), std::vector<std::string>{"fcc_111_110"});
  EXPECT_EQ(c.attribute_string("kinematics"), "finite_rotation");
  EXPECT_EQ(c.attribute_int("grains"), 2);
}

TEST(CrystalOutput, OnlyTheRequestedFieldsAreWritten) {
  const fs::path dir = scratch_dir();
  run_into(kScene + "output:\n  macro: [time, stress]\n  grains: [crss]\n", dir / "some.h5");
  {
    const h5::File file = h5::File::open_read(dir / "some.h5");
    const h5::Group c = file.root().open_group("cases").open_group("base");
    EXPECT_EQ(sorted(c.open_group("macro").members()), sorted({"time", "stress"}));
    EXPECT_EQ(sorted(c.open_group("grains").members()),
              sorted({"weight", "initial_orientation", "slip_systems", "row", "crss"}));
  }
  run_into(kScene, dir / "macro_only.h5");
  const h5::File file = h5::File::open_read(dir / "macro_only.h5");
  const h5::Group c = file.root().open_group("cases").open_group("base");
  EXPECT_FALSE(c.has("grains"));
  EXPECT_EQ(c.open_group("macro").members().size(), kAllMacroFields.size());
}

TEST(CrystalOutput, LoadingComponentAndVonMises) {
  crystal::LoadSegment s;
  s.velocity_gradient(0, 1) = 2.0;
  s.velocity_gradient(2, 2) = 1.0;
  s.free(2, 2) = true;  // a free component does not drive the case
  EXPECT_EQ(driver::loading_component({s}), (std::pair<int, int>{0, 1}));
  Eigen::Matrix3d uniaxial = Eigen::Matrix3d::Zero();
  uniaxial(2, 2) = 100.0;
  EXPECT_NEAR(crystal::von_mises_stress(uniaxial), 100.0, 1e-12);
  Eigen::Matrix3d strain = Eigen::Vector3d(-0.5, -0.5, 1.0).asDiagonal();
  EXPECT_NEAR(crystal::von_mises_strain(strain * 0.01), 0.01, 1e-15);
}

// ---------------------------------------------------------------- the command line

namespace {

using Outcome = subslip::testing::CommandOutput;

// Runs `subslip ARGS` in `dir`, stdout and stderr together in `out`.
Outcome run_cli(const fs::path& dir, const std::string& args) {
  return subslip::testing::run_command("cd '" + dir.string() + "' && '" + kBinary + "' " + args +
                                       " 2>&1");
}

}  // namespace

TEST(CrystalCli, RunsTheDefaultSceneIntoATempFile) {
  const fs::path dir = scratch_dir();
  const Outcome r =
      run_cli(dir, "run '" + (kSource / "inputs/default.yaml").string() + "' -o out.h5 -j 2");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("results: out.h5"), std::string::npos) << r.out;
  // The table names the loading component and the stress unit.
  EXPECT_NE(r.out.find("strain_33  stress[MPa]"), std::string::npos) << r.out;
  const h5::File file = h5::File::open_read(dir / "out.h5");
  EXPECT_EQ(file.root().attribute_int("completed"), 1);
  // How the results were computed: the build and the grain solver's SIMD kernels (results of
  // different builds, or of "none" against a wide set, differ by round-off).
  EXPECT_EQ(file.root().attribute_string("build"), SUBSLIP_BUILD);
  EXPECT_EQ(file.root().attribute_string("simd_kernels"), crystal::detail::flow_batch_isa_name());
  // The --version line says the same.
  const Outcome version = run_cli(dir, "--version");
  ASSERT_EQ(version.code, 0) << version.out;
  EXPECT_NE(version.out.find(std::string(SUBSLIP_BUILD) + " build"), std::string::npos)
      << version.out;
  EXPECT_NE(version.out.find(std::string("batches: ") + crystal::detail::flow_batch_isa_name()),
            std::string::npos)
      << version.out;
  EXPECT_NE(version.out.find(std::string("48 systems: ") + crystal::detail::grain_step_isa_name()),
            std::string::npos)
      << version.out;
  // The finished result: its rows only, no checkpoint (the restart file is gone), small.
  EXPECT_EQ(file.root().attribute_int("finished"), 1);
  EXPECT_FALSE(file.root().has("checkpoint"));
  EXPECT_FALSE(fs::exists(dir / "out.restart.h5"));
  EXPECT_LT(fs::file_size(dir / "out.h5"), 200u * 1000u);
  const h5::Group c = file.root().open_group("cases").open_group("base");
  EXPECT_EQ(c.open_group("macro").open_dataset("time").shape(), (std::vector<std::size_t>{251}));
  EXPECT_FALSE(c.has("grains"));
  // Uniaxial tension: sigma33 carries the load, the lateral stresses are held at zero.
  const auto stress = c.open_group("macro").open_dataset("stress").read_doubles();
  const double s33 = stress[250 * 9 + 8];
  EXPECT_GT(s33, 50.0);
  EXPECT_LT(std::abs(stress[250 * 9 + 0]), 1e-6 * s33);
}

TEST(CrystalCli, OrientationsSubcommandWritesAndRefusesToOverwrite) {
  const fs::path dir = scratch_dir();
  ASSERT_EQ(run_cli(dir, "orientations --random 5 --seed 2 -o random.txt").code, 0);
  EXPECT_EQ(read_orientation_file((dir / "random.txt").string()).size(), 5u);
  const Outcome again = run_cli(dir, "orientations --random 5 --seed 2 -o random.txt");
  EXPECT_EQ(again.code, 2) << again.out;
  EXPECT_NE(again.out.find("--force"), std::string::npos) << again.out;
  EXPECT_EQ(run_cli(dir, "orientations --random 6 --seed 2 -o random.txt --force").code, 0);
  EXPECT_EQ(read_orientation_file((dir / "random.txt").string()).size(), 6u);
  const Outcome goss =
      run_cli(dir, "orientations --component goss --spread 5 --count 3 --seed 1 -o goss.txt");
  ASSERT_EQ(goss.code, 0) << goss.out;
  EXPECT_EQ(read_orientation_file((dir / "goss.txt").string()).size(), 3u);
  EXPECT_EQ(run_cli(dir, "orientations --component gos --count 3 -o x.txt").code, 2);
  EXPECT_EQ(run_cli(dir, "orientations --seed 3").code, 2);
}
