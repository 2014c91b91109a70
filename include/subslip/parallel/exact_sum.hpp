// The exact sum of doubles, whatever their order and however they are split among threads or
// MPI ranks: what makes a Taylor aggregate's volume average bitwise the same at any rank count
// (floating-point addition is not associative, so partial sums in rank order are not).
//
// Every finite double is an integer multiple of 2^-1074, below 2^1024: the sum is kept as a
// fixed-point number of 32-bit digits ("limbs", Kulisch's long accumulator) held in signed
// 64-bit words, so that 2^29 additions fit before carries must be propagated. Two sums merge by
// adding their words, which is exact and associative: an MPI reduction is MPI_SUM on int64
// (docs/scaling.md: the method and its cost). Cost: an addition is a frexp and three integer
// additions; a merge or a reduction moves 71 words per summed component.
#pragma once

#include <array>
#include <cstdint>

namespace subslip::parallel {

class ExactSum {
 public:
  static constexpr int kLimbBits = 32;
  // The weight of limb 0: 2^-1088, a multiple of 32 below the smallest subnormal 2^-1074.
  static constexpr int kLowestExponent = -1088;
  // Limbs 0..66 hold every double (2^1024 = limb 66's weight 2^1024 ... 2^1056); limb 67 keeps
  // the carries of many large terms and the sign.
  static constexpr int kLimbs = 68;
  // Words: the limbs, then counts of NaN, +inf and -inf terms (they decide a non-finite sum).
  static constexpr int kWords = kLimbs + 3;

  void add(double x);
  // Adds another sum (of any other terms): exact.
  void merge(const ExactSum& other);
  // The sum rounded to a double: a function of the exact sum alone (not of the order of the
  // terms), within one unit in the last place. NaN when a term was NaN or the terms held both
  // infinities; +-inf when they held one of them (or the sum overflows).
  double value() const;

  // The words, for a reduction that adds them (MPI_SUM on int64). Call normalize() first, so
  // that up to 2^31 sums can be added without overflow; the sum of the words is a valid sum.
  void normalize();
  std::array<std::int64_t, kWords>& words() { return words_; }
  const std::array<std::int64_t, kWords>& words() const { return words_; }

 private:
  static constexpr int kNan = kLimbs, kPlusInf = kLimbs + 1, kMinusInf = kLimbs + 2;
  // Additions a limb takes (each adds less than 2^33 in magnitude) before it could overflow.
  static constexpr std::int32_t kAddsBeforeCarry = 1 << 29;
  std::array<std::int64_t, kWords> words_{};
  std::int32_t pending_ = 0;  // additions since the last normalize()
};

}  // namespace subslip::parallel
