#include "subslip/model/units.hpp"

#include <array>
#include <cmath>
#include <cstdlib>
#include <sstream>
#include <stdexcept>
#include <string>

namespace subslip::model {

namespace {

struct BaseUnit {
  std::string_view name;  // as written
  std::string_view canonical;
  Dimension dimension;
  Scale scale;
};

// The micro sign (U+00B5) and the Greek small letter mu (U+03BC) in UTF-8: both are written
// for micrometres; the canonical name is "um" (ASCII, as result files store it).
constexpr std::string_view kMicroSign = "\xC2\xB5m";
constexpr std::string_view kGreekMu = "\xCE\xBCm";

constexpr std::array<BaseUnit, 15> kBaseUnits = {{
    {"Pa", "Pa", dimension::stress, {0, 0}},
    {"kPa", "kPa", dimension::stress, {3, 0}},
    {"MPa", "MPa", dimension::stress, {6, 0}},
    {"GPa", "GPa", dimension::stress, {9, 0}},
    {"m", "m", dimension::length, {0, 0}},
    {"cm", "cm", dimension::length, {-2, 0}},
    {"mm", "mm", dimension::length, {-3, 0}},
    {"um", "um", dimension::length, {-6, 0}},
    {kMicroSign, "um", dimension::length, {-6, 0}},
    {kGreekMu, "um", dimension::length, {-6, 0}},
    {"nm", "nm", dimension::length, {-9, 0}},
    {"s", "s", dimension::time, {0, 0}},
    {"ms", "ms", dimension::time, {-3, 0}},
    {"min", "min", dimension::time, {0, 1}},
    {"h", "h", dimension::time, {0, 2}},
}};

std::vector<std::string_view> names_of(Dimension d) {
  std::vector<std::string_view> out;
  for (const auto& u : kBaseUnits)
    if (u.dimension == d) out.push_back(u.name);
  return out;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

// The ASCII names of the base units of one kind (no alternative spellings of um).
std::vector<std::string_view> ascii_names_of(Dimension d) {
  std::vector<std::string_view> out;
  for (const auto& u : kBaseUnits)
    if (u.dimension == d && u.name == u.canonical) out.push_back(u.name);
  return out;
}

// The base dimension with exponent `sign` (+1 or -1) in `d`, when exactly one base has it and
// the others are 0 or have the other sign: the shapes a / b, a, 1 / b.
std::optional<Dimension> single_base(Dimension d, int sign) {
  std::optional<Dimension> found;
  const std::array<std::pair<int, Dimension>, 3> bases = {
      {{d.stress, dimension::stress}, {d.length, dimension::length}, {d.time, dimension::time}}};
  for (const auto& [exponent, base] : bases) {
    if (exponent == 0 || exponent == -sign) continue;
    if (exponent != sign || found) return std::nullopt;
    found = base;
  }
  return found;
}

// 2^a 3^b 5^c with a, b, c >= 0, exact while 3^b 5^c < 2^53 (every ratio of scene units).
double power_product(int twos, int threes, int fives) {
  double x = 1.0;
  for (int k = 0; k < threes; ++k) x *= 3.0;
  for (int k = 0; k < fives; ++k) x *= 5.0;
  return std::ldexp(x, twos);
}

}  // namespace

std::string describe(Dimension d) {
  // (A stream rather than string concatenation: GCC 12 reports a false -Wstringop-overflow on
  // the short appends this needs.)
  std::ostringstream num, den;
  const std::array<std::pair<int, const char*>, 3> bases = {
      {{d.stress, "stress"}, {d.length, "length"}, {d.time, "time"}}};
  for (const auto& [exponent, name] : bases) {
    if (exponent == 0) continue;
    std::ostringstream& side = exponent > 0 ? num : den;
    if (side.tellp() > 0) side << '*';
    side << name;
    if (std::abs(exponent) != 1) side << '^' << std::abs(exponent);
  }
  if (num.tellp() == 0) num << '1';
  if (den.tellp() > 0) num << '/' << den.str();
  return num.str();
}

const std::vector<std::string_view>& stress_unit_names() {
  static const std::vector<std::string_view> names = names_of(dimension::stress);
  return names;
}
const std::vector<std::string_view>& length_unit_names() {
  static const std::vector<std::string_view> names = names_of(dimension::length);
  return names;
}
const std::vector<std::string_view>& time_unit_names() {
  static const std::vector<std::string_view> names = names_of(dimension::time);
  return names;
}

std::optional<Unit> base_unit(std::string_view name) {
  for (const auto& u : kBaseUnits) {
    if (u.name == name) return Unit{u.dimension, u.scale, std::string(u.canonical)};
  }
  return std::nullopt;
}

std::optional<Unit> parse_unit(std::string_view text) {
  text = trim(text);
  const std::size_t slash = text.find('/');
  if (slash == std::string_view::npos) return base_unit(text);
  const std::string_view top = trim(text.substr(0, slash));
  const auto bottom = base_unit(trim(text.substr(slash + 1)));  // a second '/' fails here
  if (!bottom) return std::nullopt;
  Unit out;
  if (top == "1") {
    out.name = "1";
  } else {
    const auto numerator = base_unit(top);
    if (!numerator || numerator->dimension == bottom->dimension) return std::nullopt;
    out = *numerator;
  }
  out.dimension.stress -= bottom->dimension.stress;
  out.dimension.length -= bottom->dimension.length;
  out.dimension.time -= bottom->dimension.time;
  out.scale.pow10 -= bottom->scale.pow10;
  out.scale.pow60 -= bottom->scale.pow60;
  out.name += "/" + bottom->name;
  return out;
}

std::vector<std::string> unit_names_of(Dimension d) {
  std::vector<std::string> out;
  if (d == dimension::none) return out;
  const auto top = single_base(d, +1);
  const auto bottom = single_base(d, -1);
  std::vector<std::string_view> tops = {"1"};
  if (top) tops = ascii_names_of(*top);
  if (!bottom) {
    for (const auto& t : tops) out.emplace_back(t);
    return out;
  }
  for (const auto& t : tops)
    for (const auto& b : ascii_names_of(*bottom))
      out.push_back(std::string(t) + "/" + std::string(b));
  return out;
}

std::string units_for(Dimension d) {
  auto either = [](const std::vector<std::string>& names) {
    std::string s;
    for (std::size_t k = 0; k < names.size(); ++k)
      s.append(k == 0 ? "" : k + 1 == names.size() ? " or " : ", ").append(names[k]);
    return s;
  };
  auto listed = [](Dimension base) {
    std::string s;
    for (const auto& n : ascii_names_of(base)) s.append(s.empty() ? "" : ", ").append(n);
    return s;
  };
  if (d == dimension::none) return "no unit";
  const auto top = single_base(d, +1);
  const auto bottom = single_base(d, -1);
  if (top && bottom) {
    return "a " + describe(*top) + " unit (" + listed(*top) + ") / a " + describe(*bottom) +
           " unit (" + listed(*bottom) + ")";
  }
  return either(unit_names_of(d));
}

std::string supported_units() {
  auto list = [](Dimension d) {
    std::string s;
    for (const auto& n : ascii_names_of(d)) s.append(s.empty() ? "" : " ").append(n);
    return s;
  };
  return "stress " + list(dimension::stress) + "; length " + list(dimension::length) +
         " (um also as \xC2\xB5m); time " + list(dimension::time) +
         "; and quotients of two of them or 1/unit (mm/min, MPa/mm, min/mm, 1/s)";
}

double convert(double value, Scale from, Scale to) {
  // from / to = 10^p 60^q = 2^(p + 2q) 3^q 5^(p + q).
  const int p = from.pow10 - to.pow10;
  const int q = from.pow60 - to.pow60;
  const int twos = p + 2 * q, threes = q, fives = p + q;
  const double num = power_product(std::max(twos, 0), std::max(threes, 0), std::max(fives, 0));
  const double den = power_product(std::max(-twos, 0), std::max(-threes, 0), std::max(-fives, 0));
  if (den == 1.0) return value * num;
  if (num == 1.0) return value / den;
  return value * num / den;
}

double to_si(double value, Scale from) {
  return convert(value, from, Scale{});
}

std::vector<std::pair<std::string, std::string>> Units::entries() const {
  return {{"stress", stress}, {"length", length}, {"time", time}};
}

Unit Units::unit(Dimension d) const {
  Unit out{d, {}, "1"};
  if (d == dimension::none) return out;
  std::string num, den;
  const std::array<std::pair<int, const std::string*>, 3> bases = {
      {{d.stress, &stress}, {d.length, &length}, {d.time, &time}}};
  for (const auto& [exponent, name] : bases) {
    if (exponent == 0) continue;
    const auto base = base_unit(*name);
    if (!base) throw std::logic_error("Units::unit: no unit for " + describe(d));
    std::string& side = exponent > 0 ? num : den;
    if (!side.empty()) side += '*';
    side += *name;
    if (std::abs(exponent) != 1) side.append("^").append(std::to_string(std::abs(exponent)));
    out.scale.pow10 += exponent * base->scale.pow10;
    out.scale.pow60 += exponent * base->scale.pow60;
  }
  out.name = num.empty() ? "1" : num;
  if (!den.empty()) out.name.append("/").append(den);
  return out;
}

}  // namespace subslip::model
