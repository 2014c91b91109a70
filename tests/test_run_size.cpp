// The size check before a run: the result file (checkpoints included) and the memory
// of a scene are estimated from its layout, and a scene that cannot fit in the free space of the
// output's file system or in memory is refused naming the key and line, before any work.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "subslip/io/contact_output.hpp"
#include "subslip/io/crystal_output.hpp"
#include "subslip/io/crystal_scene.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/run_size.hpp"
#include "subslip/io/yaml_checked.hpp"

using namespace subslip;
using namespace subslip::io;

namespace {

// FCC, `grains` random grains, two segments (the second with `increments`), every grain field.
std::string crystal_text(int grains, const std::string& increments) {
  return R"(scene: crystal
units: {stress: MPa, time: s}
phase:
  families: [fcc_111_110]
  elasticity: {type: cubic, C11: 168400, C12: 121400, C44: 75400}
  tau0: 10.0
  law:
    friction: {mu_s: 1.6, mu_k: 14.8, kappa: 20.0, xi: 0.01}
    subloading: {function: cot, u_tilde: 200}
    overstress: {form: exponential, eta_v: 1.0e-3, n: 16, r_hat: 1.6}
orientations:
  random: {count: )" +
         std::to_string(grains) + R"(}
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 1
    increments: 10
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 50
    increments: )" +
         increments + R"(
output:
  macro: [time, L, F, strain, stress, segment]
  grains: [stress, orientation, slip, slip_rate, crss, r, r_s]
)";
}

InputError refusal(const YamlDocument& d, const RunSize& size, const Capacity& capacity) {
  try {
    check_run_fits(d, size, capacity, "out/x.h5");
  } catch (const InputError& e) {
    return e;
  }
  ADD_FAILURE() << "accepted";
  return InputError("", 0, "", "");
}

}  // namespace

// A typo: 250000000 increments for 250, 1000 grains with every field.
TEST(RunSize, CrystalEstimateCountsEveryRowOfEveryGrain) {
  const YamlDocument d = YamlDocument::from_string(crystal_text(1000, "250000000"), "s.yaml");
  const RunSize size = estimate_crystal_run(parse_crystal_scene(d), 0);
  // rows x (macro 1 + 4 x 9 + 1, grains 1000 x (9 + 4 + 5 x 12)) x 8 bytes
  const double rows = 10 + 250000000 + 1;
  const double expected = rows * (38.0 + 1000.0 * 73.0) * 8.0;
  EXPECT_GE(size.result_bytes, expected);
  EXPECT_LT(size.result_bytes, expected * 1.001);
  EXPECT_EQ(size.rows, 250000011u);
  EXPECT_EQ(size.rows_segment, 1u);
  EXPECT_EQ(size.grains, 1000u);
  EXPECT_EQ(size.checkpoint_bytes, 0.0);  // checkpoint_every 0: none
}

TEST(RunSize, CheckpointsAreCounted) {
  const YamlDocument d = YamlDocument::from_string(crystal_text(100, "20"), "s.yaml");
  const RunSize size = estimate_crystal_run(parse_crystal_scene(d), 5);
  // two slots of 100 grains x (15 + 6 x 12) values
  EXPECT_EQ(size.checkpoint_bytes, 2.0 * 8.0 * 100.0 * 87.0);
  EXPECT_GT(size.result_bytes, size.checkpoint_bytes);
}

TEST(RunSize, TooLargeForTheDiskIsRefusedAtTheIncrements) {
  const YamlDocument d = YamlDocument::from_string(crystal_text(1000, "250000000"), "s.yaml");
  const RunSize size = estimate_crystal_run(parse_crystal_scene(d), 0);
  const InputError e = refusal(d, size, {1e12, 1e12});
  EXPECT_EQ(e.file, "s.yaml");
  EXPECT_EQ(e.line, 21);
  EXPECT_EQ(e.key, "loading[1].increments");
  EXPECT_NE(e.message.find("the result would take about 146 TB (250000011 output rows)"),
            std::string::npos)
      << e.what();
  EXPECT_NE(e.message.find("out/x.h5 is on a file system with 1 TB free"), std::string::npos)
      << e.what();
  EXPECT_NE(e.message.find("output_every"), std::string::npos) << e.what();
  EXPECT_NE(e.message.find("fewer grains"), std::string::npos) << e.what();
  EXPECT_NO_THROW(check_run_fits(d, size, {1e15, 1e12}, "out/x.h5"));
}

