// The subslip executable: run, output-path safety, error lines and exit codes; where the
// progress goes and the width of what is printed.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "scene_text.hpp"
#include "scratch_dir.hpp"
#include "shell_command.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/result_protocol.hpp"
#include "terminal_screen.hpp"

namespace fs = std::filesystem;
using namespace subslip::io;

namespace {

const fs::path kSource = SUBSLIP_SOURCE_DIR;
const std::string kBinary = SUBSLIP_BINARY;

const std::string kScene =
    subslip::testing::contact_scene_start("title: \"cli test\"\n") + R"(loading:
  - slide: {speed: 10, direction: [1, 0], distance: 0.2}
    increments: 200
    growth: 1.03
sweep:
  "loading[0].slide.speed": [1, 100]
)";

struct Outcome {
  int code;
  std::string out;
  std::string err;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

fs::path scratch_dir() {
  return subslip::testing::scratch_dir("cli");
}

// Runs `subslip ARGS` in `dir`, capturing stdout and stderr.
Outcome run(const fs::path& dir, const std::string& args) {
  const fs::path err = dir / "stderr.txt";
  const std::string command =
      "cd '" + dir.string() + "' && '" + kBinary + "' " + args + " 2>'" + err.string() + "'";
  const auto [code, out] = subslip::testing::run_command(command);
  return {code, out, slurp(err)};
}

void write(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary) << text;
}

bool contains(const std::string& s, const std::string& part) {
  return s.find(part) != std::string::npos;
}

}  // namespace

TEST(Cli, HelpListsTheRunCommandAndItsOptions) {
  const fs::path dir = scratch_dir();
  const Outcome top = run(dir, "--help");
  EXPECT_EQ(top.code, 0);
  EXPECT_TRUE(contains(top.out, "run")) << top.out;
  const Outcome sub = run(dir, "run --help");
  EXPECT_EQ(sub.code, 0);
  for (const char* option : {"--output", "--force", "--quiet", "--threads"}) {
    EXPECT_TRUE(contains(sub.out, option)) << option << "\n" << sub.out;
  }
  EXPECT_EQ(run(dir, "").code, 2);               // a subcommand is required
  EXPECT_EQ(run(dir, "run --bogus x").code, 2);  // usage errors are input errors
  fs::remove_all(dir);
}

TEST(Cli, RunWritesTheDefaultOutputAndPrintsTheSummary) {
  const fs::path dir = scratch_dir();
  write(dir / "tiny.yaml", kScene);
  const Outcome r = run(dir, "run tiny.yaml");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(r.err.empty()) << r.err;
  const fs::path out = dir / "results/tiny.h5";
  ASSERT_TRUE(fs::exists(out));
  EXPECT_TRUE(contains(r.out, "speed=1 ")) << r.out;
  EXPECT_TRUE(contains(r.out, "speed=100")) << r.out;
  EXPECT_TRUE(contains(r.out, "peak")) << r.out;
  EXPECT_TRUE(contains(r.out, "results/tiny.h5")) << r.out;
  const h5::File file = h5::File::open_read(out);
  EXPECT_EQ(file.root().attribute_int("completed"), 1);
  EXPECT_EQ(file.root().attribute_string("scene_file"), "tiny.yaml");
  EXPECT_EQ(file.root().open_group("cases").members().size(), 2u);
  // --quiet prints nothing.
  const Outcome q = run(dir, "run tiny.yaml -o quiet.h5 --quiet");
  EXPECT_EQ(q.code, 0);
  EXPECT_TRUE(q.out.empty()) << q.out;
  EXPECT_TRUE(fs::exists(dir / "quiet.h5"));
  fs::remove_all(dir);
}

