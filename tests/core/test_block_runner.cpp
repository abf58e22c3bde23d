// The block runner (core/block_runner.h) and the exact, mergeable histogram (stats/histogram.h): results
// depend only on (seed, block range), shards add up to the whole run bit for bit, and cancellation keeps
// the completed prefix.
#include "core/block_runner.h"
#include "core/exact_sum.h"
#include "core/random.h"
#include "stats/histogram.h"

#include <gtest/gtest.h>

#include <bit>

#include <random>

#include <cmath>
#include <vector>

namespace microsim {
namespace {

// A floating-point reduction whose value depends on the order of the additions: the sum of squares of
// every variate, block by block, reduced sequentially.
double ordered_sum(BlockRange range, int threads, std::vector<std::uint64_t>* order = nullptr) {
  const BlockPlan plan{1000 * 37 + 11, 1000};
  RunControl run;
  run.threads = threads;
  double total = 0;
  for_each_block(
      range, run, {"test", plan},
      [&](std::uint64_t b) {
        CounterRng rng(7, b);
        double s = 0;
        for (std::uint64_t i = 0; i < plan.units_in(b); ++i) s += std::pow(rng.uniform(), 2.0) * 1e3;
        return s;
      },
      [&](double s, std::uint64_t b) {
        total += s;
        if (order) order->push_back(b);
      });
  return total;
}

TEST(BlockRunner, ResultIndependentOfThreadsAndReducedInBlockOrder) {
  std::vector<std::uint64_t> order;
  const double one = ordered_sum({0, 38}, 1, &order);
  for (int threads : {2, 3, 8}) EXPECT_EQ(ordered_sum({0, 38}, threads), one) << threads;
  ASSERT_EQ(order.size(), 38u);
  for (std::size_t i = 0; i < order.size(); ++i) EXPECT_EQ(order[i], i);
}

TEST(BlockRunner, ShardsCoverTheRangeInOrder) {
  for (std::uint64_t blocks : {0ull, 1ull, 7ull, 38ull, 1000003ull}) {
    for (std::uint64_t n : {1ull, 2ull, 3ull, 7ull, 64ull}) {
      std::uint64_t next = 0;
      for (std::uint64_t k = 1; k <= n; ++k) {
        const BlockRange r = shard_range(blocks, k, n);
        EXPECT_EQ(r.begin, next);
        EXPECT_LE(r.size(), blocks / n + 1);
        EXPECT_GE(r.size(), blocks / n);
        next = r.end;
      }
      EXPECT_EQ(next, blocks);
    }
  }
  EXPECT_THROW(shard_range(10, 0, 3), std::invalid_argument);
  EXPECT_THROW(shard_range(10, 4, 3), std::invalid_argument);
}

TEST(BlockRunner, CancelKeepsTheCompletedPrefix) {
  CancelToken cancel;
  RunControl run;
  run.threads = 2;
  run.cancel = &cancel;
  const BlockPlan plan{1000, 1};
  std::uint64_t reduced = 0;
  const BlockRunStatus status = for_each_block(
      BlockRange{0, 1000}, run, {"test", plan, 8},
      [&](std::uint64_t b) {
        if (b == 100) cancel.cancel();
        return b;
      },
      [&](std::uint64_t b, std::uint64_t block) {
        EXPECT_EQ(b, block);
        EXPECT_EQ(block, reduced);
        ++reduced;
      });
  EXPECT_TRUE(status.cancelled);
  EXPECT_EQ(status.done.begin, 0u);
  EXPECT_EQ(status.done.end, reduced);
  EXPECT_GE(reduced, 100u);
  EXPECT_LT(reduced, 1000u);
}

// The fast conversion of a term is nearbyint(ldexp(term, 64)) bit for bit: edge values, ties, and 4e6
// random terms over [2^-70, 2^40].
TEST(ExactSum, FixedPointOfATermIsTheRoundedScaledDouble) {
  const auto reference = [](double x) { return static_cast<__int128>(std::nearbyint(std::ldexp(x, 64))); };
  for (double x : {0.0, 1.0, 0.5, 0x1p40, 0x1p-64, 0x1p-65, 0x1.8p-65, 0x1p-66, 0x1.8p-64, 0x1.4p-63, 0x1.cp-64, 3e-20,
                   5.4e-20, 1e-300, 0x1p-1074, 0x1p-1022, 0x1.fffffffffffffp39})
    EXPECT_TRUE(ExactSum::to_fixed(x) == reference(x)) << x;
  std::mt19937_64 g(1);
  int differ = 0;
  for (int i = 0; i < 2'000'000; ++i) {
    const double x = std::ldexp(std::uniform_real_distribution<double>(1, 2)(g),
                                int(std::floor(std::uniform_real_distribution<double>(-70, 40)(g))));
    const double tie_prone = std::bit_cast<double>(std::bit_cast<std::uint64_t>(x) & ~std::uint64_t(0xFF));
    differ += int(ExactSum::to_fixed(x) != reference(x)) + int(ExactSum::to_fixed(tie_prone) != reference(tie_prone));
  }
  EXPECT_EQ(differ, 0);
}

TEST(ExactSum, AssociativeWhereDoublesAreNot) {
  const double a = 1.0, b = 1.2e-16, c = 1.2e-16;
  EXPECT_NE((a + b) + c, a + (b + c));  // the control: plain doubles depend on the grouping
  ExactSum left, right, ab, bc, sa, sb, sc;
  sa.add(a), sb.add(b), sc.add(c);
  ab = sa, ab += sb, ab += sc;
  bc = sb, bc += sc, left = sa, left += bc;
  EXPECT_EQ(ab, left);
  EXPECT_THROW(sa.add(-1.0), std::domain_error);
  EXPECT_THROW(sa.add(std::nan("")), std::domain_error);
}

TEST(Histogram, MergeOfShardsIsTheWholeRunAndRefusesOtherBinnings) {
  auto fill = [](BlockRange r) {
    Histogram h("sphere rows 3", 18);
    for (std::uint64_t b = r.begin; b < r.end; ++b) {
      CounterRng rng(3, b);
      for (int i = 0; i < 100; ++i) h.add(std::size_t(rng.uniform() * 18), rng.uniform());  // Fresnel-like weights
    }
    return h;
  };
  const Histogram whole = fill({0, 50});
  Histogram merged = fill({0, 17});
  merged.merge(fill({17, 31}));
  merged.merge(fill({31, 50}));
  EXPECT_TRUE(merged == whole);
  EXPECT_THROW(merged.merge(Histogram("lobe rows 3", 18)), HistogramMergeError);
}

TEST(Histogram, BlockRangesNameGapsAndOverlaps) {
  EXPECT_EQ(merge_block_ranges({{5, 9}, {0, 5}}, 9, true), (BlockRange{0, 9}));
  try {
    merge_block_ranges({{0, 5}, {4, 9}}, 9, true);
    FAIL();
  } catch (const HistogramMergeError& e) {
    EXPECT_NE(std::string(e.what()).find("[4, 5)"), std::string::npos) << e.what();
  }
  try {
    merge_block_ranges({{0, 3}, {5, 9}}, 12, true);
    FAIL();
  } catch (const HistogramMergeError& e) {
    EXPECT_NE(std::string(e.what()).find("[3, 5), [9, 12)"), std::string::npos) << e.what();
  }
  EXPECT_EQ(merge_block_ranges({{3, 5}, {5, 9}}, 12, false), (BlockRange{3, 9}));  // a contiguous partial
}

}  // namespace
}  // namespace microsim
