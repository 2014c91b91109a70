// What every fuzz target asserts about a parse that succeeded: the parsers promise finite,
// in-range values (docs/scenes.md, docs/orientations.md), so a value that breaks one of these
// invariants is a finding just like a crash. A violation prints the invariant and aborts, which
// libFuzzer reports with the input that caused it.
#pragma once

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "subslip/crystal/rotation.hpp"

namespace subslip::fuzz {

[[noreturn]] inline void violated(const char* what, const char* file, int line) {
  std::fprintf(stderr, "fuzz invariant violated: %s (%s:%d)\n", what, file, line);
  std::abort();
}

}  // namespace subslip::fuzz

// Aborts with the condition's text unless it holds.
#define FUZZ_REQUIRE(condition) \
  ((condition) ? void(0) : ::subslip::fuzz::violated(#condition, __FILE__, __LINE__))

namespace subslip::fuzz {

template <class Matrix>
bool all_finite(const Matrix& m) {
  return m.allFinite();
}

// A parsed orientation: a finite unit quaternion with w >= 0, its rotation matrix, a finite
// positive weight.
inline void check_orientation(const crystal::Orientation& o) {
  const crystal::Quaternion& q = o.q;
  FUZZ_REQUIRE(std::isfinite(q.w) && std::isfinite(q.x) && std::isfinite(q.y) &&
               std::isfinite(q.z));
  FUZZ_REQUIRE(std::abs(q.norm() - 1.0) < 1e-12);
  FUZZ_REQUIRE(q.w >= 0.0);
  FUZZ_REQUIRE(all_finite(o.g));
  FUZZ_REQUIRE((o.g * o.g.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-12);
  FUZZ_REQUIRE(std::isfinite(o.weight) && o.weight > 0.0);
}

}  // namespace subslip::fuzz
