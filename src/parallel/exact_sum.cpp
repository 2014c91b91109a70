#include "subslip/parallel/exact_sum.hpp"

#include <bit>
#include <cmath>
#include <limits>

namespace subslip::parallel {

namespace {

constexpr std::int64_t kDigitMask = (std::int64_t{1} << ExactSum::kLimbBits) - 1;
constexpr int kMantissaBits = std::numeric_limits<double>::digits;  // 53
constexpr int kLowestDoubleExponent = -1074;                        // the subnormal step

// Carries every limb but the last into [0, 2^32); the last keeps the sign. The result is the
// unique such form of the number, so value() sees the same limbs however the sum was formed.
void carry(std::array<std::int64_t, ExactSum::kWords>& w) {
  for (int k = 0; k + 1 < ExactSum::kLimbs; ++k) {
    const std::int64_t c = w[k] >> ExactSum::kLimbBits;  // floor division (arithmetic shift)
    w[k] &= kDigitMask;
    w[k + 1] += c;
  }
}

}  // namespace

void ExactSum::add(double x) {
  // x = (-1)^sign mantissa 2^exponent, read from its IEEE 754 fields: an integer mantissa of at
  // most 53 bits and exponent >= -1074 (subnormals: the biased exponent 0, no hidden bit).
  const auto bits = std::bit_cast<std::uint64_t>(x);
  const auto biased = static_cast<int>((bits >> (kMantissaBits - 1)) & 0x7ff);
  if (biased == 0x7ff) {
    ++words_[std::isnan(x) ? kNan : (x > 0 ? kPlusInf : kMinusInf)];
    return;
  }
  auto mantissa = static_cast<std::int64_t>(bits & ((std::uint64_t{1} << (kMantissaBits - 1)) - 1));
  int exponent = kLowestDoubleExponent;
  if (biased > 0) {
    mantissa |= std::int64_t{1} << (kMantissaBits - 1);
    exponent += biased - 1;
  }
  if (mantissa == 0) return;  // +-0
  const int shift = exponent - kLowestExponent;
  const int limb = shift / kLimbBits, bit = shift % kLimbBits;
  // mantissa 2^bit < 2^84 over limbs limb .. limb + 2, from its low and high 32 bits (each
  // shifted stays below 2^63).
  const std::int64_t sign = (bits >> 63) != 0 ? -1 : 1;
  const std::int64_t low = (mantissa & kDigitMask) << bit, high = (mantissa >> kLimbBits) << bit;
  words_[limb] += sign * (low & kDigitMask);
  words_[limb + 1] += sign * ((low >> kLimbBits) + (high & kDigitMask));
  words_[limb + 2] += sign * (high >> kLimbBits);
  if (++pending_ == kAddsBeforeCarry) normalize();
}

void ExactSum::merge(const ExactSum& other) {
  ExactSum o = other;
  o.normalize();
  normalize();
  for (int k = 0; k < kWords; ++k) words_[k] += o.words_[k];
  normalize();
}

void ExactSum::normalize() {
  carry(words_);
  pending_ = 0;
}

double ExactSum::value() const {
  if (words_[kNan] > 0 || (words_[kPlusInf] > 0 && words_[kMinusInf] > 0))
    return std::numeric_limits<double>::quiet_NaN();
  if (words_[kPlusInf] > 0) return std::numeric_limits<double>::infinity();
  if (words_[kMinusInf] > 0) return -std::numeric_limits<double>::infinity();
  std::array<std::int64_t, kWords> w = words_;
  carry(w);
  // The magnitude in the same unique form, then its four leading limbs from the top (at least
  // 97 significant bits), so the rounded sum is within an ulp of the exact one.
  const bool negative = w[kLimbs - 1] < 0;
  if (negative) {
    for (int k = 0; k < kLimbs; ++k) w[k] = -w[k];
    carry(w);
  }
  int top = kLimbs - 1;
  while (top >= 0 && w[top] == 0) --top;
  double sum = 0.0;
  for (int k = top; k >= 0 && k > top - 4; --k)
    sum += std::ldexp(static_cast<double>(w[k]), kLowestExponent + kLimbBits * k);
  return negative ? -sum : sum;
}

}  // namespace subslip::parallel
