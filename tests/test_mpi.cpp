// `mpirun -np N subslip run`: a crystal case's grains shared among MPI ranks give the serial
// run's result file bit for bit (every dataset), for 1, 2 and 4 ranks (4 oversubscribed on two
// cores); a run killed (SIGKILL to the job) or stopped by a signal under 2 ranks continues
// under 1 (or, written through rank 0 first, under 2 writing together) and equals the
// uninterrupted run; a grain that fails on rank 1 stops every rank with one
// message naming it; a sweep's cases (crystal or contact) distributed over ranks give the serial
// sweep; the finished file the ranks make together is the serial finish of the same working
// file; a write failing on one rank (inside the collective writes of the run, or of the finish)
// ends every rank with one message. Built only with MPI; these tests run alone
// (tests/CMakeLists.txt).
#ifdef SUBSLIP_MPIEXEC

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "child_process.hpp"
#include "scene_text.hpp"
#include "scratch_dir.hpp"
#include "small_tmpfs.hpp"
#include "subslip/io/h5_writer.hpp"
#include "subslip/io/result_file.hpp"
#include "subslip/io/result_protocol.hpp"

namespace {

namespace fs = std::filesystem;
namespace h5 = subslip::io::h5;
fs::path scratch_dir() {
  return subslip::testing::scratch_dir("mpi");
}

// Uniaxial tension under mixed control (free lateral stresses), then reversed into compression;
// 37 grains, so that the ranks' blocks differ in size; every per-grain field, checkpoints.
std::string reversal_scene(int increments, int checkpoint_every = 3) {
  const std::string n = std::to_string(increments);
  return subslip::testing::copper_scene_start("title: \"mixed-control tension, reversed\"\n") +
         R"(
orientations: {random: {count: 37, seed: 5}}
loading:
  - L: [[x, 0, 0], [0, x, 0], [0, 0, 1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 10
    increments: )" +
         n + R"(
  - L: [[x, 0, 0], [0, x, 0], [0, 0, -1.0e-3]]
    stress: [[0, x, x], [x, 0, x], [x, x, x]]
    duration: 20
    increments: )" +
         n + R"(
integrator: {method: implicit, residual_tolerance: 1.0e-12, stress_tolerance: 1.0e-10}
output:
  macro: [time, L, F, strain, stress, segment]
  grains: [stress, orientation, slip, slip_rate, crss, r, r_s]
  checkpoint_every: )" +
         std::to_string(checkpoint_every) + "\n";
}

// Command line of `subslip args...` under the launcher with `ranks` ranks (root may run it).
std::vector<std::string> under_mpi(int ranks, const std::vector<std::string>& args) {
  std::vector<std::string> all{SUBSLIP_MPIEXEC, "-n", std::to_string(ranks), "--oversubscribe",
                               SUBSLIP_BINARY};
  all.insert(all.end(), args.begin(), args.end());
  return all;
}

// Every rank gets the environment of the launcher (one machine): root may run Open MPI, and one
// thread per rank keeps 4 ranks on two cores reasonable.
void launcher_environment() {
  ::setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
  ::setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
  ::setenv("OMP_NUM_THREADS", "1", 1);
  // Open MPI's own allocations at exit are not subslip's leaks.
  ::setenv("ASAN_OPTIONS", "detect_leaks=0", 1);
  // Open MPI's MPI-IO (OMPIO) allocates a 32 MB aggregation buffer for every collective write and
  // clears it. glibc's malloc hands the freed buffer back at the next write, already mapped;
  // AddressSanitizer's maps every allocation that large afresh, so each write faulted 8192 pages
  // in: 4 ranks on 2 cores took 40-55 s for the adaptive scene below instead of 1.5 s (Release),
  // most of it in the kernel. Every write of these tests (one row of one dataset, at most 48 kB)
  // fits 1 MB in one aggregation cycle, as it fits 32 MB; the transfer and the file are the same.
  ::setenv("OMPI_MCA_io_ompio_bytes_per_agg", "1048576", 1);
}

int run_mpi(const fs::path& dir, int ranks, const std::vector<std::string>& args) {
  return subslip::testing::wait_child(subslip::testing::spawn_program(
      dir, under_mpi(ranks, args), dir / "mpi.log", launcher_environment));
}

std::string log_of(const fs::path& dir) {
  return subslip::testing::read_text(dir / "mpi.log");
}

// `gathered`: also rank 0 writing what the others send it (--gather-output), under two ranks.
void expect_ranks_give_the_serial_run(const fs::path& dir, const std::string& scene,
                                      const std::vector<int>& rank_counts = {1, 2, 4},
                                      bool gathered = true) {
  ASSERT_EQ(subslip::testing::run_subslip(dir, {"run", scene, "-o", "serial.h5", "-q"},
                                          dir / "serial.log"),
            0)
      << subslip::testing::read_text(dir / "serial.log");
  for (int ranks : rank_counts) {
    SCOPED_TRACE(std::to_string(ranks) + " ranks");
    const std::string out = "ranks" + std::to_string(ranks) + ".h5";
    ASSERT_EQ(run_mpi(dir, ranks, {"run", scene, "-o", out, "-q"}), 0) << log_of(dir);
    EXPECT_EQ(h5::File::open_read(dir / out).root().attribute_int("completed"), 1);
    subslip::testing::expect_same_datasets(dir / "serial.h5", dir / out);
  }
  if (!gathered) return;
  // Rank 0 writing what the others send it (file systems without MPI-IO) gives the same file.
  ASSERT_EQ(run_mpi(dir, 2, {"run", scene, "-o", "gathered.h5", "-q", "--gather-output"}), 0)
      << log_of(dir);
  subslip::testing::expect_same_datasets(dir / "serial.h5", dir / "gathered.h5");
}

}  // namespace

