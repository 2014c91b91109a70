#include "subslip/io/run_size.hpp"

#include <sys/statvfs.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <system_error>

namespace subslip::io {

namespace {

// statvfs needs a path that exists: the output's directory may be created by the run.
std::filesystem::path existing_ancestor(const std::filesystem::path& output) {
  std::filesystem::path dir = std::filesystem::absolute(output).parent_path();
  std::error_code ec;
  while (!dir.empty() && !std::filesystem::exists(dir, ec) && dir != dir.root_path())
    dir = dir.parent_path();
  return dir;
}

double free_disk_bytes(const std::filesystem::path& output) {
  struct statvfs s {};
  // Cannot tell, or a pseudo file system (/proc: no blocks at all), where the output path
  // check gives the real reason.
  if (::statvfs(existing_ancestor(output).c_str(), &s) != 0 || s.f_blocks == 0) return INFINITY;
  return static_cast<double>(s.f_bavail) * static_cast<double>(s.f_frsize);
}

// MemAvailable of /proc/meminfo (what can be allocated without swapping); else free pages.
double available_memory_bytes() {
  std::ifstream in("/proc/meminfo");
  std::string key;
  double kib = 0.0;
  std::string unit;
  while (in >> key >> kib >> unit) {
    if (key == "MemAvailable:") return kib * 1024.0;
  }
  const long pages = ::sysconf(_SC_AVPHYS_PAGES), page = ::sysconf(_SC_PAGESIZE);
  if (pages > 0 && page > 0) return static_cast<double>(pages) * static_cast<double>(page);
  return INFINITY;
}

// The scene's line of `loading[segment].increments` (0 when the scene does not have it).
CheckedNode increments_node(const YamlDocument& scene, std::size_t segment) {
  const CheckedNode loading = scene.root().required("loading");
  const CheckedNode element = loading.element(segment);
  return element.is_map() && element.has("increments") ? element.required("increments") : element;
}

}  // namespace

std::string format_bytes(double bytes) {
  static const char* const kUnits[] = {"bytes", "kB", "MB", "GB", "TB", "PB", "EB"};
  int k = 0;
  while (bytes >= 1000.0 && k < 6) {
    bytes /= 1000.0;
    ++k;
  }
  char buf[32];
  std::snprintf(buf, sizeof buf, k == 0 ? "%.0f %s" : "%.3g %s", bytes, kUnits[k]);
  return buf;
}

Capacity capacity_for(const std::filesystem::path& output) {
  return {free_disk_bytes(output), available_memory_bytes()};
}

void check_run_fits(const YamlDocument& scene, const RunSize& size, const Capacity& capacity,
                    const std::filesystem::path& output) {
  if (size.result_bytes + size.finish_bytes > capacity.disk_bytes) {
    const std::string checkpoints =
        size.checkpoint_bytes > 0.0
            ? " (checkpoints " + format_bytes(size.checkpoint_bytes) + " of it)"
            : std::string();
    const std::string finish = size.finish_bytes > 0.0
                                   ? ", and up to " + format_bytes(size.finish_bytes) +
                                         " more while the finished file is written"
                                   : std::string();
    const std::string grains =
        size.grains > 0 ? ", fewer grains or fewer output.grains fields" : std::string();
    increments_node(scene, size.rows_segment)
        .fail("the result would take about " + format_bytes(size.result_bytes) + checkpoints +
              " (" + std::to_string(size.rows) + " output rows)" + finish + ", but " +
              output.string() + " is on a file system with " + format_bytes(capacity.disk_bytes) +
              " free; write fewer rows (output_every, fewer increments)" + grains);
  }
  if (size.memory_bytes > capacity.memory_bytes) {
    scene.root()
        .required("orientations")
        .fail("the run would need about " + format_bytes(size.memory_bytes) + " of memory (" +
              std::to_string(size.grains) + " grains), but " + format_bytes(capacity.memory_bytes) +
              " are available; use fewer grains");
  }
}

}  // namespace subslip::io
