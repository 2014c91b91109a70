#include "post.hpp"

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>

#include "subslip/io/result_post.hpp"

namespace subslip::cli {

namespace {

std::string derived_list() {
  std::string out;
  for (const auto& [path, what] : io::post::derived_quantities())
    out += (out.empty() ? "" : ", ") + path;
  return out;
}

void report(const std::vector<std::filesystem::path>& written, const std::string& dir) {
  for (const auto& p : written) std::printf("%s\n", p.c_str());
  std::fprintf(stderr, "subslip: wrote %zu CSV file%s to %s\n", written.size(),
               written.size() == 1 ? "" : "s", dir.c_str());
}

}  // namespace

void add_post_command(CLI::App& app, PostArgs& a) {
  CLI::App* cmd =
      app.add_subcommand("post", "Summarise a result file (HDF5) or export chosen datasets to CSV");
  cmd->add_option("file", a.file, "Result file written by subslip run")->required();
  auto* csv = cmd->add_option("--csv", a.csv_dir,
                              "Write CSV files (one per case and dataset) into this directory "
                              "instead of printing the summary");
  cmd->add_option("--case", a.case_name, "Only this case (default: every case)");
  auto* dataset =
      cmd->add_option("--dataset", a.datasets,
                      "Dataset or group, relative to the case (macro/stress, ratio, grains) or "
                      "absolute (/cases/base/macro/stress); repeatable; default: every dataset")
          ->needs(csv);
  cmd->add_option("--quantity", a.quantities,
                  "Write one CSV per case, <case>.csv, with a column (or one per component) "
                  "for each quantity, in order: a time series of the case (macro/strain, "
                  "ratio) or a derived one (" +
                      derived_list() + "); repeatable")
      ->needs(csv)
      ->excludes(dataset);
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
  const std::optional<std::size_t> grain =
      a.grain >= 0 ? std::optional<std::size_t>(static_cast<std::size_t>(a.grain)) : std::nullopt;
  if (!a.quantities.empty()) {
    const auto written =
        io::post::export_table(a.file, {a.csv_dir, a.case_name, a.quantities, grain, a.force});
    if (!a.quiet) report(written, a.csv_dir);
    return 0;
  }
  io::post::CsvOptions options;
  options.directory = a.csv_dir;
  options.case_name = a.case_name;
  options.datasets = a.datasets;
  options.grain = grain;
  options.force = a.force;
  const auto written = io::post::export_csv(a.file, options);
  if (!a.quiet) report(written, a.csv_dir);
  return 0;
}

}  // namespace subslip::cli