// Two ranks: the default scene's 1000 grains in blocks of 500. One rank, ranks beyond the cores
// (oversubscribed, 4) and the output gathered through rank 0 are run on the smaller scenes below,
// whose 37 grains also split unevenly: under the sanitizers each run of the default scene takes
// about 40 s (MPI tests run alone, so each adds its time to the suite's), and four ranks on two
// cores spend most of their time polling (the adaptive scene: 74 s, 111 s of it in the kernel,
// against 4 s for two ranks).
TEST(Mpi, DefaultSceneUnderTwoRanksIsTheSerialRun) {
  const fs::path dir = scratch_dir();
  expect_ranks_give_the_serial_run(dir, fs::path(SUBSLIP_SOURCE_DIR) / "inputs/default.yaml", {2},
                                   /*gathered=*/false);
  fs::remove_all(dir);
}

TEST(Mpi, MixedControlReversalAtAnyRankCountIsTheSerialRun) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "reversal.yaml") << reversal_scene(30);
  expect_ranks_give_the_serial_run(dir, "reversal.yaml");
  fs::remove_all(dir);
}

// The reversal scene with adaptive steps: planned for the rows of 8 increments, it writes 74 at
// the tolerance 1e-2, 625 at 1e-4 (backward Euler's own estimate, `order: 1`: many short steps,
// which is what these tests need, not accuracy).
std::string adaptive_reversal_scene(const std::string& tolerance) {
  std::string scene = reversal_scene(4);
  const std::string fixed = "integrator: {method: implicit,";
  scene.replace(scene.find(fixed), fixed.size(),
                "integrator: {method: implicit, order: 1, tolerance: " + tolerance + ",");
  return scene;
}

// An adaptive run writes more rows than it planned for, so every series grows while the ranks
// write the file together: each growth is collective (space claimed by rank 0 for all, the
// extent set by all), at 2, 3 and 4 ranks alike (3 and 4 hung or failed before the space was
// claimed through rank 0), and the file is the serial one.
TEST(Mpi, AdaptiveRunGrowingItsSeriesAtAnyRankCountIsTheSerialRun) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "adaptive.yaml") << adaptive_reversal_scene("1.0e-2");
  expect_ranks_give_the_serial_run(dir, "adaptive.yaml");
  ASSERT_EQ(run_mpi(dir, 3, {"run", "adaptive.yaml", "-o", "ranks3.h5", "-q"}), 0) << log_of(dir);
  subslip::testing::expect_same_datasets(dir / "serial.h5", dir / "ranks3.h5");
  // Over four times the rows of the 8 increments planned: the series grew more than once (each
  // growth doubles it).
  const h5::File serial = h5::File::open_read(dir / "serial.h5");
  EXPECT_GT(serial.root().open_dataset("cases/base/macro/time").shape().front(), 4u * 9u);
  fs::remove_all(dir);
}

// A full disk while the ranks grow the series together: every rank stops with the one message
// naming the reason, the rows written stay readable, and the run continues (--restart, on a disk
// with room, under another rank count) to the serial run's file.
TEST(Mpi, FullDiskWhileRanksGrowTheFileStopsCleanlyAndRestarts) {
  const fs::path dir = scratch_dir();
  // (625 rows: a file large enough that half of it passes the size check before the run; its
  // series stored plain, so that the finished file's size is what the run writes)
  std::ofstream(dir / "adaptive.yaml")
      << adaptive_reversal_scene("1.0e-4") << "  compression: none\n";
  ASSERT_EQ(subslip::testing::run_subslip(dir, {"run", "adaptive.yaml", "-o", "serial.h5", "-q"},
                                          dir / "serial.log"),
            0)
      << subslip::testing::read_text(dir / "serial.log");
  {
    const subslip::testing::SmallTmpfs disk(dir / "disk", fs::file_size(dir / "serial.h5") / 2);
    if (!disk.mounted()) GTEST_SKIP() << "cannot mount a tmpfs here: " << disk.why();
    ASSERT_EQ(run_mpi(dir, 2, {"run", "adaptive.yaml", "-o", "disk/out.h5", "-q"}), 1)
        << log_of(dir);
    const std::string log = log_of(dir);
    EXPECT_EQ(log.rfind("subslip: error: disk/out.h5: cannot grow dataset", 0), 0u) << log;
    EXPECT_NE(log.find("No space left on device"), std::string::npos) << log;
    EXPECT_EQ(log.find("HDF5-DIAG"), std::string::npos) << log;
    fs::copy_file(dir / "disk/out.h5", dir / "continued.h5");
  }
  EXPECT_EQ(h5::File::open_read(dir / "continued.h5").root().attribute_int("completed"), 0);
  ASSERT_EQ(run_mpi(dir, 1, {"run", "adaptive.yaml", "--restart", "continued.h5", "-q"}), 0)
      << log_of(dir);
  subslip::testing::expect_same_datasets(dir / "serial.h5", dir / "continued.h5");
  fs::remove_all(dir);
}

