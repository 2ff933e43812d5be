#include "voxfield/core/accuracy.hpp"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "voxfield/core/reference.hpp"

namespace voxfield {
namespace {

World random_world(Dims d, double density, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::bernoulli_distribution solid(density);
    World w(d);
    for (auto& v : w.voxels()) {
        v = solid(rng) ? 1 : 0;
    }
    return w;
}

// The index planes (z, y, x) of a feature transform given as Dims::index per voxel.
std::vector<std::int32_t> planes_of(const std::vector<std::int64_t>& features, Dims d) {
    const std::size_t n = d.count();
    std::vector<std::int32_t> p(3 * n);
    for (std::size_t i = 0; i < n; ++i) {
        const std::int64_t f = features[i];
        p[i] = f < 0 ? -1 : static_cast<std::int32_t>(f / d.x / d.y);
        p[n + i] = f < 0 ? -1 : static_cast<std::int32_t>(f / d.x % d.y);
        p[2 * n + i] = f < 0 ? -1 : static_cast<std::int32_t>(f % d.x);
    }
    return p;
}

// The reference's own features pass; each kind of wrong index is counted where it is.
TEST(CheckIndices, CountsEveryKindOfWrongIndex) {
    const Dims d{9, 7, 5};
    const World w = random_world(d, 0.05, 17);
    const std::size_t n = d.count();
    for (Metric m : {Metric::manhattan, Metric::euclidean}) {
        SCOPED_TRACE(to_string(m));
        const auto exact = reference_distance(w, m, Spacing{});
        const auto scipy = reference_features(w, m, Spacing{});
        std::vector<std::int32_t> planes = planes_of(scipy, d);
        IndexAccuracy a = check_indices(w, m, Spacing{}, planes, exact, &scipy);
        EXPECT_EQ(a.checked, n);
        EXPECT_EQ(a.not_nearest, 0u);
        EXPECT_EQ(a.not_scipy, 0u);
        EXPECT_EQ(a.first_wrong, -1);

        // An empty voxel named: not a solid one. Out of the world: x = X.
        std::size_t empty = 0;
        while (w.voxels()[empty] != 0) {
            ++empty;
        }
        planes[3] = static_cast<std::int32_t>(empty / d.x / d.y);
        planes[n + 3] = static_cast<std::int32_t>(empty / d.x % d.y);
        planes[2 * n + 3] = static_cast<std::int32_t>(empty % d.x);
        planes[2 * n + 10] = static_cast<std::int32_t>(d.x);
        a = check_indices(w, m, Spacing{}, planes, exact, &scipy);
        EXPECT_EQ(a.not_nearest, 2u);
        EXPECT_EQ(a.first_wrong, 3);
    }
}

// A solid voxel farther than the nearest is not nearest; an equally near solid other than
// SciPy's choice is counted apart, and not at all without `scipy`.
TEST(CheckIndices, TellsFartherSolidsFromOtherTies) {
    // Solids at x = 0 and x = 4 of a 5 x 1 x 1 world: voxel 2 has two nearest solids.
    World w(Dims{5, 1, 1});
    w.voxels() = {1, 0, 0, 0, 1};
    const auto exact = reference_distance(w, Metric::euclidean, Spacing{});
    const auto scipy = reference_features(w, Metric::euclidean, Spacing{});
    std::vector<std::int32_t> planes(15, 0);
    const std::int32_t x[5] = {0, 0, 4, 4, 4};  // voxel 2 names x = 4, SciPy's lowest is 0
    std::copy(std::begin(x), std::end(x), planes.begin() + 10);
    IndexAccuracy a = check_indices(w, Metric::euclidean, Spacing{}, planes, exact, &scipy);
    EXPECT_EQ(a.not_nearest, 0u);
    EXPECT_EQ(a.not_scipy, 1u);
    EXPECT_EQ(a.first_wrong, 2);
    a = check_indices(w, Metric::euclidean, Spacing{}, planes, exact, nullptr);
    EXPECT_EQ(a.not_scipy, 0u);
    EXPECT_EQ(a.first_wrong, -1);
    planes[11] = 4;  // voxel 1 names x = 4, 3 away instead of 1
    a = check_indices(w, Metric::euclidean, Spacing{}, planes, exact, nullptr);
    EXPECT_EQ(a.not_nearest, 1u);
    EXPECT_EQ(a.first_wrong, 1);
}

// A world without solids: every index must be -1; spacing scales the distances compared.
TEST(CheckIndices, NoSolidsAndSpacing) {
    const World empty(Dims{3, 2, 2});
    const auto none = reference_distance(empty, Metric::euclidean, Spacing{});
    std::vector<std::int32_t> planes(36, -1);
    EXPECT_EQ(check_indices(empty, Metric::euclidean, Spacing{}, planes, none, nullptr).not_nearest,
              0u);
    planes[5] = 0;
    EXPECT_EQ(check_indices(empty, Metric::euclidean, Spacing{}, planes, none, nullptr).not_nearest,
              1u);

    const Dims d{6, 5, 4};
    const World w = random_world(d, 0.1, 5);
    const Spacing s{1.5, 0.75, 2.0};
    const auto exact = reference_distance(w, Metric::euclidean, s);
    // Brute force: a nearest solid by the spaced metric.
    std::vector<std::int64_t> nearest(d.count(), -1);
    for (std::size_t i = 0; i < d.count(); ++i) {
        double best = 1e300;
        for (std::size_t t = 0; t < d.count(); ++t) {
            if (w.voxels()[t] == 0) {
                continue;
            }
            const double dist = metric_distance(
                Metric::euclidean, s, static_cast<long>(t % d.x) - static_cast<long>(i % d.x),
                static_cast<long>(t / d.x % d.y) - static_cast<long>(i / d.x % d.y),
                static_cast<long>(t / d.x / d.y) - static_cast<long>(i / d.x / d.y));
            if (dist < best) {
                best = dist;
                nearest[i] = static_cast<std::int64_t>(t);
            }
        }
    }
    const auto spaced = planes_of(nearest, d);
    EXPECT_EQ(check_indices(w, Metric::euclidean, s, spaced, exact, nullptr).not_nearest, 0u);
    // The same indices are not all nearest without the spacing.
    const auto unit = reference_distance(w, Metric::euclidean, Spacing{});
    EXPECT_GT(check_indices(w, Metric::euclidean, Spacing{}, spaced, unit, nullptr).not_nearest,
              0u);
}

}  // namespace
}  // namespace voxfield
