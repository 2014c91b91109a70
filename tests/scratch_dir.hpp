// Test helper: an empty directory of the running test's own, for the files it writes.
#pragma once

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <string>
#include <string_view>

namespace subslip::testing {

// <temp>/subslip_<prefix>_<test name>_<pid>, emptied when it exists: `prefix` keeps the test
// files apart, the pid runs of the suite at the same time.
inline std::filesystem::path scratch_dir(std::string_view prefix) {
  namespace fs = std::filesystem;
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const fs::path dir =
      fs::temp_directory_path() /
      ("subslip_" + std::string(prefix) + "_" + info->name() + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

}  // namespace subslip::testing
