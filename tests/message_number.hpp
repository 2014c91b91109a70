// Test helper: the number a message prints after a key ("at time 1.5", "mu = 0.097"), for the
// tests of failure messages. (std::strtod, not <regex>: GCC 12's regex headers warn under -O2.)
#pragma once

#include <gtest/gtest.h>

#include <cstdlib>
#include <limits>
#include <string>

namespace subslip::testing {

// The number right after the first occurrence of `key` that is followed by one; NaN (and a test
// failure) when there is none.
inline double number_after(const std::string& message, const std::string& key) {
  for (std::size_t at = message.find(key); at != std::string::npos;
       at = message.find(key, at + 1)) {
    const char* start = message.c_str() + at + key.size();
    char* end = nullptr;
    const double value = std::strtod(start, &end);
    if (end != start) return value;
  }
  ADD_FAILURE() << "'" << key << "' followed by a number missing in: " << message;
  return std::numeric_limits<double>::quiet_NaN();
}

}  // namespace subslip::testing
