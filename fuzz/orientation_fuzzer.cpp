// libFuzzer target: the orientation-file reader on arbitrary bytes, in every layout it reads
// (subslip's header, a headerless Euler list, MTEX and DAMASK tables): each input is read in each.
//
// Expected outcome of a bad file: one subslip::InputError. Any other exception, a crash or
// sanitizer report, or an accepted orientation that is not a finite unit quaternion with a
// finite positive weight (fuzz_checks.hpp) is a finding.
//
// Build and run: docs/internals.md, "Sanitizers and fuzzing".
#include <cstddef>
#include <cstdint>
#include <sstream>
#include <string>

#include "fuzz_checks.hpp"
#include "subslip/io/input_error.hpp"
#include "subslip/io/orientation_file.hpp"

namespace {

subslip::io::OrientationFileLayout layout(subslip::io::OrientationFileKind kind,
                                          subslip::io::AngleUnit angles, const char* column) {
  subslip::io::OrientationFileLayout l;
  l.kind = kind;
  l.angles = angles;
  l.column = column;
  return l;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace subslip;
  using io::AngleUnit;
  using io::OrientationFileKind;
  const std::string text(reinterpret_cast<const char*>(data), size);
  const io::OrientationFileLayout layouts[] = {
      {},
      layout(OrientationFileKind::euler, AngleUnit::degrees, "O"),
      layout(OrientationFileKind::euler, AngleUnit::radians, "O"),
      layout(OrientationFileKind::mtex, AngleUnit::degrees, "O"),
      layout(OrientationFileKind::damask, AngleUnit::radians, "O"),
      layout(OrientationFileKind::damask, AngleUnit::degrees, "eu"),
  };
  for (const auto& l : layouts) {
    std::istringstream in(text);
    try {
      const auto orientations = io::read_orientations(in, "fuzz.txt", nullptr, l);
      FUZZ_REQUIRE(!orientations.empty());
      for (const auto& o : orientations) fuzz::check_orientation(o);
    } catch (const InputError&) {
      // The expected outcome of a bad file.
    }
  }
  return 0;
}
