#include "post.hpp"

#include <cstdio>
#include <iostream>

#include "subslip/io/result_post.hpp"

namespace subslip::cli {

void add_post_command(CLI::App& app, PostArgs& a) {
  CLI::App* cmd =
      app.add_subcommand("post", "Summarise a result file (HDF5) or export chosen datasets to CSV");
  cmd->add_option("file", a.file, "Result file written by subslip run")->required();
  auto* csv = cmd->add_option("--csv", a.csv_dir,
                              "Write CSV files (one per case and dataset) into this directory "
                              "instead of printing the summary");
  cmd->add_option("--case", a.case_name, "Only this case (default: every case)");
  cmd->add_option("--dataset", a.datasets,
                  "Dataset or group, relative to the case (macro/stress, ratio, grains) or "
                  "absolute (/cases/base/macro/stress); repeatable; default: every dataset")
      ->needs(csv);
  cmd->add_option("--grain", a.grain,
                  "Per-grain series [n, G, k]: only grain G (0-based), one row per step; "
                  "default: every grain, one row per step and grain")
      ->check(CLI::NonNegativeNumber)
      ->needs(csv);
  cmd->add_flag("-f,--force", a.force, "Overwrite existing CSV files")->needs(csv);
  cmd->add_flag("-q,--quiet", a.quiet, "Do not list the CSV files written");
}

int run_post(const PostArgs& a) {
  if (a.csv_dir.empty()) {
    io::post::print_summary(std::cout, a.file, a.case_name);
    return 0;
  }
  io::post::CsvOptions options;
  options.directory = a.csv_dir;
  options.case_name = a.case_name;
  options.datasets = a.datasets;
  if (a.grain >= 0) options.grain = static_cast<std::size_t>(a.grain);
  options.force = a.force;
  const auto written = io::post::export_csv(a.file, options);
  if (!a.quiet) {
    for (const auto& p : written) std::printf("%s\n", p.c_str());
    std::fprintf(stderr, "subslip: wrote %zu CSV file%s to %s\n", written.size(),
                 written.size() == 1 ? "" : "s", a.csv_dir.c_str());
  }
  return 0;
}

}  // namespace subslip::cli
