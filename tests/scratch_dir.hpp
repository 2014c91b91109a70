// Test helper: an empty directory of the running test's own, for the files it writes.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

namespace subslip::testing {

// Removes the scratch directories a test was handed once it has ended without failing; a failed
// test keeps them, for a look at what it wrote (its messages name the files). Registered with
// gtest's listeners on the first scratch_dir call, which own it from then on.
class ScratchCleaner : public ::testing::EmptyTestEventListener {
 public:
  static ScratchCleaner& instance() {
    static ScratchCleaner* const cleaner = [] {
      auto* c = new ScratchCleaner;
      ::testing::UnitTest::GetInstance()->listeners().Append(c);
      return c;
    }();
    return *cleaner;
  }
  void add(const std::filesystem::path& dir) { dirs_.push_back(dir); }
  void OnTestEnd(const ::testing::TestInfo& info) override {
    if (!info.result()->Failed()) {
      for (const auto& dir : dirs_) {
        std::error_code ignored;  // a directory the test removed itself is already gone
        std::filesystem::remove_all(dir, ignored);
      }
    }
    dirs_.clear();
  }

 private:
  std::vector<std::filesystem::path> dirs_;
};

// <temp>/subslip_<prefix>_<test name>_<pid>, emptied when it exists: `prefix` keeps the test
// files apart, the pid runs of the suite at the same time. Removed after the test unless it
// failed (ScratchCleaner).
inline std::filesystem::path scratch_dir(std::string_view prefix) {
  namespace fs = std::filesystem;
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir =
      fs::temp_directory_path() /
      ("subslip_" + std::string(prefix) + "_" + info->name() + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  ScratchCleaner::instance().add(dir);
  return dir;
}

}  // namespace subslip::testing