// The reversal scene with its orientations given by `orientations` (a flow mapping).
std::string reversal_scene_with(const std::string& orientations, int increments) {
  std::string scene = reversal_scene(increments);
  const std::string random = "{random: {count: 37, seed: 5}}";
  scene.replace(scene.find(random), random.size(), orientations);
  return scene;
}

// Where the ranks write the file together, every rank reads its range of an orientation file's
// lines and keeps its block of the orientations: the result is the serial run's, also where
// some ranks hold no grain (3 grains on 4 ranks).
TEST(Mpi, OrientationFileReadByBlocksGivesTheSerialRun) {
  const fs::path dir = scratch_dir();
  const std::string shipped = std::string(SUBSLIP_SOURCE_DIR) + "/orientations/random_100.txt";
  std::ofstream(dir / "file.yaml") << reversal_scene_with("{file: \"" + shipped + "\"}", 10);
  expect_ranks_give_the_serial_run(dir, "file.yaml");
  const fs::path three = dir / "three";
  fs::create_directory(three);
  std::ofstream(three / "three.txt") << "# subslip-orientations convention=bunge-euler-deg\n"
                                        "10 20 30 2\n40 50 60 1\n70 80 90 0.5\n";
  std::ofstream(three / "three.yaml") << reversal_scene_with("{file: three.txt}", 10);
  expect_ranks_give_the_serial_run(three, "three.yaml");
  fs::remove_all(dir);
}

// A file another tool wrote (a DAMASK table: comments, labels, a text column) is read by blocks
// through the same reader: the serial run's result, and a bad line reported as in a serial run.
TEST(Mpi, OrientationTableOfAnotherToolReadByBlocksGivesTheSerialRun) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "table.txt") << "# written by damask.Table.save\n"
                                      "1_O 2_O 3_O 4_O phase\n"
                                      "1.0 0.0 0.0 0.0 Copper\n"
                                      "0.5 0.5 0.5 0.5 Copper\n"
                                      "0.7071067811865476 0.0 0.7071067811865476 0.0 Copper\n";
  std::ofstream(dir / "table.yaml") << reversal_scene_with("{file: table.txt, format: damask}", 10);
  expect_ranks_give_the_serial_run(dir, "table.yaml", {2}, false);
  std::ofstream(dir / "bad.txt") << "1_O 2_O 3_O 4_O\n1 0 0 0\n1 zero 0 0\n";
  std::ofstream(dir / "bad.yaml") << reversal_scene_with("{file: bad.txt, format: damask}", 10);
  EXPECT_NE(run_mpi(dir, 2, {"run", "bad.yaml", "-o", "p.h5", "-q"}), 0);
  const std::string log = log_of(dir);
  const auto first = log.find("bad.txt:3: 2_O: 'zero' is not a number");
  ASSERT_NE(first, std::string::npos) << log;
  EXPECT_EQ(log.find("bad.txt:3: 2_O:", first + 1), std::string::npos) << log;
  fs::remove_all(dir);
}

// A problem in an orientation file read by rank 0 for every rank is reported once, as a
// serial run reports it, with the same exit status.
TEST(Mpi, BadOrientationFileIsReportedOnceAsInASerialRun) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "bad.txt") << "# subslip-orientations convention=bunge-euler-deg\n"
                                    "10 20 30\n40 200 60\n";
  std::ofstream(dir / "bad.yaml") << reversal_scene_with("{file: bad.txt}", 10);
  const int serial = subslip::testing::run_subslip(dir, {"run", "bad.yaml", "-o", "s.h5", "-q"},
                                                   dir / "serial.log");
  std::string message = subslip::testing::read_text(dir / "serial.log");
  ASSERT_NE(serial, 0);
  ASSERT_NE(message.find("bad.txt:3: Phi:"), std::string::npos) << message;
  message = message.substr(0, message.find('\n'));
  EXPECT_EQ(run_mpi(dir, 2, {"run", "bad.yaml", "-o", "p.h5", "-q"}), serial) << log_of(dir);
  const std::string log = log_of(dir);
  const auto first = log.find(message);
  ASSERT_NE(first, std::string::npos) << log;
  EXPECT_EQ(log.find(message, first + 1), std::string::npos) << log;
  EXPECT_FALSE(fs::exists(dir / "p.h5"));
  fs::remove_all(dir);
}