TEST(Cli, RefusesToOverwriteWithoutForceAndLeavesTheOldFile) {
  const fs::path dir = scratch_dir();
  write(dir / "tiny.yaml", kScene);
  ASSERT_EQ(run(dir, "run tiny.yaml -o out.h5 -q").code, 0);
  const std::string before = slurp(dir / "out.h5");
  const auto mtime = fs::last_write_time(dir / "out.h5");
  const Outcome again = run(dir, "run tiny.yaml -o out.h5");
  EXPECT_EQ(again.code, 2);
  EXPECT_TRUE(contains(again.err, "subslip: error: out.h5: already exists; use --force"))
      << again.err;
  EXPECT_FALSE(contains(again.out, "peak")) << again.out;  // nothing was run
  EXPECT_EQ(slurp(dir / "out.h5"), before);                // byte-identical
  EXPECT_EQ(fs::last_write_time(dir / "out.h5"), mtime);
  const Outcome forced = run(dir, "run tiny.yaml -o out.h5 --force -q");
  EXPECT_EQ(forced.code, 0) << forced.err;
  EXPECT_EQ(h5::File::open_read(dir / "out.h5").root().attribute_int("completed"), 1);
  fs::remove_all(dir);
}

TEST(Cli, UnwritableOutputFailsBeforeRunning) {
  const fs::path dir = scratch_dir();
  write(dir / "tiny.yaml", kScene);
  write(dir / "a_file", "not a directory");
  for (const std::string target : {"/proc/subslip_cli_test/out.h5", "a_file/out.h5"}) {
    SCOPED_TRACE(target);
    const Outcome r = run(dir, "run tiny.yaml -o " + target);
    EXPECT_EQ(r.code, 2);
    EXPECT_TRUE(contains(r.err, "subslip: error: " + target + ":")) << r.err;
    EXPECT_EQ(r.err.find('\n'), r.err.size() - 1) << "one line: " << r.err;
    EXPECT_FALSE(contains(r.out, "peak")) << r.out;
  }
  fs::remove_all(dir);
}

TEST(Cli, BrokenSceneIsOneErrorLineWithExitCode2) {
  const fs::path dir = scratch_dir();
  const fs::path scene = kSource / "tests/data/scenes/unknown_key.yaml";
  const Outcome r = run(dir, "run '" + scene.string() + "' -o out.h5");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.err, "subslip: error: " + scene.string() +
                       ":7: law.overstress.eta: unknown key 'eta'; did you mean 'eta_v'?\n");
  EXPECT_FALSE(fs::exists(dir / "out.h5"));  // input is checked before the output is created
  const Outcome missing = run(dir, "run no_such_scene.yaml");
  EXPECT_EQ(missing.code, 2);
  EXPECT_TRUE(contains(missing.err, "no_such_scene.yaml")) << missing.err;
  fs::remove_all(dir);
}

TEST(Cli, NumericalFailureExitsWith3AndKeepsAnIncompleteFile) {
  const fs::path dir = scratch_dir();
  // One forward-Euler increment over the whole slide, with no cutbacks allowed: r jumps past
  // r_hat and the step cannot be completed.
  std::string text = kScene.substr(0, kScene.find("    increments: 200"));
  text += "    increments: 1\nintegrator: {method: forward_euler, max_cutbacks: 0}\n";
  write(dir / "fails.yaml", text);
  const Outcome r = run(dir, "run fails.yaml -o fails.h5");
  EXPECT_EQ(r.code, 3) << r.err;
  EXPECT_TRUE(contains(r.err, "subslip: error: case 'base': contact step failed")) << r.err;
  const h5::File file = h5::File::open_read(dir / "fails.h5");
  EXPECT_EQ(file.root().attribute_int("completed"), 0);
  EXPECT_NE(h5::failure_message(file.root().open_group("cases/base")), "");
  fs::remove_all(dir);
}

namespace {

// A small crystal scene reading `orientations.txt` (beside it).
const std::string kCrystalScene = R"(scene: crystal
units: {stress: MPa, time: s}
phase:
  families: [fcc_111_110]
  elasticity: {type: cubic, C11: 168400, C12: 121400, C44: 75400}
  tau0: 10.0
  law:
    friction: {mu_s: 1.6, mu_k: 14.8, kappa: 20.0, xi: 0.01}
    subloading: {function: cot, u_tilde: 200}
    overstress: {form: exponential, eta_v: 1.0e-3, n: 16, r_hat: 1.6}
orientations: {file: orientations.txt}
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 1
    increments: 5
)";

}  // namespace

