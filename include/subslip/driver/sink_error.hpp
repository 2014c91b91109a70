// A sink that could not store what the driver handed it (a full disk, a file-size limit): what
// was being written and why it failed, so that the command line can say so and the drivers can
// pass it on between ranks as what it is (driver/team_crystal_sink.hpp). The HDF5 result files'
// error (io::h5::Error) is one.
#pragma once

#include <stdexcept>
#include <string>
#include <utility>

namespace subslip::driver {

struct SinkWriteError : std::runtime_error {
  // `what`: the whole message; `what_failed`: what was attempted and on which object; `why`:
  // the reason (the operating system's when there is one; may be empty).
  SinkWriteError(const std::string& what, std::string what_failed, std::string why)
      : std::runtime_error(what), action(std::move(what_failed)), reason(std::move(why)) {}
  std::string action;
  std::string reason;
};

}  // namespace subslip::driver