// Every rank reads its range of an orientation file's lines: a bad line in the block of rank 1
// (of 2; of rank 2 of 3) is reported once, with the serial read's message (file, line, key) and
// exit status; with a bad line in rank 0's block too, the one the serial read reports, the first.
TEST(Mpi, BadLineInTheBlockOfRankOneIsReportedAsTheSerialReadReportsIt) {
  const fs::path dir = scratch_dir();
  for (const std::vector<int>& bad_lines : {std::vector<int>{36}, std::vector<int>{5, 36}}) {
    std::ofstream file(dir / "bad.txt");
    file << "# subslip-orientations convention=bunge-euler-deg\n";
    for (int line = 2; line <= 41; ++line) {
      const bool bad = std::find(bad_lines.begin(), bad_lines.end(), line) != bad_lines.end();
      file << (bad ? "10 200 30\n" : "10 20 30\n");
    }
    file.close();
    std::ofstream(dir / "bad.yaml") << reversal_scene_with("{file: bad.txt}", 10);
    const int serial = subslip::testing::run_subslip(dir, {"run", "bad.yaml", "-o", "s.h5", "-q"},
                                                     dir / "serial.log");
    std::string message = subslip::testing::read_text(dir / "serial.log");
    ASSERT_NE(serial, 0);
    const std::string where = "bad.txt:" + std::to_string(bad_lines.front()) + ": Phi:";
    ASSERT_NE(message.find(where), std::string::npos) << message;
    message = message.substr(0, message.find('\n'));
    for (int ranks : {2, 3}) {
      SCOPED_TRACE(std::to_string(ranks) + " ranks, bad line " + std::to_string(bad_lines.front()));
      EXPECT_EQ(run_mpi(dir, ranks, {"run", "bad.yaml", "-o", "p.h5", "-q"}), serial)
          << log_of(dir);
      const std::string log = log_of(dir);
      const auto first = log.find(message);
      ASSERT_NE(first, std::string::npos) << log;
      EXPECT_EQ(log.find(message, first + 1), std::string::npos) << log;
      EXPECT_EQ(log.find("bad.txt:36", first + message.size()), std::string::npos) << log;
      EXPECT_FALSE(fs::exists(dir / "p.h5"));
    }
  }
  fs::remove_all(dir);
}

// With parallel HDF5 the ranks sharing a case's grains write them into the file together, and
// the run says so; --gather-output (and a serial HDF5) has rank 0 write them.
TEST(Mpi, RanksSharingGrainsWriteTogetherWithParallelHdf5) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "reversal.yaml") << reversal_scene(5);
  ASSERT_EQ(run_mpi(dir, 2, {"run", "reversal.yaml", "-o", "together.h5"}), 0) << log_of(dir);
  const bool together =
      log_of(dir).find("every rank writes its grains (parallel HDF5") != std::string::npos;
  EXPECT_EQ(together, h5::parallel_hdf5()) << log_of(dir);
  ASSERT_EQ(run_mpi(dir, 2, {"run", "reversal.yaml", "-o", "gathered.h5", "--gather-output"}), 0)
      << log_of(dir);
  EXPECT_NE(log_of(dir).find("rank 0 writes the grains gathered from every rank"),
            std::string::npos)
      << log_of(dir);
  fs::remove_all(dir);
}

// The processes descended from `root` (from /proc: each process's parent).
std::vector<pid_t> descendants(pid_t root) {
  std::map<pid_t, std::vector<pid_t>> children;
  for (const auto& entry : fs::directory_iterator("/proc")) {
    const std::string name = entry.path().filename();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream stat(entry.path() / "stat");
    std::string line;
    if (!std::getline(stat, line)) continue;
    // pid (comm) state ppid ...: comm may hold spaces, so read after its closing parenthesis.
    std::istringstream rest(line.substr(line.rfind(')') + 1));
    char state = 0;
    pid_t parent = 0;
    rest >> state >> parent;
    children[parent].push_back(static_cast<pid_t>(std::stol(name)));
  }
  std::vector<pid_t> found, todo{root};
  while (!todo.empty()) {
    const pid_t p = todo.back();
    todo.pop_back();
    for (pid_t c : children[p]) {
      found.push_back(c);
      todo.push_back(c);
    }
  }
  return found;
}

// Whether process `pid` has let go of its files: no thread of it has a descriptor left open. A
// killed process's main thread turns zombie (and its /proc/<pid>/fd reads empty) while its other
// threads still share the open descriptor table, the HDF5 file's lock among them; so every
// thread's table is looked at, and a process that is gone has let go.
bool let_go(pid_t pid) {
  std::error_code error;
  fs::directory_iterator threads(fs::path("/proc") / std::to_string(pid) / "task", error);
  if (error) return true;
  // (a thread may end while it is listed: each step takes an error code instead of throwing)
  for (; !error && threads != fs::directory_iterator(); threads.increment(error)) {
    std::error_code unreadable;
    fs::directory_iterator fds(threads->path() / "fd", unreadable);
    if (!unreadable && fds != fs::directory_iterator()) return false;
  }
  return true;
}

// Whether no process holds an flock on `file` (the lock HDF5 takes on a file it opens).
bool lock_is_free(const fs::path& file) {
  const int fd = ::open(file.c_str(), O_RDONLY);
  if (fd < 0) return true;
  const bool free = ::flock(fd, LOCK_EX | LOCK_NB) == 0;
  ::close(fd);  // (closing releases the lock just taken)
  return free;
}

