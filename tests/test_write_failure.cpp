// Write failures of the result file. A file-size limit or a full disk ends `subslip
// run` with one line naming the output file, what was being written and the system's reason,
// exit status 1 (no crash, no HDF5 error stack unless --verbose); the rows written before stay
// readable, the file says it did not complete and can be continued with --restart; a file that
// holds nothing useful is removed.
//
// Fault injection: RLIMIT_FSIZE with SIGXFSZ ignored in the child (write() then fails with
// EFBIG, "File too large"), which works everywhere; and a small tmpfs (ENOSPC, "No space left
// on device") where the test may mount one, skipped where mounting is not permitted.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "child_process.hpp"
#include "scene_text.hpp"
#include "scratch_dir.hpp"
#include "small_tmpfs.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/result_protocol.hpp"

namespace fs = std::filesystem;
using namespace subslip;
using subslip::testing::read_text;

namespace {

// An adaptive contact slide: its series are laid out for the 3 rows of its 2 increments and
// grow (doubling) as the ~10^4 accepted steps come, so the file grows long after its layout
// (backward Euler's own estimate, `order: 1`, which resolves a segment given as one increment
// in many steps; the extrapolated default takes a few).
std::string adaptive_scene() {
  return subslip::testing::contact_scene_start("title: write failure\n") +
         "integrator: {method: implicit, tolerance: 1.0e-7, order: 1}\n"
         "loading:\n"
         "  - slide: {speed: 1.0, direction: [1, 0], distance: 1.0}\n"
         "    increments: 2\n";
}

struct Outcome {
  int code = -1;
  std::string log;
};

// `subslip run -q ...` in `dir` with files limited to `bytes` (0: no limit).
Outcome run_limited(const fs::path& dir, std::vector<std::string> args, rlim_t bytes) {
  args.insert(args.begin(), {"run", "-q"});
  const fs::path log = dir / "log.txt";
  const pid_t pid = subslip::testing::spawn_subslip(dir, args, log, [bytes] {
    if (bytes == 0) return;
    ::signal(SIGXFSZ, SIG_IGN);  // stays ignored across exec: write() fails with EFBIG instead
    const rlimit limit{bytes, bytes};
    ::setrlimit(RLIMIT_FSIZE, &limit);
  });
  Outcome r;
  r.code = subslip::testing::wait_child(pid);
  r.log = read_text(log);
  return r;
}

void write_file(const fs::path& p, const std::string& text) {
  std::ofstream(p) << text;
}

// Exit status 1 (not a signal), and the log is the one line
// "subslip: error: OUT: cannot ...: REASON; ..." without HDF5's error stack.
void expect_one_clear_message(const Outcome& r, const std::string& out, const std::string& reason) {
  EXPECT_EQ(r.code, 1) << r.log;
  EXPECT_EQ(r.log.rfind("subslip: error: " + out + ": cannot ", 0), 0u) << r.log;
  EXPECT_NE(r.log.find(reason), std::string::npos) << r.log;
  EXPECT_EQ(std::count(r.log.begin(), r.log.end(), '\n'), 1) << r.log;
  EXPECT_EQ(r.log.find("HDF5-DIAG"), std::string::npos) << r.log;
}

// The file a failed run kept: marked incomplete with the reason, and its valid rows (as
// /progress counts them) are the finite start of the time series.
void expect_readable_incomplete(const fs::path& file, const std::string& reason) {
  const io::h5::File f = io::h5::File::open_read(file);
  const io::h5::Group root = f.root();
  EXPECT_EQ(root.attribute_int("completed"), 0);
  EXPECT_NE(root.attribute_string("write_error").find(reason), std::string::npos);
  const auto progress = io::h5::CaseProgress::open(root);
  ASSERT_EQ(progress.size(), 1u);
  EXPECT_EQ(progress.state(0), io::h5::CaseState::running);
  const auto rows = static_cast<std::size_t>(progress.rows(0));
  // At least the initial state; how many more were counted before the failure depends on the
  // write pacer, which commits by time (WritePacer), so on the machine's load.
  ASSERT_GE(rows, 1u);
  const io::h5::Group c = root.open_group("cases").open_group("base");
  const auto time = c.open_dataset("time").read_doubles();
  ASSERT_GE(time.size(), rows);
  for (std::size_t i = 0; i < rows; ++i) ASSERT_TRUE(std::isfinite(time[i])) << "row " << i;
  for (std::size_t i = 1; i < rows; ++i) ASSERT_GT(time[i], time[i - 1]) << "row " << i;
}

// The size of the unlimited run's result: the growth failures below come at half of it.
std::uintmax_t full_size(const fs::path& dir) {
  const Outcome r = run_limited(dir, {"scene.yaml", "-o", "full.h5"}, 0);
  EXPECT_EQ(r.code, 0) << r.log;
  return fs::file_size(dir / "full.h5");
}

}  // namespace

