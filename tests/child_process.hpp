// Running the subslip binary as a child process (fork + exec), killing it with SIGKILL at a
// chosen moment, and comparing result files dataset by dataset, for the crash-safety and
// restart tests.
#pragma once

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "subslip/io/h5_writer.hpp"

namespace subslip::testing {

namespace fs = std::filesystem;

// Starts `command...` (command[0] a path) in `dir` with stdout and stderr to `log`; returns its
// pid. `in_child` runs in the child before exec (resource limits, signal dispositions).
inline pid_t spawn_program(const fs::path& dir, std::vector<std::string> all, const fs::path& log,
                           const std::function<void()>& in_child = {}) {
  const pid_t pid = ::fork();
  if (pid != 0) return pid;
  if (in_child) in_child();
  if (::chdir(dir.c_str()) != 0) ::_exit(127);
  const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd >= 0) {
    ::dup2(fd, 1);
    ::dup2(fd, 2);
    ::close(fd);
  }
  std::vector<char*> argv;
  for (auto& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  ::execv(argv[0], argv.data());
  ::_exit(127);
}

// Starts `SUBSLIP_BINARY args...` (as spawn_program).
inline pid_t spawn_subslip(const fs::path& dir, const std::vector<std::string>& args,
                           const fs::path& log, const std::function<void()>& in_child = {}) {
  std::vector<std::string> all{SUBSLIP_BINARY};
  all.insert(all.end(), args.begin(), args.end());
  return spawn_program(dir, all, log, in_child);
}

// Waits for the child; its exit code, or 128 + signal.
inline int wait_child(pid_t pid) {
  int status = 0;
  if (::waitpid(pid, &status, 0) != pid) return -1;
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return -1;
}

// Runs to the end; the exit code and the wall time.
inline int run_subslip(const fs::path& dir, const std::vector<std::string>& args,
                       const fs::path& log, double* seconds = nullptr) {
  const auto start = std::chrono::steady_clock::now();
  const int code = wait_child(spawn_subslip(dir, args, log));
  if (seconds != nullptr)
    *seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return code;
}

// Polls (every millisecond) until the child ends or `done()` says stop; the child's exit code
// when it ended, else -1.
template <class Done>
int poll_child(pid_t pid, Done&& done) {
  while (!done()) {
    int status = 0;
    if (::waitpid(pid, &status, WNOHANG) == pid)
      return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  return -1;
}

// How long a run took, and when its result file appeared (the command line renames the file
// into place once its layout is complete: from then on a kill leaves a file to restart from).
struct RunTiming {
  double total = 0.0;
  double until_file = 0.0;
};

// Runs to the end; the exit code. `t`: the wall time and when `appears` came into existence.
inline int run_subslip_timed(const fs::path& dir, const std::vector<std::string>& args,
                             const fs::path& log, const fs::path& appears, RunTiming& t) {
  const auto start = std::chrono::steady_clock::now();
  auto since_start = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  const pid_t pid = spawn_subslip(dir, args, log);
  int code = poll_child(pid, [&] { return fs::exists(appears); });
  t.until_file = since_start();
  if (code < 0) code = wait_child(pid);
  t.total = since_start();
  return code;
}

// Sends `signal` (SIGKILL: 137 when killed) to the child `delay` seconds from now unless it
// ends before, then waits for it; its exit code.
inline int kill_after(pid_t pid, double delay, int signal = SIGKILL) {
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(delay);
  const int code = poll_child(pid, [&] { return std::chrono::steady_clock::now() >= until; });
  if (code >= 0) return code;
  ::kill(pid, signal);
  return wait_child(pid);
}

// Starts the command and SIGKILLs it after `delay` seconds (unless it ended before).
inline int run_and_kill(const fs::path& dir, const std::vector<std::string>& args,
                        const fs::path& log, double delay) {
  return kill_after(spawn_subslip(dir, args, log), delay);
}

// Starts the command and SIGKILLs it (or sends it `signal`) `delay` seconds after `appears`
// exists (unless it ended before).
inline int run_and_kill_after_file(const fs::path& dir, const std::vector<std::string>& args,
                                   const fs::path& log, const fs::path& appears, double delay,
                                   int signal = SIGKILL) {
  const pid_t pid = spawn_subslip(dir, args, log);
  const int code = poll_child(pid, [&] { return fs::exists(appears); });
  return code >= 0 ? code : kill_after(pid, delay, signal);
}

inline std::string read_text(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

// A seed for the kill moments: random, and printed so that a failure can be repeated
// (SUBSLIP_KILL_SEED=... overrides).
inline unsigned kill_seed() {
  if (const char* s = std::getenv("SUBSLIP_KILL_SEED")) return static_cast<unsigned>(std::stoul(s));
  return std::random_device{}();
}

// One dataset: its shape and its values as raw bytes of doubles (integers converted exactly).
struct DatasetValues {
  std::vector<std::size_t> shape;
  std::vector<double> values;
  bool integer = false;
};

// Every dataset under /cases (recursively), by path, except the checkpoint groups.
inline std::map<std::string, DatasetValues> case_datasets(const fs::path& file) {
  std::map<std::string, DatasetValues> out;
  const io::h5::File f = io::h5::File::open_read(file);
  std::function<void(const io::h5::Group&, const std::string&)> walk =
      [&](const io::h5::Group& g, const std::string& path) {
        for (const auto& name : g.members()) {
          if (name == "checkpoint") continue;
          const std::string p = path + "/" + name;
          if (g.is_group(name)) {
            walk(g.open_group(name), p);
            continue;
          }
          const io::h5::Dataset d = g.open_dataset(name);
          DatasetValues v;
          v.shape = d.shape();
          v.integer = d.value_class() == io::h5::ValueClass::integer;
          if (v.integer) {
            for (long long x : d.read_ints()) v.values.push_back(static_cast<double>(x));
          } else {
            v.values = d.read_doubles();
          }
          out[p] = std::move(v);
        }
      };
  walk(f.root().open_group("cases"), "/cases");
  return out;
}

// Bit for bit (NaN == NaN when the bits agree).
inline bool same_bits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

inline void expect_same_datasets(const fs::path& expected, const fs::path& actual) {
  const auto a = case_datasets(expected);
  const auto b = case_datasets(actual);
  ASSERT_FALSE(a.empty());
  ASSERT_EQ(a.size(), b.size());
  for (const auto& [name, x] : a) {
    SCOPED_TRACE(name);
    const auto it = b.find(name);
    ASSERT_NE(it, b.end());
    const DatasetValues& y = it->second;
    ASSERT_EQ(x.shape, y.shape);
    ASSERT_EQ(x.values.size(), y.values.size());
    std::size_t different = 0;
    for (std::size_t i = 0; i < x.values.size(); ++i)
      different += same_bits(x.values[i], y.values[i]) ? 0 : 1;
    EXPECT_EQ(different, 0u);
  }
}

}  // namespace subslip::testing
