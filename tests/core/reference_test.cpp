#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <random>
#include <vector>

#include "voxfield/core/format.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/scenes.hpp"

namespace voxfield {
namespace {

TEST(Reference, HandComputedLine) {
    World w(Dims{7, 1, 1});
    w.set(2, 0, 0, 1);
    const auto f = reference_manhattan(w);
    EXPECT_EQ(f, (std::vector<std::uint32_t>{2, 1, 0, 1, 2, 3, 4}));
}

TEST(Reference, SingleVoxelIsL1Ball) {
    World w(Dims{5, 6, 7});
    w.set(1, 2, 3, 9);
    const auto f = reference_manhattan(w);
    for (std::uint32_t z = 0; z < 7; ++z) {
        for (std::uint32_t y = 0; y < 6; ++y) {
            for (std::uint32_t x = 0; x < 5; ++x) {
                const auto expected = static_cast<std::uint32_t>(std::abs(static_cast<int>(x) - 1) +
                                                                 std::abs(static_cast<int>(y) - 2) +
                                                                 std::abs(static_cast<int>(z) - 3));
                ASSERT_EQ(f[w.dims().index(x, y, z)], expected) << x << " " << y << " " << z;
            }
        }
    }
}

TEST(Reference, EmptyWorldIsInfinite) {
    const World w(Dims{3, 4, 5});
    for (auto v : reference_manhattan(w)) {
        ASSERT_EQ(v, kInfinite);
    }
    for (auto v : brute_force_manhattan(w)) {
        ASSERT_EQ(v, kInfinite);
    }
}

TEST(Reference, MatchesBruteForceOnRandomGrids) {
    std::mt19937_64 rng(2024);
    const double densities[] = {0.0, 0.002, 0.02, 0.1, 0.3, 0.7, 1.0};
    int grids = 0, nontrivial = 0;
    for (int trial = 0; trial < 280; ++trial) {
        const Dims d{static_cast<std::uint32_t>(1 + rng() % 9),
                     static_cast<std::uint32_t>(1 + rng() % 9),
                     static_cast<std::uint32_t>(1 + rng() % 9)};
        const double density = densities[static_cast<std::size_t>(trial) % 7];
        World w(d);
        for (auto& v : w.voxels()) {
            const double u = static_cast<double>(rng() >> 11) * 0x1.0p-53;
            v = u < density ? static_cast<std::uint8_t>(1 + rng() % 255) : 0;
        }
        const auto ref = reference_manhattan(w);
        const auto brute = brute_force_manhattan(w);
        ASSERT_EQ(ref, brute) << "trial " << trial << " dims " << d.to_string() << " density "
                              << density;
        ++grids;
        const std::size_t solids = w.solid_count();
        if (solids > 0 && solids < w.size()) {
            ++nontrivial;
        }
        if (density == 1.0) {
            for (auto v : ref) {
                ASSERT_EQ(v, 0u);
            }
        }
    }
    EXPECT_GE(grids, 200);
    EXPECT_GE(nontrivial, 100);
}

TEST(Reference, LargeWorldIsFastEnough) {
    const World w = scene_floor_spheres(Dims{256, 256, 256}, 7);
    const auto t0 = std::chrono::steady_clock::now();
    const auto f = reference_manhattan(w);
    const auto ms =
        std::chrono::duration_cast<std::chrono::milliseconds>(std::chrono::steady_clock::now() - t0)
            .count();
    ASSERT_EQ(f.size(), w.size());
    // The floor at y = 0 bounds every distance by y; solids are 0.
    for (std::uint32_t z = 0; z < 256; z += 37) {
        for (std::uint32_t y = 0; y < 256; y += 13) {
            for (std::uint32_t x = 0; x < 256; x += 11) {
                const auto v = f[w.dims().index(x, y, z)];
                EXPECT_LE(v, y);
                EXPECT_EQ(v == 0, w.at(x, y, z) != 0);
            }
        }
    }
    EXPECT_LT(ms, 5000) << "reference_manhattan on 256^3 took " << ms << " ms";
}

}  // namespace
}  // namespace voxfield