// A limit below the layout: the partial file is removed, nothing is left behind.
TEST(WriteFailure, FileSizeLimitDuringLayoutRemovesThePartialFile) {
  const fs::path dir = subslip::testing::scratch_dir("write_failure");
  write_file(dir / "scene.yaml", adaptive_scene());
  const Outcome r = run_limited(dir, {"scene.yaml", "-o", "out.h5"}, 16 * 1024);
  expect_one_clear_message(r, "out.h5", "File too large");
  EXPECT_NE(r.log.find("was removed"), std::string::npos) << r.log;
  EXPECT_FALSE(fs::exists(dir / "out.h5"));
  EXPECT_FALSE(fs::exists(dir / "out.h5.partial"));
  fs::remove_all(dir);
}

// A limit reached while an adaptive run grows its series: the rows written stay readable, the
// file says why it stopped, and --restart (without the limit) finishes the same result as an
// uninterrupted run.
TEST(WriteFailure, FileSizeLimitWhileGrowingKeepsRowsAndRestarts) {
  const fs::path dir = subslip::testing::scratch_dir("write_failure");
  write_file(dir / "scene.yaml", adaptive_scene());
  const std::uintmax_t full = full_size(dir);
  const Outcome r = run_limited(dir, {"scene.yaml", "-o", "out.h5"}, full / 2);
  expect_one_clear_message(r, "out.h5", "File too large");
  EXPECT_NE(r.log.find("--restart out.h5"), std::string::npos) << r.log;
  EXPECT_FALSE(fs::exists(dir / "out.h5.partial"));
  expect_readable_incomplete(dir / "out.h5", "File too large");
  // `subslip post` shows why the run stopped.
  const pid_t post = subslip::testing::spawn_subslip(dir, {"post", "out.h5"}, dir / "post.txt");
  ASSERT_EQ(subslip::testing::wait_child(post), 0);
  const std::string summary = read_text(dir / "post.txt");
  EXPECT_NE(summary.find("write error: the run stopped: out.h5: cannot grow dataset /cases/base/"),
            std::string::npos)
      << summary;
  const Outcome again = run_limited(dir, {"--restart", "out.h5"}, 0);
  ASSERT_EQ(again.code, 0) << again.log;
  subslip::testing::expect_same_datasets(dir / "full.h5", dir / "out.h5");
  EXPECT_EQ(io::h5::File::open_read(dir / "out.h5").root().attribute_string("write_error"), "");
  fs::remove_all(dir);
}

// --verbose adds HDF5's error stack to the message (for a bug report).
TEST(WriteFailure, VerbosePrintsHdf5Stack) {
  const fs::path dir = subslip::testing::scratch_dir("write_failure");
  write_file(dir / "scene.yaml", adaptive_scene());
  const Outcome r = run_limited(dir, {"scene.yaml", "-o", "out.h5", "--verbose"}, 16 * 1024);
  EXPECT_EQ(r.code, 1) << r.log;
  EXPECT_NE(r.log.find("HDF5-DIAG"), std::string::npos) << r.log;
  EXPECT_NE(r.log.find("subslip: error: out.h5: cannot "), std::string::npos) << r.log;
  fs::remove_all(dir);
}