// -o naming the scene or an orientation file is refused, with --force too, and the file stays.
TEST(Cli, OutputOverAnInputFileIsRefusedEvenWithForce) {
  const fs::path dir = scratch_dir();
  write(dir / "crystal.yaml", kCrystalScene);
  write(dir / "orientations.txt",
        "# subslip-orientations convention=bunge-euler-deg\n10 20 30\n40 50 60\n");
  for (const std::string target : {"crystal.yaml", "./orientations.txt"}) {
    SCOPED_TRACE(target);
    const std::string before = slurp(dir / target);
    const Outcome r = run(dir, "run crystal.yaml -q --force -o " + target);
    EXPECT_EQ(r.code, 2);
    EXPECT_TRUE(contains(r.err, "subslip: error: " + target + ": is the input file")) << r.err;
    EXPECT_EQ(slurp(dir / target), before);
  }
  fs::remove_all(dir);
}

// Euler angles that all lie within 2 pi under a degree header: a warning naming the file.
TEST(Cli, EulerAnglesThatLookLikeRadiansAreWarnedAbout) {
  const fs::path dir = scratch_dir();
  write(dir / "crystal.yaml", kCrystalScene);
  write(dir / "orientations.txt",
        "# subslip-orientations convention=bunge-euler-deg\n0.5 1.2 3.1\n2.0 0.3 6.2\n");
  const Outcome radians = run(dir, "run crystal.yaml -o a.h5");
  EXPECT_EQ(radians.code, 0) << radians.err;
  EXPECT_TRUE(contains(radians.err,
                       "warning: crystal.yaml: orientations.file: orientations.txt: "
                       "every Euler angle of the 2 orientations is within 2 pi"))
      << radians.err;
  write(dir / "orientations.txt",
        "# subslip-orientations convention=bunge-euler-deg\n30 1.2 3.1\n2.0 0.3 6.2\n");
  const Outcome degrees = run(dir, "run crystal.yaml -o b.h5");
  EXPECT_EQ(degrees.code, 0) << degrees.err;
  EXPECT_FALSE(contains(degrees.err, "2 pi")) << degrees.err;
  fs::remove_all(dir);
}

// A value out of range: the usual error line, with readable bounds.
TEST(Cli, RangeErrorsAreOneErrorLineWithReadableBounds) {
  const fs::path dir = scratch_dir();
  const Outcome r = run(dir, "orientations --random 0");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.err.rfind("subslip: error: --random: must be > 0, got 0", 0), 0u) << r.err;
  EXPECT_LT(r.err.size(), 120u) << r.err;
  const Outcome spread = run(dir, "orientations --component cube --spread 200");
  EXPECT_EQ(spread.code, 2);
  EXPECT_TRUE(contains(spread.err, "must be in [0, 180], got 200")) << spread.err;
  fs::remove_all(dir);
}

// A binary file given as a scene: one short line, not the file's bytes.
TEST(Cli, BinaryFileAsSceneIsOneShortLine) {
  const fs::path dir = scratch_dir();
  std::string bytes = "scene: contact\n";
  for (int i = 0; i < 4096; ++i) bytes.push_back(static_cast<char>((i * 37 + 11) % 256));
  write(dir / "binary.yaml", bytes);
  const Outcome r = run(dir, "run binary.yaml -o out.h5");
  EXPECT_EQ(r.code, 2);
  // 0x9F, the 5th byte of line 2, cannot start a UTF-8 character.
  EXPECT_EQ(r.err.rfind("subslip: error: binary.yaml:2: byte 0x9F at column 5 is not UTF-8", 0), 0u)
      << r.err;
  EXPECT_LT(r.err.size(), 250u) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out.h5"));
  fs::remove_all(dir);
}