// The reversal scene run serially (ref.h5), then under 2 ranks (out.h5) until `interrupt`
// (given the launcher and a random delay, from the moment out.h5 is in place) ends it; an
// interrupted run must have exited with `interrupted_code` and is continued under
// `restart_ranks` ranks (--restart). Every dataset must equal the serial run's. `check`: what
// else an interrupted run must show. (The continuations stay within the two cores: under the
// sanitizers three ranks on two cores poll, and one such continuation took 37 to 61 s of CI
// against a few seconds; ranks beyond the cores are tested on the short runs above.)
void interrupt_and_continue(const fs::path& dir, int restart_ranks, int checkpoint_every,
                            int interrupted_code,
                            const std::function<int(pid_t, double)>& interrupt,
                            const std::function<void()>& check = {},
                            const std::vector<std::string>& first_options = {},
                            const std::vector<std::string>& restart_options = {}) {
  std::ofstream(dir / "reversal.yaml") << reversal_scene(150, checkpoint_every);
  double serial = 0.0;
  ASSERT_EQ(subslip::testing::run_subslip(dir, {"run", "reversal.yaml", "-o", "ref.h5", "-q"},
                                          dir / "ref.log", &serial),
            0);
  const unsigned seed = subslip::testing::kill_seed();
  SCOPED_TRACE("SUBSLIP_KILL_SEED=" + std::to_string(seed));
  std::mt19937 rng(seed);
  // (2 ranks take about half the serial time)
  std::uniform_real_distribution<double> when(0.1 * serial, 0.4 * serial);
  std::vector<std::string> first{"run", "reversal.yaml", "-o", "out.h5", "-q"};
  first.insert(first.end(), first_options.begin(), first_options.end());
  const pid_t launcher = subslip::testing::spawn_program(dir, under_mpi(2, first), dir / "mpi.log",
                                                         launcher_environment);
  int code = subslip::testing::poll_child(launcher, [&] { return fs::exists(dir / "out.h5"); });
  if (code < 0) code = interrupt(launcher, when(rng));
  ASSERT_TRUE(code == interrupted_code || code == 0) << log_of(dir);
  // An interrupt that comes after the run has finished its file (while the ranks finalise MPI
  // and exit) interrupts nothing: the file is complete, as when the run ends first. The launcher
  // still reports the signal (measured: SIGUSR1 with SUBSLIP_KILL_SEED=1394856856 under load left
  // a completed file and exit code 128 + SIGUSR1), so the file, not the code, tells.
  const bool finished_first =
      code == 0 || h5::File::open_read(dir / "out.h5").root().attribute_int("completed") == 1;
  if (!finished_first) {
    EXPECT_EQ(h5::File::open_read(dir / "out.h5").root().attribute_int("completed"), 0);
    if (check) check();
    std::vector<std::string> again{"run", "--restart", "out.h5", "-q"};
    again.insert(again.end(), restart_options.begin(), restart_options.end());
    ASSERT_EQ(run_mpi(dir, restart_ranks, again), 0) << log_of(dir);
  } else {
    GTEST_LOG_(INFO) << "the run finished its file before it was interrupted";
  }
  EXPECT_EQ(h5::File::open_read(dir / "out.h5").root().attribute_int("completed"), 1);
  subslip::testing::expect_same_datasets(dir / "ref.h5", dir / "out.h5");
}

// A batch scheduler's hard kill: SIGKILL to every process of the job (the launcher and the
// ranks it started, which Open MPI puts in process groups of their own) at a random moment;
// --restart under 1 rank continues from the last periodic checkpoint (every 3 increments) to
// the uninterrupted serial run's file.
TEST(Mpi, RunKilledUnderTwoRanksContinuesUnderOne) {
  const fs::path dir = scratch_dir();
  interrupt_and_continue(dir, 1, 3, 128 + SIGKILL, [&dir](pid_t launcher, double delay) {
    const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(delay);
    const int code = subslip::testing::poll_child(
        launcher, [&] { return std::chrono::steady_clock::now() >= until; });
    if (code >= 0) return code;
    const std::vector<pid_t> ranks = descendants(launcher);
    for (pid_t p : ranks) ::kill(p, SIGKILL);
    ::kill(launcher, SIGKILL);
    const int killed = subslip::testing::wait_child(launcher);
    // Until the ranks have let go of the file, and its lock (HDF5's flock) is released too: an
    // exiting process closes its descriptors before the kernel puts the last reference down.
    for (pid_t p : ranks)
      while (!let_go(p)) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    while (!lock_is_free(dir / "out.h5")) std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return killed;
  });
  fs::remove_all(dir);
}

// A sweep of five cases: under 2 and 4 ranks each rank runs whole cases (rank r: r, r + N, ...)
// and the root writes them in case order; the file equals the serial sweep's.
TEST(Mpi, SweepOverRanksIsTheSerialSweep) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "sweep.yaml") << reversal_scene(10) + R"(sweep:
  "phase.tau0": [10, 12, 14, 16, 18]
)";
  expect_ranks_give_the_serial_run(dir, "sweep.yaml");
  fs::remove_all(dir);
}

