// The separable reference of every metric against brute force, and the metric helpers.
#include <gtest/gtest.h>

#include <cmath>
#include <array>
#include <random>

#include "voxfield/core/error.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/scenes.hpp"

namespace voxfield {
namespace {

const Metric kMetrics[] = {Metric::manhattan, Metric::chebyshev, Metric::euclidean};

void expect_near_all(const std::vector<double>& a, const std::vector<double>& b,
                     const std::string& what) {
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t i = 0; i < a.size(); ++i) {
        if (std::isinf(b[i])) {
            ASSERT_TRUE(std::isinf(a[i]) && (a[i] > 0) == (b[i] > 0)) << what << " voxel " << i;
        } else {
            ASSERT_NEAR(a[i], b[i], 1e-9 * std::max(1.0, std::fabs(b[i])))
                << what << " voxel " << i;
        }
    }
}

TEST(ReferenceMetric, EqualsBruteForce) {
    std::mt19937_64 rng(7);
    std::uniform_int_distribution<std::uint32_t> axis(1, 9);
    std::uniform_real_distribution<double> sp(0.3, 2.5);
    for (int i = 0; i < 40; ++i) {
        const World w = scene_random(Dims{axis(rng), axis(rng), axis(rng)},
                                     std::array{0.0, 0.05, 0.2, 0.6, 1.0}[i % 5], rng());
        for (Metric m : kMetrics) {
            for (const Spacing& s : {Spacing{}, Spacing{sp(rng), sp(rng), sp(rng)}}) {
                const std::string what =
                    to_string(m) + " " + s.to_string() + " #" + std::to_string(i);
                expect_near_all(reference_distance(w, m, s), brute_force_distance(w, m, s), what);
                expect_near_all(reference_signed(w, m, s), brute_force_signed(w, m, s),
                                what + " signed");
            }
        }
    }
}

TEST(ReferenceMetric, FeaturesBreakTiesAsBruteForce) {
    std::mt19937_64 rng(11);
    std::uniform_int_distribution<std::uint32_t> axis(1, 9);
    for (int i = 0; i < 40; ++i) {
        const World w = scene_random(Dims{axis(rng), axis(rng), axis(rng)},
                                     std::array{0.0, 0.05, 0.3, 0.7, 1.0}[i % 5], rng());
        for (Metric m : {Metric::manhattan, Metric::euclidean}) {
            EXPECT_EQ(reference_features(w, m, Spacing{}), brute_force_features(w, m, Spacing{}))
                << to_string(m) << " #" << i;
        }
        // L-inf: the passes' choice, a nearest solid.
        const auto f = reference_features(w, Metric::chebyshev, Spacing{});
        const auto d = reference_distance(w, Metric::chebyshev, Spacing{});
        const Dims n = w.dims();
        for (std::size_t k = 0; k < f.size(); ++k) {
            if (f[k] < 0) {
                ASSERT_TRUE(std::isinf(d[k]));
                continue;
            }
            const auto j = static_cast<std::size_t>(f[k]);
            ASSERT_NE(w.voxels()[j], 0);
            const auto c = [](std::size_t a, std::size_t b) {
                return static_cast<long>(a) - static_cast<long>(b);
            };
            ASSERT_EQ(
                metric_distance(Metric::chebyshev, Spacing{}, c(k % n.x, j % n.x),
                                c(k / n.x % n.y, j / n.x % n.y), c(k / n.x / n.y, j / n.x / n.y)),
                d[k])
                << "chebyshev #" << i << " voxel " << k;
        }
    }
}

TEST(ReferenceMetric, UnitSpacingIsExactAndManhattanAgrees) {
    const World w = scene_random(Dims{23, 17, 12}, 0.02, 3);
    const auto l1 = reference_manhattan(w);
    const auto r1 = reference_distance(w, Metric::manhattan, Spacing{});
    const auto l2 = reference_distance(w, Metric::euclidean, Spacing{});
    const auto li = reference_distance(w, Metric::chebyshev, Spacing{});
    for (std::size_t i = 0; i < w.size(); ++i) {
        ASSERT_EQ(r1[i], static_cast<double>(l1[i]));
        ASSERT_EQ(li[i], std::floor(li[i]));
        ASSERT_EQ(l2[i], std::sqrt(std::round(l2[i] * l2[i])));  // sqrt of an integer
        ASSERT_LE(li[i], l2[i]);
        ASSERT_LE(l2[i], r1[i]);
    }
}

TEST(ReferenceMetric, SignedValuesOfAFullWorldCountToTheBorder) {
    World w(Dims{5, 3, 4});
    std::fill(w.voxels().begin(), w.voxels().end(), std::uint8_t{1});
    const auto s = reference_signed(w, Metric::chebyshev, Spacing{});
    EXPECT_EQ(s[w.dims().index(0, 0, 0)], -1);
    EXPECT_EQ(s[w.dims().index(2, 1, 1)], -2);
    const auto e = reference_signed(World(Dims{3, 3, 3}), Metric::euclidean, Spacing{});
    EXPECT_TRUE(std::isinf(e[0]) && e[0] > 0);
}

TEST(Metric, ParsesNamesAndSpacing) {
    EXPECT_EQ(parse_metric("chebyshev"), Metric::chebyshev);
    EXPECT_THROW(parse_metric("cosine"), InputError);
    EXPECT_EQ(parse_spacing("1,2.5,0.25"), (Spacing{1, 2.5, 0.25}));
    for (const char* bad : {"", "1,2", "1,2,3,4", "0,1,1", "-1,1,1", "1,x,1", "1,,1", "inf,1,1",
                            "nan,1,1", "1,1,1,"}) {
        EXPECT_THROW(parse_spacing(bad), InputError) << bad;
    }
    EXPECT_DOUBLE_EQ(metric_distance(Metric::euclidean, Spacing{1, 2, 3}, 1, -1, 1),
                     std::sqrt(14.0));
    EXPECT_DOUBLE_EQ(metric_distance(Metric::chebyshev, Spacing{1, 2, 3}, 4, -1, 1), 4.0);
    EXPECT_DOUBLE_EQ(metric_distance(Metric::manhattan, Spacing{1, 2, 3}, 1, -1, 1), 6.0);
}

TEST(Format, RealFieldEncoding) {
    const World w(Dims{6, 1, 1});
    const std::vector<double> d = {0.0, 2.7, -2.7, 1e9, -1e9, INFINITY};
    const auto u8 =
        encode_real_field({0.0, 2.7, 2.2, 1e9, 300, INFINITY}, w, Palette(), Format::u8);
    EXPECT_EQ(u8, (std::vector<std::uint8_t>{0, 2, 2, 255, 255, 255}));
    const auto i16 = encode_real_field(d, w, Palette(), Format::i16);
    EXPECT_EQ(decode_value(i16, Format::i16, 1), 2);
    EXPECT_EQ(decode_value(i16, Format::i16, 2), -2);
    EXPECT_EQ(decode_value(i16, Format::i16, 3), 32767);
    EXPECT_EQ(decode_value(i16, Format::i16, 4), -32767);
    const auto f32 = encode_real_field(d, w, Palette(), Format::f32);
    EXPECT_FLOAT_EQ(static_cast<float>(decode_value(f32, Format::f32, 2)), -2.7f);
    EXPECT_TRUE(std::isinf(decode_value(f32, Format::f32, 5)));
    const auto f64 = encode_real_field(d, w, Palette(), Format::f64);
    EXPECT_EQ(decode_value(f64, Format::f64, 1), 2.7);
}

}  // namespace
}  // namespace voxfield