// A result larger than any disk (1e4 grains, every field, 2e9 increments: ~12 PB) is refused
// before the file is created, naming the key and line; 1e12 increments name the key's limit.
TEST(Cli, ResultTooLargeForTheDiskIsRefusedBeforeAnyWork) {
  const fs::path dir = scratch_dir();
  std::string scene = kCrystalScene;
  scene.replace(scene.find("{file: orientations.txt}"), 24, "{random: {count: 10000}}");
  scene.replace(scene.find("increments: 5"), 13, "increments: 2000000000");
  scene += "output: {grains: [stress, orientation, slip, slip_rate, crss, r, r_s]}\n";
  write(dir / "big.yaml", scene);
  const Outcome r = run(dir, "run big.yaml -o out/big.h5");
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(r.err.rfind("subslip: error: big.yaml:16: loading[0].increments: the result would "
                        "take about 11.7 PB",
                        0),
            0u)
      << r.err;
  EXPECT_TRUE(contains(r.err, "output_every")) << r.err;
  EXPECT_FALSE(fs::exists(dir / "out"));
  scene.replace(scene.find("increments: 2000000000"), 22, "increments: 1000000000000");
  write(dir / "big.yaml", scene);
  const Outcome limit = run(dir, "run big.yaml -o out/big.h5");
  EXPECT_EQ(limit.code, 2);
  EXPECT_TRUE(contains(limit.err,
                       "big.yaml:16: loading[0].increments: 1000000000000 is above "
                       "the largest value this key takes, 2147483647"))
      << limit.err;
  fs::remove_all(dir);
}

// ---------------------------------------------------------------- terminal width and streams

namespace {

using subslip::testing::columns_of;
using subslip::testing::lines_of;

// Two crystal cases of 200 random grains and 50 increments each (a second or so in all, long
// enough for the bar to be redrawn), whose names ("kappa=20.0,u_tilde=200,eta_v=1.0e-3") are
// too long for the name column of an 80-column table and differ only at their ends.
const std::string kCrystalSweep = R"(scene: crystal
units: {stress: MPa, time: s}
phase:
  families: [fcc_111_110]
  elasticity: {type: cubic, C11: 168400, C12: 121400, C44: 75400}
  tau0: 10.0
  law:
    friction: {mu_s: 1.6, mu_k: 14.8, kappa: 20.0, xi: 0.01}
    subloading: {function: cot, u_tilde: 200}
    overstress: {form: exponential, eta_v: 1.0e-3, n: 16, r_hat: 1.6}
orientations: {random: {count: 200, seed: 7}}
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 20
    increments: 50
sweep:
  "phase.law.friction.kappa": [20.0]
  "phase.law.subloading.u_tilde": [200]
  "phase.law.overstress.eta_v": [1.0e-3, 2.0e-3]
)";

// The progress line's own words, which must never reach stdout.
void expect_no_progress(const std::string& out) {
  EXPECT_EQ(out.find('\r'), std::string::npos) << out;
  EXPECT_EQ(out.find('\x1b'), std::string::npos) << out;
  EXPECT_FALSE(contains(out, "case 1/2")) << out;
  EXPECT_FALSE(contains(out, "elapsed")) << out;
  EXPECT_FALSE(contains(out, " left ")) << out;
  EXPECT_FALSE(contains(out, "progress:")) << out;
}

void expect_lines_fit_80(const std::string& out) {
  ASSERT_FALSE(out.empty());
  for (const auto& line : lines_of(out)) EXPECT_LE(columns_of(line), 80) << line;
}

}  // namespace

// With stdout redirected and stderr a terminal, the bar is drawn on stderr and stdout holds only
// the results; with neither a terminal, stderr gets no bar either.
TEST(Cli, ProgressGoesToStderrAndStdoutKeepsOnlyTheResults) {
  const fs::path dir = scratch_dir();
  write(dir / "sweep.yaml", kCrystalSweep);
  const auto on_terminal = subslip::testing::run_on_terminal(
      dir, {"run", "sweep.yaml", "-o", "a.h5"}, 80, dir / "stdout.txt");
  ASSERT_EQ(on_terminal.code, 0) << on_terminal.terminal;
  EXPECT_TRUE(contains(on_terminal.terminal, "\rcase 1/2 ")) << on_terminal.terminal;
  EXPECT_TRUE(contains(on_terminal.terminal, "\x1b[K")) << on_terminal.terminal;
  const std::string out = slurp(dir / "stdout.txt");
  expect_no_progress(out);
  EXPECT_TRUE(contains(out, "done in ")) << out;
  EXPECT_TRUE(contains(out, "results: a.h5")) << out;
  EXPECT_FALSE(contains(on_terminal.terminal, "results: a.h5")) << on_terminal.terminal;

  const Outcome files = run(dir, "run sweep.yaml -o b.h5");
  ASSERT_EQ(files.code, 0) << files.err;
  expect_no_progress(files.out);
  EXPECT_EQ(files.err.find('\r'), std::string::npos) << files.err;  // no bar off a terminal
  EXPECT_TRUE(contains(files.out, "done in ")) << files.out;
  fs::remove_all(dir);
}

