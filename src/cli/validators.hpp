// Range checks of command-line values with readable bounds. CLI11's PositiveNumber and
// NonNegativeNumber print theirs as "Value 0 not in range 0.000000 to 1797693...(309 digits)";
// these say "must be > 0, got 0".
#pragma once

#include <CLI/CLI.hpp>

#include <cstdio>
#include <string>

namespace subslip::cli {

namespace detail {

inline std::string number(double x) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.15g", x);
  return buf;
}

// A validator of numbers: `ok(x)` must hold; else "must be <description>, got <input>".
template <class Ok>
CLI::Validator number_check(const std::string& description, Ok ok) {
  return CLI::Validator(
      [description, ok](std::string& input) -> std::string {
        double x = 0.0;
        if (!CLI::detail::lexical_cast(input, x)) return "'" + input + "' is not a number";
        return ok(x) ? std::string() : "must be " + description + ", got " + input;
      },
      description);
}

}  // namespace detail

inline CLI::Validator positive() {
  return detail::number_check("> 0", [](double x) { return x > 0.0; });
}

inline CLI::Validator non_negative() {
  return detail::number_check(">= 0", [](double x) { return x >= 0.0; });
}

// lo < x <= hi (tolerances: above zero, at most 1).
inline CLI::Validator above_and_at_most(double lo, double hi) {
  return detail::number_check("in (" + detail::number(lo) + ", " + detail::number(hi) + "]",
                              [lo, hi](double x) { return x > lo && x <= hi; });
}

// lo <= x <= hi.
inline CLI::Validator between(double lo, double hi) {
  return detail::number_check("in [" + detail::number(lo) + ", " + detail::number(hi) + "]",
                              [lo, hi](double x) { return x >= lo && x <= hi; });
}

}  // namespace subslip::cli
