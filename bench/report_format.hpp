// Number formats of the bench reports' Markdown tables.
#pragma once

#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

namespace subslip::bench {

// `v` through printf's format `f` ("%.3f").
inline std::string fmt(const char* f, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, v);
  return buf;
}

// Three significant digits in exponent form; "-" for NaN (not measured), "inf".
inline std::string sci(double v) {
  if (std::isnan(v)) return "-";
  if (v == std::numeric_limits<double>::infinity()) return "inf";
  return fmt("%.2e", v);
}

}  // namespace subslip::bench