// On an 80-column terminal the bar never wraps and leaves no line behind: the screen holds one
// row per line the run ended with a newline (the bar itself only returns the carriage). (Not
// compared with a second, redirected run: its summary's timings can wrap to another line count.)
TEST(Cli, ProgressStaysOneLineOnAnEightyColumnTerminal) {
  const fs::path dir = scratch_dir();
  write(dir / "sweep.yaml", kCrystalSweep);
  const auto tty = subslip::testing::run_on_terminal(dir, {"run", "sweep.yaml", "-o", "a.h5"}, 80);
  ASSERT_EQ(tty.code, 0) << tty.terminal;
  ASSERT_TRUE(contains(tty.terminal, "\rcase 1/2 ")) << "the bar was drawn";
  subslip::testing::Screen screen(80);
  screen.feed(tty.terminal);
  EXPECT_EQ(screen.wraps, 0) << tty.terminal;
  const auto rows = screen.text_rows();
  for (const auto& row : rows) EXPECT_FALSE(contains(row, "elapsed") || contains(row, " %")) << row;
  const auto newlines = std::count(tty.terminal.begin(), tty.terminal.end(), '\n');
  EXPECT_EQ(rows.size(), static_cast<std::size_t>(newlines)) << tty.terminal;
  EXPECT_TRUE(contains(rows.back(), "results: a.h5")) << tty.terminal;
  fs::remove_all(dir);
}

// `subslip bench` says the mixed-control inputs it ran with and takes the stress tolerance: at one
// the first sweep meets (1e-4 with the trend predictor) an FCC aggregate takes fewer grain solves
// per step than at the default (1e-10); a tolerance that is not positive is refused.
TEST(Cli, BenchTakesTheStressTolerance) {
  const fs::path dir = scratch_dir();
  auto bench = [&](const std::string& extra) {
    const Outcome o = run(
        dir, "bench --grains 50 --steps 40 --threads 1 --lattice fcc --predictor trend" + extra);
    EXPECT_EQ(o.code, 0) << o.err;
    // The fcc row: phase, slips, grains, threads, gsteps/s, newton, solves/step, ...
    const auto row = o.out.find("\nfcc ");
    std::istringstream in(row == std::string::npos ? std::string() : o.out.substr(row + 1));
    std::string phase, slips, grains, threads, rate, newton;
    double solves = 0.0;
    in >> phase >> slips >> grains >> threads >> rate >> newton >> solves;
    return std::pair{o.out, solves};
  };
  const auto [tight_out, tight] = bench("");
  const auto [loose_out, loose] = bench(" --stress-tolerance 1e-4");
  EXPECT_TRUE(contains(tight_out, "predictor trend, stress_tolerance 1e-10")) << tight_out;
  EXPECT_TRUE(contains(loose_out, "stress_tolerance 0.0001")) << loose_out;
  EXPECT_GT(loose, 0.0) << loose_out;
  EXPECT_LT(loose, tight) << tight_out << loose_out;
  EXPECT_NE(run(dir, "bench --stress-tolerance 0").code, 0);
  fs::remove_all(dir);
}

