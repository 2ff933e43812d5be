#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "voxfield/core/stats.hpp"

namespace voxfield {
namespace {

TEST(Stats, Empty) {
    const Summary s = summarize({});
    EXPECT_EQ(s.n, 0u);
    EXPECT_EQ(s.mean, 0);
    EXPECT_EQ(s.median, 0);
    EXPECT_EQ(s.std, 0);
    EXPECT_EQ(s.ci95_lo, 0);
    EXPECT_EQ(s.ci95_hi, 0);
}

TEST(Stats, Single) {
    const std::vector<double> v{4.5};
    const Summary s = summarize(v);
    EXPECT_EQ(s.n, 1u);
    EXPECT_DOUBLE_EQ(s.mean, 4.5);
    EXPECT_DOUBLE_EQ(s.median, 4.5);
    EXPECT_DOUBLE_EQ(s.std, 0.0);
    EXPECT_DOUBLE_EQ(s.min, 4.5);
    EXPECT_DOUBLE_EQ(s.max, 4.5);
    EXPECT_DOUBLE_EQ(s.ci95_lo, 4.5);
    EXPECT_DOUBLE_EQ(s.ci95_hi, 4.5);
}

TEST(Stats, KnownValuesOdd) {
    // Sorted: 1 2 4 4 4 5 5 7 9, so the mean is 41/9 and the median 4.
    const std::vector<double> v{9, 4, 1, 5, 4, 7, 2, 5, 4};
    const Summary s = summarize(v);
    EXPECT_EQ(s.n, 9u);
    EXPECT_DOUBLE_EQ(s.mean, 41.0 / 9.0);
    EXPECT_DOUBLE_EQ(s.median, 4.0);
    EXPECT_DOUBLE_EQ(s.min, 1.0);
    EXPECT_DOUBLE_EQ(s.max, 9.0);
    double ss = 0;
    for (double x : v) {
        ss += (x - 41.0 / 9.0) * (x - 41.0 / 9.0);
    }
    EXPECT_NEAR(s.std, std::sqrt(ss / 8.0), 1e-12);
}

TEST(Stats, KnownValuesEven) {
    // Classic example: 2 4 4 4 5 5 7 9 has mean 5, sample std sqrt(32/7), median 4.5.
    const std::vector<double> v{2, 4, 4, 4, 5, 5, 7, 9};
    const Summary s = summarize(v);
    EXPECT_EQ(s.n, 8u);
    EXPECT_DOUBLE_EQ(s.mean, 5.0);
    EXPECT_DOUBLE_EQ(s.median, 4.5);
    EXPECT_NEAR(s.std, std::sqrt(32.0 / 7.0), 1e-12);
    const double half = 1.96 * std::sqrt(32.0 / 7.0) / std::sqrt(8.0);
    EXPECT_NEAR(s.ci95_lo, 5.0 - half, 1e-12);
    EXPECT_NEAR(s.ci95_hi, 5.0 + half, 1e-12);
    const std::vector<double> two{1.0, 2.0};
    EXPECT_DOUBLE_EQ(summarize(two).median, 1.5);
}

TEST(Stats, ConfidenceIntervalOfDurationsNeverGoesBelowZero) {
    // One slow run among fast ones: mean - 1.96 std/sqrt(n) is negative, a time is not.
    const std::vector<double> ms{0.019, 0.02, 0.021, 2.5};
    const Summary s = summarize(ms);
    EXPECT_GT(1.96 * s.std / 2.0, s.mean);
    EXPECT_EQ(s.ci95_lo, 0.0);
    EXPECT_NEAR(s.ci95_hi, s.mean + 1.96 * s.std / 2.0, 1e-12);
    // Samples that can be negative keep the plain interval.
    const std::vector<double> signed_values{-1.0, 1.0};
    EXPECT_LT(summarize(signed_values).ci95_lo, -1.0);
}

}  // namespace
}  // namespace voxfield
