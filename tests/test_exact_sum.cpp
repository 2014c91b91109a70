// parallel::ExactSum, the sum the Taylor aggregate's volume averages use so that they do not
// depend on how the grains are split among threads and MPI ranks: exact for terms whose sum is
// known, the same bits in any order and any split, and the non-finite cases.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "subslip/parallel/exact_sum.hpp"
#include "subslip/parallel/team.hpp"

namespace {

using subslip::parallel::ExactSum;

double sum_of(const std::vector<double>& terms) {
  ExactSum s;
  for (double x : terms) s.add(x);
  return s.value();
}

bool same_bits(double a, double b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

// Terms spread over 600 binades (and subnormals), with cancellation.
std::vector<double> wild_terms(std::size_t n, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> mantissa(-1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-300, 300);
  std::vector<double> t;
  for (std::size_t k = 0; k < n; ++k) t.push_back(std::ldexp(mantissa(rng), exponent(rng)));
  t.push_back(std::numeric_limits<double>::denorm_min());
  t.push_back(-3.0 * std::numeric_limits<double>::denorm_min());
  t.push_back(std::numeric_limits<double>::max() / 4);
  t.push_back(-std::numeric_limits<double>::max() / 4);
  return t;
}

}  // namespace

TEST(ExactSum, SumsWhoseValueIsKnownAreExact) {
  EXPECT_EQ(sum_of({1e100, 1.0, -1e100}), 1.0);  // plain summation gives 0
  EXPECT_EQ(sum_of({0.1, 0.2, -0.1, -0.2}), 0.0);
  EXPECT_EQ(sum_of({}), 0.0);
  const double tiny = std::numeric_limits<double>::denorm_min();
  EXPECT_EQ(sum_of({tiny, tiny, tiny}), 3 * tiny);
  EXPECT_EQ(sum_of({std::numeric_limits<double>::max(), -std::numeric_limits<double>::max(), 2.5}),
            2.5);
  // Integers times a common power of two: the exact sum is an integer sum.
  std::mt19937_64 rng(7);
  std::uniform_int_distribution<std::int64_t> integer(-(std::int64_t{1} << 40),
                                                      std::int64_t{1} << 40);
  for (int scale : {-1070, -500, 0, 300, 900}) {
    std::vector<double> terms;
    std::int64_t exact = 0;
    for (int k = 0; k < 1000; ++k) {
      const std::int64_t m = integer(rng);
      exact += m;
      terms.push_back(std::ldexp(static_cast<double>(m), scale));
    }
    SCOPED_TRACE(scale);
    EXPECT_EQ(sum_of(terms), std::ldexp(static_cast<double>(exact), scale));
  }
}

TEST(ExactSum, TheSameBitsInAnyOrderAndAnySplit) {
  std::vector<double> terms = wild_terms(5000, 11);
  const double reference = sum_of(terms);
  std::mt19937 rng(3);
  for (int trial = 0; trial < 5; ++trial) {
    std::shuffle(terms.begin(), terms.end(), rng);
    EXPECT_TRUE(same_bits(sum_of(terms), reference));
    // Split into parts summed separately and merged, as ranks are.
    for (int parts : {2, 3, 7}) {
      std::vector<ExactSum> part(static_cast<std::size_t>(parts));
      for (std::size_t k = 0; k < terms.size(); ++k) part[k % part.size()].add(terms[k]);
      ExactSum merged;
      for (const auto& p : part) merged.merge(p);
      EXPECT_TRUE(same_bits(merged.value(), reference)) << parts << " parts";
      // Adding the normalized words, as an MPI_SUM on int64 does.
      ExactSum words;
      for (auto p : part) {
        p.normalize();
        for (int w = 0; w < ExactSum::kWords; ++w) words.words()[w] += p.words()[w];
      }
      EXPECT_TRUE(same_bits(words.value(), reference)) << parts << " parts (words)";
    }
  }
}

TEST(ExactSum, IsWithinAnUlpOfTheExactSum) {
  // Terms of one sign and similar size: the long-double sum is accurate to far below a
  // double's ulp, so it stands for the exact value.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(1.0, 2.0);
  std::vector<double> terms;
  long double exact = 0.0L;
  for (int k = 0; k < 1000; ++k) {
    terms.push_back(u(rng));
    exact += terms.back();
  }
  const double got = sum_of(terms);
  EXPECT_LE(std::abs(static_cast<long double>(got) - exact), std::nextafter(got, 1e300) - got);
}

TEST(ExactSum, NonFiniteTermsDecideTheSum) {
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(std::isnan(sum_of({1.0, std::nan(""), 2.0})));
  EXPECT_EQ(sum_of({1.0, inf, 2.0}), inf);
  EXPECT_EQ(sum_of({1.0, -inf}), -inf);
  EXPECT_TRUE(std::isnan(sum_of({inf, -inf})));
  // A finite sum beyond the largest double overflows to infinity.
  const double max = std::numeric_limits<double>::max();
  EXPECT_EQ(sum_of({max, max}), inf);
  EXPECT_EQ(sum_of({-max, -max}), -inf);
}

TEST(Team, BlocksCoverTheGrainsInOrder) {
  for (std::size_t total : {0UL, 1UL, 7UL, 1000UL}) {
    for (int ranks : {1, 2, 3, 4, 7}) {
      std::size_t next = 0, largest = 0, smallest = total;
      for (int r = 0; r < ranks; ++r) {
        const auto b = subslip::parallel::block_of(total, r, ranks);
        EXPECT_EQ(b.offset, next);
        EXPECT_EQ(b.total, total);
        next += b.count;
        largest = std::max(largest, b.count);
        smallest = std::min(smallest, b.count);
      }
      EXPECT_EQ(next, total) << total << " over " << ranks;
      EXPECT_LE(largest - smallest, 1u);
    }
  }
}

TEST(Team, TheLaunchersEnvironmentSaysWhetherAndAmongHowManyRanks) {
  // (The suite itself runs without a launcher: none of these is set.)
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"})
    ASSERT_EQ(std::getenv(name), nullptr) << name;
  EXPECT_FALSE(subslip::parallel::launched_by_mpi());
  EXPECT_EQ(subslip::parallel::launched_ranks(), 0);
  ::setenv("OMPI_COMM_WORLD_SIZE", "3", 1);
  EXPECT_TRUE(subslip::parallel::launched_by_mpi());
  EXPECT_EQ(subslip::parallel::launched_ranks(), 3);
  ::unsetenv("OMPI_COMM_WORLD_SIZE");
  ::setenv("PMIX_RANK", "0", 1);
  EXPECT_TRUE(subslip::parallel::launched_by_mpi());
  EXPECT_EQ(subslip::parallel::launched_ranks(), 0);
  ::unsetenv("PMIX_RANK");
}