// The tables of `subslip run` (contact and crystal, long case names wrapped whole), of
// `subslip bench` and the summary of `subslip post` fit 80 columns, units in the headers.
TEST(Cli, TablesFitEightyColumns) {
  const fs::path dir = scratch_dir();
  write(dir / "tiny.yaml", kScene);
  const Outcome contact = run(dir, "run tiny.yaml -o c.h5");
  ASSERT_EQ(contact.code, 0) << contact.err;
  expect_lines_fit_80(contact.out);
  EXPECT_TRUE(contains(contact.out, "slip@peak[mm]")) << contact.out;
  EXPECT_TRUE(contains(contact.out, "\nspeed=1 ")) << contact.out;
  EXPECT_TRUE(contains(contact.out, "\nspeed=100 ")) << contact.out;

  write(dir / "sweep.yaml", kCrystalSweep);
  const Outcome crystal = run(dir, "run sweep.yaml -o s.h5");
  ASSERT_EQ(crystal.code, 0) << crystal.err;
  expect_lines_fit_80(crystal.out);
  EXPECT_TRUE(contains(crystal.out, "stress[MPa]")) << crystal.out;
  EXPECT_TRUE(contains(crystal.out, "wall[s]")) << crystal.out;
  // A name wider than its column (18 of 80 here) goes on over further lines, after its commas.
  EXPECT_TRUE(contains(crystal.out, "\nkappa=20.0, ")) << crystal.out;
  EXPECT_TRUE(contains(crystal.out, "\nu_tilde=200,\neta_v=1.0e-3\n")) << crystal.out;
  EXPECT_TRUE(contains(crystal.out, "\nu_tilde=200,\neta_v=2.0e-3\n")) << crystal.out;
  EXPECT_FALSE(contains(crystal.out, "...")) << crystal.out;

  const Outcome bench = run(dir, "bench --grains 4 --steps 2 --threads 1");
  ASSERT_EQ(bench.code, 0) << bench.err;
  expect_lines_fit_80(bench.out);
  EXPECT_TRUE(contains(bench.out, "\nbcc48 ")) << bench.out;

  const Outcome post = run(dir, "post s.h5");
  ASSERT_EQ(post.code, 0) << post.err;
  expect_lines_fit_80(post.out);
  EXPECT_TRUE(contains(post.out, "macro/stress")) << post.out;
  fs::remove_all(dir);
}

// A swept value with a unit keeps it in the case's name ("speed=1 mm/min"), in the table, in
// `post` and in `post --case`; the group stores '/' as '_' and says so.
TEST(Cli, SweepNamesKeepTheirUnits) {
  const fs::path dir = scratch_dir();
  write(dir / "units.yaml", subslip::testing::contact_scene_start() + R"(loading:
  - slide: {speed: 10, direction: [1, 0], distance: 0.2}
    increments: 50
sweep:
  "loading[0].slide.speed": [1 mm/min, 0.5 mm/s]
)");
  const Outcome r = run(dir, "run units.yaml -o u.h5");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(contains(r.out, "\nspeed=1 mm/min ")) << r.out;
  EXPECT_TRUE(contains(r.out, "\nspeed=0.5 mm/s ")) << r.out;
  const Outcome post = run(dir, "post u.h5");
  ASSERT_EQ(post.code, 0) << post.err;
  EXPECT_TRUE(contains(post.out, "2: speed=1 mm/min, speed=0.5 mm/s\n")) << post.out;
  EXPECT_TRUE(contains(post.out, "\ncase speed=1 mm/min (group /cases/speed=1 mm_min, index 0)"))
      << post.out;
  const Outcome one = run(dir, "post u.h5 --case 'speed=0.5 mm/s'");
  ASSERT_EQ(one.code, 0) << one.err;
  EXPECT_TRUE(contains(one.out, "\ncase speed=0.5 mm/s (group /cases/speed=0.5 mm_s, index 1)"))
      << one.out;
  EXPECT_FALSE(contains(one.out, "case speed=1 mm/min (")) << one.out;
  EXPECT_EQ(run(dir, "post u.h5 --case 'speed=0.5 mm_s'").code, 0);
  const Outcome bad = run(dir, "post u.h5 --case 'speed=2 mm/min'");
  EXPECT_EQ(bad.code, 2);
  EXPECT_TRUE(contains(bad.err, "the file has: speed=1 mm/min, speed=0.5 mm/s")) << bad.err;
  fs::remove_all(dir);
}