TEST(RunSize, TooLargeForMemoryIsRefusedAtTheOrientations) {
  const YamlDocument d = YamlDocument::from_string(crystal_text(1000, "10"), "s.yaml");
  const RunSize size = estimate_crystal_run(parse_crystal_scene(d), 0);
  EXPECT_GT(size.memory_bytes, 1000.0 * 63.0 * 8.0);
  const InputError e = refusal(d, size, {1e15, 1e5});
  EXPECT_EQ(e.line, 12);  // the orientations themselves (random: {count: 1000})
  EXPECT_EQ(e.key, "orientations");
  EXPECT_NE(e.message.find("(1000 grains), but 100 kB are available"), std::string::npos)
      << e.what();
  EXPECT_NE(e.message.find("use fewer grains"), std::string::npos) << e.what();
}

// The extrapolated integrator of order k holds k + 1 more copies of every grain's state (the
// step's start and its k solutions): the estimate grows by that, and only for it.
TEST(RunSize, ExtrapolatedIntegratorCountsItsStateCopies) {
  const auto memory = [](const std::string& integrator) {
    const YamlDocument d =
        YamlDocument::from_string(crystal_text(1000, "10") + integrator, "s.yaml");
    return estimate_crystal_run(parse_crystal_scene(d), 0).memory_bytes;
  };
  const double fixed = memory("");
  const double backward_euler =
      memory("integrator: {method: implicit, tolerance: 1.0e-4, order: 1}\n");
  const double order3 = memory("integrator: {method: implicit, tolerance: 1.0e-4, order: 3}\n");
  const double default_order = memory("integrator: {method: implicit, tolerance: 1.0e-4}\n");
  EXPECT_EQ(backward_euler, fixed);
  // 1000 grains x 4 copies x (15 + 4 x 12 values) x 8 bytes
  EXPECT_EQ(order3 - fixed, 1000.0 * 4.0 * 63.0 * 8.0);
  // A tolerance without an order is order 2: 3 copies.
  EXPECT_EQ(default_order - fixed, 1000.0 * 3.0 * 63.0 * 8.0);
}

TEST(RunSize, ContactEstimateAndRefusal) {
  const std::string text = R"(scene: contact
units: {stress: MPa, length: mm, time: min}
law:
  friction: {mu_s: 0.097, mu_k: 0.085, kappa: 0.2, xi: 0.009}
  subloading: {function: cot, u_tilde: 80}
  overstress: {form: exponential, eta_v: 950, n: 16, r_hat: 1.8}
contact: {alpha_n: 1.0e6, alpha_t: 1.0e6, normal_traction: 5.56}
loading:
  - slide: {speed: 1.0, direction: [1, 0], distance: 1.0}
    increments: 250000000
output:
  fields: [time, ratio, traction]
)";
  const YamlDocument d = YamlDocument::from_string(text, "c.yaml");
  const RunSize size = estimate_contact_run(parse_contact_scene(d));
  EXPECT_GE(size.result_bytes, 250000001.0 * 5 * 8);  // time 1, ratio 1, traction 3
  EXPECT_LT(size.result_bytes, 250000001.0 * 5 * 8 * 1.001);
  const InputError e = refusal(d, size, {1e9, 1e12});
  EXPECT_EQ(e.line, 10);
  EXPECT_EQ(e.key, "loading[0].increments");
  EXPECT_EQ(e.message.find("grains"), std::string::npos) << e.what();
}

TEST(RunSize, BytesAreFormattedInDecimalUnits) {
  EXPECT_EQ(format_bytes(512), "512 bytes");
  EXPECT_EQ(format_bytes(75e9), "75 GB");
  EXPECT_EQ(format_bytes(1.4e15), "1.4 PB");
}
