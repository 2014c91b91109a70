// What the work-precision study's parts (work_precision.cpp: the study and its ladders;
// work_precision_problems.cpp: the contact and crystal problems; work_precision_errors.cpp:
// interpolation and errors) share. Internal to src/study/.
#pragma once

#include <chrono>

namespace subslip::study::work_precision_detail {

using Clock = std::chrono::steady_clock;

inline double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace subslip::study::work_precision_detail