// A contact sweep of seven cases: each rank computes its share of every round, the root writes
// them in case order; the file equals the serial sweep's.
TEST(Mpi, ContactSweepOverRanksIsTheSerialSweep) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "contact.yaml") << subslip::testing::contact_scene_start() + R"(loading:
  - slide: {speed: 1, direction: [1, 0], distance: 2.0}
    increments: 400
sweep:
  "loading[0].slide.speed": [1, 2, 5, 10, 20, 50, 100]
)";
  expect_ranks_give_the_serial_run(dir, "contact.yaml");
  fs::remove_all(dir);
}

// SIGUSR1 to the launcher (which passes it on to every rank; a batch scheduler's SIGTERM goes to
// every rank itself) at a random moment: every rank stops after the same increment with a
// checkpoint there (the scene's own are too rare to come); --restart under another rank count
// continues from it, and every dataset equals the uninterrupted serial run.
TEST(Mpi, RunStoppedUnderTwoRanksContinuesUnderOne) {
  const fs::path dir = scratch_dir();
  interrupt_and_continue(
      dir, 1, 100000, 128 + SIGUSR1,
      [](pid_t launcher, double delay) {
        return subslip::testing::kill_after(launcher, delay, SIGUSR1);
      },
      [&] {
        const std::string log = log_of(dir);
        EXPECT_NE(log.find("subslip: stopped by SIGUSR1: case 'base' stopped after"),
                  std::string::npos)
            << log;
      });
  fs::remove_all(dir);
}

// SIGUSR1 the moment the result file exists (the root has just laid it out; the other ranks may
// be behind): every rank has its handler by then (run_crystal installs them on all ranks before
// the root creates the file), so the run stops cleanly after its first increment and continues
// under 1 rank, as above.
TEST(Mpi, RunStoppedAsSoonAsItsFileExistsContinuesUnderOne) {
  const fs::path dir = scratch_dir();
  interrupt_and_continue(dir, 1, 100000, 128 + SIGUSR1, [](pid_t launcher, double) {
    return subslip::testing::kill_after(launcher, 0.0, SIGUSR1);
  });
  fs::remove_all(dir);
}

// The two ways of writing the file over ranks make the same file, checkpoints included: a run
// stopped under 2 ranks whose output went through rank 0 (--gather-output) continues under 2
// ranks writing together, to the serial run's file.
TEST(Mpi, RunStoppedWritingThroughRankZeroContinuesWritingTogether) {
  const fs::path dir = scratch_dir();
  interrupt_and_continue(dir, 2, 100000, 128 + SIGUSR1,
                         [](pid_t launcher, double delay) {
                           return subslip::testing::kill_after(launcher, delay, SIGUSR1);
                         },
                         {}, {"--gather-output"}, {});
  fs::remove_all(dir);
}

// Two cube grains (rank 0 of 2) and two [111] grains (rank 1) in one forward-Euler step with no
// cutbacks: the [111] grains are loaded twice as hard and leave the admissible range. Every
// rank stops; the message (one, from the root) names the first failing grain, 2, as the serial
// run does; the file is left incomplete with the failure stored.
TEST(Mpi, FailingGrainOnRankOneStopsEveryRankWithItsMessage) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "fails.yaml") << subslip::testing::copper_scene_start() + R"(orientations:
  euler_deg: [[0, 0, 0], [0, 0, 0], [0, 54.7356, 45], [0, 54.7356, 45]]
loading:
  - L: [[-0.5e-3, 0, 0], [0, -0.5e-3, 0], [0, 0, 1.0e-3]]
    duration: 0.7
    increments: 1
integrator: {method: forward_euler, max_cutbacks: 0}
)";
  const int serial = subslip::testing::run_subslip(dir, {"run", "fails.yaml", "-o", "serial.h5"},
                                                   dir / "serial.log");
  const std::string serial_log = subslip::testing::read_text(dir / "serial.log");
  ASSERT_EQ(serial, 3) << serial_log;
  ASSERT_NE(serial_log.find("grain 2,"), std::string::npos) << serial_log;
  EXPECT_EQ(run_mpi(dir, 2, {"run", "fails.yaml", "-o", "ranks.h5"}), 3) << log_of(dir);
  const std::string log = log_of(dir);
  const std::size_t at = serial_log.find("subslip: error:");
  const std::string error = serial_log.substr(at, serial_log.find('\n', at) - at);
  EXPECT_NE(log.find(error), std::string::npos) << log;
  EXPECT_EQ(log.find(error), log.rfind("subslip: error:")) << "one message: " << log;
  const h5::File file = h5::File::open_read(dir / "ranks.h5");
  EXPECT_EQ(file.root().attribute_int("completed"), 0);
  EXPECT_NE(h5::failure_message(file.root().open_group("cases/base")), "");
  fs::remove_all(dir);
}

