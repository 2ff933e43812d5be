#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <random>
#include <vector>

#include "voxfield/core/chunks.hpp"
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

TEST(ReferenceChunked, HandComputedRow) {
    // One row of 8 in chunks of 4: each chunk's shell bounds the distance, a solid at x = 6.
    World w(Dims{8, 1, 1});
    w.set(6, 0, 0, 1);
    const auto f = reference_manhattan_chunked(w, 4);
    // y and z extents are 1, so the shell is one step away everywhere.
    EXPECT_EQ(f, (std::vector<std::uint32_t>{1, 1, 1, 1, 1, 1, 0, 1}));
    World row(Dims{8, 9, 9});
    row.set(6, 4, 4, 1);
    const auto g = reference_manhattan_chunked(row, 8);
    const std::uint32_t expected[] = {1, 2, 3, 3, 2, 1, 0, 1};
    for (std::uint32_t x = 0; x < 8; ++x) {
        EXPECT_EQ(g[row.dims().index(x, 4, 4)], expected[x]) << x;
    }
}

TEST(ReferenceChunked, MatchesAlgorithm3OnRandomGrids) {
    std::mt19937_64 rng(77);
    const double densities[] = {0.0, 0.01, 0.05, 0.2, 0.6, 1.0};
    for (int trial = 0; trial < 150; ++trial) {
        const Dims d{static_cast<std::uint32_t>(1 + rng() % 13),
                     static_cast<std::uint32_t>(1 + rng() % 13),
                     static_cast<std::uint32_t>(1 + rng() % 13)};
        const std::uint32_t chunk = 1u << (rng() % 4);
        World w(d);
        const double density = densities[static_cast<std::size_t>(trial) % 6];
        for (auto& v : w.voxels()) {
            v = static_cast<double>(rng() >> 11) * 0x1.0p-53 < density ? 3 : 0;
        }
        const auto ref = reference_manhattan_chunked(w, chunk);
        ASSERT_EQ(ref, brute_force_manhattan_chunked(w, chunk))
            << "trial " << trial << " dims " << d.to_string() << " chunk " << chunk;
        for (auto v : ref) {
            ASSERT_LE(v, (chunk + 1) / 2) << "beyond the shell bound";
        }
    }
}

TEST(ReferenceChunked, ChunkAsLargeAsWorldIsGlobalPlusShell) {
    const World w = scene_floor_spheres(Dims{16, 16, 16}, 3);
    const auto local = reference_manhattan_chunked(w, 16);
    const auto global = reference_manhattan(w);
    for (std::uint32_t z = 0; z < 16; ++z) {
        for (std::uint32_t y = 0; y < 16; ++y) {
            for (std::uint32_t x = 0; x < 16; ++x) {
                const std::uint32_t shell = std::min({x + 1, 16 - x, y + 1, 16 - y, z + 1, 16 - z});
                const std::size_t i = w.dims().index(x, y, z);
                ASSERT_EQ(local[i], std::min(global[i], shell));
            }
        }
    }
}

}  // namespace
}  // namespace voxfield
