// subslip post: summary of a result file, CSV export of chosen datasets, and one CSV table per
// case of chosen stored and derived quantities.
#pragma once

#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace subslip::cli {

struct PostArgs {
  std::string file;
  std::string csv_dir;  // empty: print the summary only
  std::string case_name;
  std::vector<std::string> datasets;
  std::vector<std::string> quantities;  // one table per case instead of a file per dataset
  long grain = -1;                      // < 0: every grain (long format)
  bool force = false;
  bool quiet = false;
};

void add_post_command(CLI::App& app, PostArgs& args);
int run_post(const PostArgs& args);

}  // namespace subslip::cli