namespace {}  // namespace

// A full disk (ENOSPC) while the series grow: as with the file-size limit.
TEST(WriteFailure, FullTmpfsWhileGrowingKeepsRows) {
  const fs::path dir = subslip::testing::scratch_dir("write_failure");
  write_file(dir / "scene.yaml", adaptive_scene());
  const std::uintmax_t full = full_size(dir);
  {
    const subslip::testing::SmallTmpfs disk(dir / "disk", full / 2);
    if (!disk.mounted()) GTEST_SKIP() << "cannot mount a tmpfs here: " << disk.why();
    const Outcome r = run_limited(dir, {"scene.yaml", "-o", "disk/out.h5"}, 0);
    expect_one_clear_message(r, "disk/out.h5", "No space left on device");
    expect_readable_incomplete(dir / "disk/out.h5", "No space left on device");
  }
  fs::remove_all(dir);
}

// A disk too small for the layout (about 55 kB), though large enough for the size check's
// estimate (about 32 kB, and 16 kB for the finished file): nothing is left on it.
TEST(WriteFailure, FullTmpfsDuringLayoutLeavesNothing) {
  const fs::path dir = subslip::testing::scratch_dir("write_failure");
  write_file(dir / "scene.yaml", adaptive_scene());
  {
    const subslip::testing::SmallTmpfs disk(dir / "disk", 48 * 1024);
    if (!disk.mounted()) GTEST_SKIP() << "cannot mount a tmpfs here: " << disk.why();
    const Outcome r = run_limited(dir, {"scene.yaml", "-o", "disk/out.h5"}, 0);
    expect_one_clear_message(r, "disk/out.h5", "No space left on device");
    EXPECT_TRUE(fs::is_empty(dir / "disk"));
  }
  fs::remove_all(dir);
}

// A UTF-16 scene (with a byte-order mark, as Windows editors save one) is stored in /scene as
// UTF-8, so that a run stopped part-way continues with --restart, the scene named again or not.
TEST(WriteFailure, Utf16SceneRunStoppedPartWayRestarts) {
  const fs::path dir = subslip::testing::scratch_dir("write_failure");
  std::string utf8 = adaptive_scene();
  const std::string title = "title: write failure\n";
  utf8.replace(utf8.find(title), title.size(), "title: \"r\xC3\xA9sum\xC3\xA9\"\n");
  std::string utf16 = "\xFF\xFE";  // the scene is ASCII but for the two 2-byte characters
  for (std::size_t i = 0; i < utf8.size(); ++i) {
    const auto c = static_cast<unsigned char>(utf8[i]);
    const unsigned unit =
        c < 0x80 ? c : ((c & 0x1Fu) << 6) | (static_cast<unsigned char>(utf8[++i]) & 0x3Fu);
    utf16 += std::string{static_cast<char>(unit & 0xFF), static_cast<char>(unit >> 8)};
  }
  write_file(dir / "scene.yaml", utf8);
  const std::uintmax_t full = full_size(dir);
  write_file(dir / "scene16.yaml", utf16);
  const Outcome r = run_limited(dir, {"scene16.yaml", "-o", "out.h5"}, full / 2);
  EXPECT_EQ(r.code, 1) << r.log;
  {
    const io::h5::File f = io::h5::File::open_read(dir / "out.h5");
    EXPECT_EQ(f.root().open_dataset("scene").read_string(), utf8);
    EXPECT_EQ(f.root().attribute_string("title"), "r\xC3\xA9sum\xC3\xA9");
  }
  const Outcome again = run_limited(dir, {"--restart", "out.h5", "scene16.yaml"}, 0);
  ASSERT_EQ(again.code, 0) << again.log;
  subslip::testing::expect_same_datasets(dir / "full.h5", dir / "out.h5");
  fs::remove_all(dir);
}