// `--set` (before or after the scene, repeatable) and a base scene: the run uses both, `post`
// names both, and a bad setting is an error naming the argument.
TEST(Cli, SettingsAndBaseScenes) {
  const fs::path dir = scratch_dir();
  write(dir / "tiny.yaml", kScene);
  write(dir / "over.yaml", "base: tiny.yaml\ntitle: \"over\"\n");
  const Outcome r = run(
      dir, "run --set 'loading[0].increments=20' over.yaml --set law.friction.mu_s=0.1 -o o.h5");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_TRUE(contains(r.out, "subslip: over.yaml: 2 cases - over\n")) << r.out;
  EXPECT_TRUE(contains(r.out, "\nspeed=1 ")) << r.out;
  EXPECT_TRUE(contains(r.out, ": 2 cases, 40 increments,")) << r.out;
  const Outcome post = run(dir, "post o.h5");
  ASSERT_EQ(post.code, 0) << post.err;
  EXPECT_TRUE(contains(post.out, "\nbase scene:  tiny.yaml (/scene_bases/1)\n")) << post.out;
  EXPECT_TRUE(contains(post.out, "\nset:         loading[0].increments=20\n")) << post.out;
  EXPECT_TRUE(contains(post.out, "\nset:         law.friction.mu_s=0.1\n")) << post.out;

  const Outcome bad = run(dir, "run over.yaml --set law.friction.mu_ss=0.1 --set kappa -o b.h5");
  EXPECT_EQ(bad.code, 2);
  EXPECT_TRUE(contains(bad.err, "subslip: error: --set kappa: expected PATH=VALUE")) << bad.err;
  EXPECT_FALSE(fs::exists(dir / "b.h5"));
  const Outcome unknown = run(dir, "run over.yaml --set law.friction.mu_ss=0.1 -o b.h5");
  EXPECT_EQ(unknown.code, 2);
  EXPECT_EQ(unknown.err,
            "subslip: error: --set law.friction.mu_ss=0.1: law.friction.mu_ss: unknown key "
            "'mu_ss'; did you mean 'mu_s'?\n");
  fs::remove_all(dir);
}

// The point lines of `subslip accuracy` are a table under each integrator; the long lines (the
// reference, failures) are wrapped.
TEST(Cli, AccuracyLinesFitEightyColumns) {
  const fs::path dir = scratch_dir();
  write(dir / "tiny.yaml", kScene);
  const Outcome r = run(dir,
                        "accuracy tiny.yaml --case speed=1 -o acc --no-plot --repeat 1 "
                        "--max-run-seconds 0.5 --implicit 1 2 --adaptive 1e-3");
  ASSERT_EQ(r.code, 0) << r.err;
  expect_lines_fit_80(r.out);
  EXPECT_TRUE(contains(r.out, "  implicit              steps  max error")) << r.out;
  fs::remove_all(dir);
}

// A crystal study against references at its runs' own times measures time into each segment:
// its table gives where the max error is as "segment:time" (a bare time read as an absolute one),
// the segment the csv names.
TEST(Cli, AccuracyTableNamesTheSegmentOfTimesIntoSegments) {
  const fs::path dir = scratch_dir();
  std::string scene = kCrystalScene;
  scene += R"(  - L: [[x, 0, 0], [0, x, 0], [0, 0, -1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 1
    increments: 5
)";
  write(dir / "crystal.yaml", scene);
  write(dir / "orientations.txt", "# subslip-orientations convention=bunge-euler-deg\n10 20 30\n");
  const Outcome r = run(dir,
                        "accuracy crystal.yaml -o acc --no-plot --repeat 1 --integrators "
                        "extrapolated_2 --extrapolated 1e-3 --reference-tolerance 1e-6 "
                        "--reference-order 2 --reference-at-run-times --cvode-check-seconds 1");
  ASSERT_EQ(r.code, 0) << r.err;
  expect_lines_fit_80(r.out);
  EXPECT_TRUE(contains(r.out, "  extrapolated_2        steps  max error      seg:t")) << r.out;
  const std::string csv = slurp(dir / "acc" / "accuracy.csv");
  const auto at = csv.find(" in segment ");
  ASSERT_NE(at, std::string::npos) << csv;
  const char segment = csv[at + std::string(" in segment ").size()];
  EXPECT_TRUE(contains(r.out, std::string(" ") + segment + ":")) << r.out;
  fs::remove_all(dir);
}
