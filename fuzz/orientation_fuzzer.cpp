// libFuzzer target: the orientation-file reader on arbitrary bytes.
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

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace subslip;
  std::istringstream in(std::string(reinterpret_cast<const char*>(data), size));
  try {
    const auto orientations = io::read_orientations(in, "fuzz.txt");
    FUZZ_REQUIRE(!orientations.empty());
    for (const auto& o : orientations) fuzz::check_orientation(o);
  } catch (const InputError&) {
    // The expected outcome of a bad file.
  }
  return 0;
}