// Every attribute of `a` and `b` (objects at `where`) the same: names in order, values bit for
// bit (numbers) or equal (strings).
void expect_same_attributes(const h5::Object& a, const h5::Object& b, const std::string& where) {
  SCOPED_TRACE(where);
  ASSERT_EQ(a.attribute_names(), b.attribute_names());
  for (const std::string& name : a.attribute_names()) {
    SCOPED_TRACE(name);
    ASSERT_EQ(a.attribute_class(name), b.attribute_class(name));
    if (a.attribute_class(name) == h5::ValueClass::string) {
      EXPECT_EQ(a.attribute_strings(name), b.attribute_strings(name));
      continue;
    }
    const auto x = a.attribute_doubles(name), y = b.attribute_doubles(name);
    ASSERT_EQ(x.size(), y.size());
    for (std::size_t i = 0; i < x.size(); ++i)
      EXPECT_TRUE(subslip::testing::same_bits(x[i], y[i])) << x[i] << " " << y[i];
  }
}

// The same groups and attributes everywhere, and the same storage (chunks, filters) of every
// dataset; its values are expect_same_datasets'.
void expect_same_structure(const h5::Group& a, const h5::Group& b, const std::string& path) {
  expect_same_attributes(a, b, path);
  ASSERT_EQ(a.members(), b.members()) << path;
  for (const std::string& name : a.members()) {
    const std::string child = path + "/" + name;
    if (a.is_group(name)) {
      expect_same_structure(a.open_group(name), b.open_group(name), child);
      continue;
    }
    const h5::Dataset x = a.open_dataset(name), y = b.open_dataset(name);
    expect_same_attributes(x, y, child);
    EXPECT_EQ(x.shape(), y.shape()) << child;
    EXPECT_EQ(x.chunk_shape(), y.chunk_shape()) << child;
    EXPECT_EQ(x.filters(), y.filters()) << child;
  }
}

// A working file whose cases have all ended is finished by the ranks together (each copies its
// block of every per-grain dataset) into the file the serial finish makes of it: the same
// groups, attributes, datasets, storage and values, compressed and not. 16000 grains, so that a
// per-grain row (1.2 MB of stresses) is cut into chunks along the grains, one of them across
// the blocks of two ranks; three ranks split them unevenly.
TEST(Mpi, FinishedTogetherIsTheSerialFinishOfTheSameFile) {
  for (const std::string compression : {"gzip", "none"}) {
    SCOPED_TRACE(compression);
    const fs::path dir = scratch_dir();
    std::ofstream(dir / "many.yaml") << subslip::testing::copper_scene_start() + R"(
orientations: {random: {count: 16000, seed: 3}}
loading:
  - L: [[-0.5e-3, 0, 0], [0, -0.5e-3, 0], [0, 0, 1.0e-3]]
    duration: 2
    increments: 3
output:
  grains: [stress, slip]
  compression: )" + compression + "\n";
    // (A directory where the finished file goes: the run ends with its working file, every
    // case ended, as after a full disk at the finish.)
    fs::create_directory(dir / "work.h5.finishing");
    ASSERT_EQ(subslip::testing::run_subslip(dir, {"run", "many.yaml", "-o", "work.h5", "-q"},
                                            dir / "work.log"),
              1)
        << subslip::testing::read_text(dir / "work.log");
    fs::remove(dir / "work.h5.finishing");
    ASSERT_EQ(h5::File::open_read(dir / "work.h5").root().attribute_int("finished"), 0);
    for (const std::string name : {"serial.h5", "ranks2.h5", "ranks3.h5"})
      fs::copy_file(dir / "work.h5", dir / name);
    ASSERT_EQ(subslip::testing::run_subslip(dir, {"run", "--restart", "serial.h5", "-q"},
                                            dir / "serial.log"),
              0)
        << subslip::testing::read_text(dir / "serial.log");
    const h5::File serial = h5::File::open_read(dir / "serial.h5");
    EXPECT_EQ(serial.root().attribute_int("finished"), 1);
    for (int ranks : {2, 3}) {
      SCOPED_TRACE(std::to_string(ranks) + " ranks");
      const std::string out = "ranks" + std::to_string(ranks) + ".h5";
      ASSERT_EQ(run_mpi(dir, ranks, {"run", "--restart", out, "-q"}), 0) << log_of(dir);
      EXPECT_FALSE(fs::exists(dir / (out + ".finishing")));
      subslip::testing::expect_same_datasets(dir / "serial.h5", dir / out);
      expect_same_structure(serial.root(), h5::File::open_read(dir / out).root(), "");
    }
    fs::remove_all(dir);
  }
}

// `subslip args...` under the launcher with `ranks` ranks, rank `limited` with files limited to
// `bytes` (RLIMIT_FSIZE, SIGXFSZ ignored: a write past it fails with EFBIG, "File too large"),
// the others without a limit; each rank writes its part of the collective writes itself (two
// aggregators: with one, rank 0 would write for both). Its exit code, or -1 when the job had
// not ended after `seconds` (then killed, every process of it).
int run_mpi_limited(const fs::path& dir, int ranks, int limited, std::uintmax_t bytes,
                    const std::vector<std::string>& args, double seconds) {
  std::vector<std::string> all{
      SUBSLIP_MPIEXEC,
      "-n",
      std::to_string(ranks),
      "--oversubscribe",
      "/bin/sh",
      "-c",
      "trap '' XFSZ; if [ \"$OMPI_COMM_WORLD_RANK\" = " + std::to_string(limited) +
          " ]; then exec prlimit --fsize=" + std::to_string(bytes) +
          " \"$0\" \"$@\"; fi; exec \"$0\" \"$@\"",
      SUBSLIP_BINARY};
  all.insert(all.end(), args.begin(), args.end());
  const pid_t launcher = subslip::testing::spawn_program(dir, all, dir / "mpi.log", [] {
    launcher_environment();
    ::setenv("OMPI_MCA_io_ompio_num_aggregators", "2", 1);
    // (no shared-memory transport: its segment file is sized with ftruncate, which the limit
    // refuses before the run begins)
    ::setenv("OMPI_MCA_btl", "self,tcp", 1);
  });
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  const int code = subslip::testing::poll_child(
      launcher, [&] { return std::chrono::steady_clock::now() >= until; });
  if (code >= 0) return code;
  for (pid_t p : descendants(launcher)) ::kill(p, SIGKILL);
  ::kill(launcher, SIGKILL);
  subslip::testing::wait_child(launcher);
  return -1;
}

