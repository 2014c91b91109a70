// The subslip executable: run, output-path safety, error lines and exit codes.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "scene_text.hpp"
#include "scratch_dir.hpp"
#include "shell_command.hpp"
#include "subslip/io/h5_writer.hpp"

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
