#include "subslip/io/restart.hpp"

#include <system_error>

#include "subslip/io/h5_writer.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/result_file.hpp"
#include "subslip/io/result_protocol.hpp"

namespace subslip::io {

namespace {

[[noreturn]] void refuse(const std::filesystem::path& file, const std::string& key,
                         const std::string& why) {
  throw InputError(file.string(), 0, key, "cannot restart: " + why);
}

std::string string_attribute(const h5::Group& root, const std::filesystem::path& file,
                             const char* name) {
  if (!root.has_attribute(name))
    refuse(file, name, "not a subslip result file (no root attribute '" + std::string(name) + "')");
  return root.attribute_string(name);
}

// For a finished file: what to do with its restart file, when one was left beside it.
std::string left_over_checkpoints(const std::filesystem::path& file) {
  if (restart_file_role(file) != RestartFileRole::left_over) return "";
  return "; " + restart_file_for(file).string() +
         " beside it holds that run's last checkpoints, which no run continues: delete it";
}

}  // namespace

RestartInfo inspect_for_restart(const std::filesystem::path& file,
                                const std::optional<std::string>& scene_text) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) refuse(file, "", "no such file");
  std::optional<h5::File> h5file;
  try {
    h5file.emplace(h5::File::open_read(file));
  } catch (const h5::Error& e) {
    refuse(file, "", std::string("not a readable HDF5 file (") + e.what() + ")");
  }
  const h5::Group root = h5file->root();
  if (!root.has_attribute("format") || root.attribute_string("format") != "subslip")
    refuse(file, "format", "not a subslip result file");
  const long long version = root.attribute_int("format_version");
  if (version != h5::kFormatVersion) {
    refuse(file, "format_version",
           "format version " + std::to_string(version) + ", this program writes " +
               std::to_string(h5::kFormatVersion));
  }
  const std::string program = string_attribute(root, file, "program_version");
  if (program != SUBSLIP_VERSION) {
    refuse(file, "program_version",
           "written by subslip " + program + ", this is " + SUBSLIP_VERSION +
               "; a continued run would not be identical to an uninterrupted one");
  }
  if (root.attribute_int("completed") == 1)
    refuse(file, "completed", "the run completed" + left_over_checkpoints(file));
  if (root.has_attribute("finished") && root.attribute_int("finished") == 1) {
    refuse(file, "finished",
           "the run finished (every case completed or failed)" + left_over_checkpoints(file));
  }
  if (!root.has_attribute("layout_complete") || root.attribute_int("layout_complete") != 1) {
    refuse(file, "layout_complete",
           "the run stopped before its result layout was written, so the file holds no result; "
           "run the scene again (--force to replace the file)");
  }
  if (!root.has("progress") || !root.has("cases") || !root.has("scene"))
    refuse(file, "progress", "the file has no /progress, /cases or /scene (it was never started)");
  RestartInfo info;
  if (root.has_attribute("build")) info.build = root.attribute_string("build");
  if (root.has_attribute("simd_kernels")) info.simd_kernels = root.attribute_string("simd_kernels");
  info.scene_kind = string_attribute(root, file, "scene_kind");
  info.scene_file = string_attribute(root, file, "scene_file");
  info.scene_text = root.open_dataset("scene").read_string();
  info.makeup = h5::read_scene_makeup(root);
  info.case_names = root.open_group("cases").attribute_strings("names");
  const h5::CaseProgress progress = h5::CaseProgress::open(root);
  if (progress.size() != info.case_names.size())
    refuse(file, "progress", "/progress does not list every case of /cases");
  // (Every case ended: the run stopped while it wrote its finished file; a restart finishes it.)
  if (scene_text && *scene_text != info.scene_text) {
    refuse(file, "scene",
           "the scene file given differs from the scene the run started with (/scene); restart "
           "without naming a scene, or start a new run");
  }
  info.restart_file = restart_file_for(file);
  std::error_code exists_error;
  if (std::filesystem::exists(info.restart_file, exists_error)) {
    std::string run_id;
    if (!is_restart_file(info.restart_file, &run_id)) {
      throw InputError(info.restart_file.string(), 0, "",
                       "cannot restart " + file.string() +
                           ": this is where its checkpoints go, but it is not a subslip restart "
                           "file; move it away");
    }
    if (!root.has_attribute("run_id") || run_id != root.attribute_string("run_id")) {
      throw InputError(info.restart_file.string(), 0, "run_id",
                       "cannot restart " + file.string() +
                           ": the restart file belongs to another run; remove it to run the "
                           "interrupted case again from its start");
    }
  }
  return info;
}

void check_restart_cases(const std::filesystem::path& file, const RestartInfo& info,
                         const std::vector<std::string>& scene_case_names) {
  if (scene_case_names != info.case_names) {
    refuse(file, "cases",
           "the scene in /scene no longer gives the cases the run started with (files it reads "
           "changed?)");
  }
}

std::string restart_rounding_warning(const std::filesystem::path& file, const RestartInfo& info,
                                     const std::string& build, const std::string& simd_kernels) {
  const bool other_build = !info.build.empty() && info.build != build;
  const bool other_kernels = !info.simd_kernels.empty() && info.simd_kernels != simd_kernels;
  if (!other_build && !other_kernels) return "";
  const auto described = [](const std::string& b, const std::string& k) {
    return "build " + b + (k.empty() ? "" : ", SIMD kernels " + k);
  };
  return file.string() + " was begun with " + described(info.build, info.simd_kernels) +
         "; this run continues with " +
         described(build, info.simd_kernels.empty() ? "" : simd_kernels) +
         ", which round differently: the result agrees with an uninterrupted run to the "
         "solvers' tolerances, not bit for bit";
}

}  // namespace subslip::io