// The one line a failed write ends a run with, from the root: "subslip: error: OUT: cannot
// ...", without HDF5's error stack. (The system's reason is not in it: HDF5's MPI-IO driver
// says "can't write data"; Open MPI's MPI-IO prints the reason itself on some failures.)
void expect_one_message(const std::string& log, const std::string& out) {
  EXPECT_NE(log.find("subslip: error: " + out + ": cannot "), std::string::npos) << log;
  EXPECT_EQ(log.find("subslip: error:"), log.rfind("subslip: error:")) << "one message: " << log;
  EXPECT_EQ(log.find("HDF5-DIAG"), std::string::npos) << log;
}

// A write that fails on rank 1 alone, inside the collective writes of the run (its file-size
// limit within the last series' rows): every rank ends within a bounded time (exit 1, not a
// hang), with one message from the root; the rows written stay, and the run continues under
// one rank to the serial run's file.
TEST(Mpi, WriteFailingOnOneRankStopsEveryRankWithOneMessage) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "reversal.yaml") << reversal_scene(40) << "  compression: none\n";
  ASSERT_EQ(subslip::testing::run_subslip(dir, {"run", "reversal.yaml", "-o", "serial.h5", "-q"},
                                          dir / "serial.log"),
            0);
  // (the working file is at least the finished one: its rows are reserved at the layout, each
  // series' after the last's, so that a limit below the last series' first row would stop the
  // run at its first output step, which leaves no file)
  const std::uintmax_t limit = fs::file_size(dir / "serial.h5") * 97 / 100;
  ASSERT_EQ(run_mpi_limited(dir, 2, 1, limit, {"run", "reversal.yaml", "-o", "out.h5", "-q"}, 120),
            1)
      << log_of(dir);
  expect_one_message(log_of(dir), "out.h5");
  EXPECT_EQ(h5::File::open_read(dir / "out.h5").root().attribute_int("completed"), 0);
  ASSERT_EQ(run_mpi(dir, 1, {"run", "--restart", "out.h5", "-q"}), 0) << log_of(dir);
  subslip::testing::expect_same_datasets(dir / "serial.h5", dir / "out.h5");
  fs::remove_all(dir);
}

// The same while the ranks write the finished file together (a working file whose cases have
// all ended, continued under two ranks, rank 1 limited): every rank stops with the root's one
// message, the temporary file is gone, the working file keeps every row, and a later --restart
// finishes it to the serial run's file.
TEST(Mpi, WriteFailingOnOneRankWhileFinishingTogetherLeavesTheWorkingFile) {
  const fs::path dir = scratch_dir();
  std::ofstream(dir / "reversal.yaml") << reversal_scene(40) << "  compression: none\n";
  ASSERT_EQ(subslip::testing::run_subslip(dir, {"run", "reversal.yaml", "-o", "serial.h5", "-q"},
                                          dir / "serial.log"),
            0);
  fs::create_directory(dir / "out.h5.finishing");  // (the serial finish fails: a directory)
  ASSERT_EQ(subslip::testing::run_subslip(dir, {"run", "reversal.yaml", "-o", "out.h5", "-q"},
                                          dir / "work.log"),
            1);
  fs::remove(dir / "out.h5.finishing");
  ASSERT_EQ(run_mpi_limited(dir, 2, 1, fs::file_size(dir / "serial.h5") / 2,
                            {"run", "--restart", "out.h5", "-q"}, 120),
            1)
      << log_of(dir);
  expect_one_message(log_of(dir), "out.h5");
  EXPECT_NE(log_of(dir).find("cannot write the finished file"), std::string::npos) << log_of(dir);
  EXPECT_FALSE(fs::exists(dir / "out.h5.finishing"));
  EXPECT_EQ(h5::File::open_read(dir / "out.h5").root().attribute_int("finished"), 0);
  ASSERT_EQ(run_mpi(dir, 2, {"run", "--restart", "out.h5", "-q"}), 0) << log_of(dir);
  EXPECT_EQ(h5::File::open_read(dir / "out.h5").root().attribute_int("finished"), 1);
  subslip::testing::expect_same_datasets(dir / "serial.h5", dir / "out.h5");
  fs::remove_all(dir);
}

#endif  // SUBSLIP_MPIEXEC
