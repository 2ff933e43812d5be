#include <gtest/gtest.h>

#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include "test_util.hpp"
#include "voxfield/core/chunks.hpp"

namespace voxfield {
namespace {

using test::expect_input_error;

TEST(Chunks, FloorDiv) {
    EXPECT_EQ(floor_div(-1, 8), -1);
    EXPECT_EQ(floor_div(-8, 8), -1);
    EXPECT_EQ(floor_div(-9, 8), -2);
    EXPECT_EQ(floor_div(0, 8), 0);
    EXPECT_EQ(floor_div(7, 8), 0);
    EXPECT_EQ(floor_div(8, 8), 1);
    EXPECT_EQ(floor_div(7, -2), -4);
    EXPECT_EQ(floor_div(-7, -2), 3);
    for (std::int64_t a = -50; a <= 50; ++a) {
        for (std::int64_t b : {1, 2, 3, 8, 16}) {
            const std::int64_t q = floor_div(a, b);
            EXPECT_LE(q * b, a);
            EXPECT_GT((q + 1) * b, a);
        }
    }
}

TEST(Chunks, BoxVolumeAndIntersect) {
    const Box a{{0, 0, 0}, {4, 5, 6}};
    EXPECT_EQ(a.volume(), 120);
    EXPECT_FALSE(a.empty());
    const Box b{{2, -3, 5}, {10, 2, 9}};
    const Box c = intersect(a, b);
    EXPECT_EQ(c, (Box{{2, 0, 5}, {4, 2, 6}}));
    EXPECT_EQ(c.volume(), 4);
    const Box d = intersect(a, Box{{4, 0, 0}, {8, 5, 6}});
    EXPECT_TRUE(d.empty());
    EXPECT_EQ(d.volume(), 0);
}

// Every voxel of `boxes` lies in some box of `merged`.
bool covers(const std::vector<Box>& merged, const std::vector<Box>& boxes) {
    for (const Box& b : boxes) {
        for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
            for (std::int64_t y = b.min.y; y < b.max.y; ++y) {
                for (std::int64_t x = b.min.x; x < b.max.x; ++x) {
                    bool in = false;
                    for (const Box& m : merged) {
                        in |= x >= m.min.x && x < m.max.x && y >= m.min.y && y < m.max.y &&
                              z >= m.min.z && z < m.max.z;
                    }
                    if (!in) {
                        return false;
                    }
                }
            }
        }
    }
    return true;
}

TEST(Box, MergeForLaunchesCoversEveryBoxAndStopsWhenMergesCostMore) {
    // Near boxes merge (their hull adds less than a launch), far ones stay apart.
    const std::vector<Box> near_far = {{{0, 0, 0}, {4, 4, 4}},
                                       {{5, 0, 0}, {9, 4, 4}},
                                       {{100, 100, 100}, {104, 104, 104}},
                                       {{}, {}}};
    const std::vector<Box> m = merge_for_launches(near_far, 64, 64);
    ASSERT_EQ(m.size(), 2u);
    EXPECT_TRUE(covers(m, near_far));
    EXPECT_EQ(m[0], (Box{{0, 0, 0}, {9, 4, 4}}));
    // A launch worth no voxels: nothing merges; worth the world: everything does.
    EXPECT_EQ(merge_for_launches(near_far, -1, 64).size(), 3u);
    EXPECT_EQ(merge_for_launches(near_far, 1 << 30, 64),
              (std::vector<Box>{{{0, 0, 0}, {104, 104, 104}}}));
    // Random boxes: always at most max_boxes, always covering; more than twice that: the hull.
    std::mt19937_64 rng(5);
    for (int trial = 0; trial < 40; ++trial) {
        std::vector<Box> boxes;
        const int n = 1 + static_cast<int>(rng() % 150);
        for (int i = 0; i < n; ++i) {
            const Int3 lo{static_cast<std::int64_t>(rng() % 40),
                          static_cast<std::int64_t>(rng() % 40),
                          static_cast<std::int64_t>(rng() % 40)};
            boxes.push_back({lo,
                             {lo.x + 1 + static_cast<std::int64_t>(rng() % 6),
                              lo.y + 1 + static_cast<std::int64_t>(rng() % 6),
                              lo.z + 1 + static_cast<std::int64_t>(rng() % 6)}});
        }
        const std::size_t max_boxes = 1 + rng() % 40;
        const std::vector<Box> merged =
            merge_for_launches(boxes, static_cast<std::int64_t>(rng() % 500), max_boxes);
        EXPECT_LE(merged.size(), max_boxes);
        EXPECT_TRUE(covers(merged, boxes));
        if (boxes.size() > 2 * max_boxes) {
            EXPECT_EQ(merged.size(), 1u);
        }
    }
}

TEST(Box, HullHoldsBothAndIgnoresEmptyBoxes) {
    const Box a{{0, 1, 2}, {3, 4, 5}};
    const Box b{{-2, 3, 4}, {1, 9, 6}};
    EXPECT_EQ(hull(a, b), (Box{{-2, 1, 2}, {3, 9, 6}}));
    EXPECT_EQ(hull(Box{}, b), b);
    EXPECT_EQ(hull(a, Box{}), a);
}

TEST(Chunks, RejectsNonPowerOfTwo) {
    for (std::uint32_t c : {0u, 3u, 6u, 12u, 100u}) {
        expect_input_error(
            [&] {
                ChunkGrid g(Dims{8, 8, 8}, c);
            },
            {std::to_string(c), "power of two"});
    }
    for (std::uint32_t c : {1u, 2u, 8u, 16u, 1024u}) {
        EXPECT_NO_THROW(ChunkGrid(Dims{8, 8, 8}, c));
    }
}

TEST(Chunks, NonCubicWorldClippedEdges) {
    const ChunkGrid g(Dims{20, 8, 33}, 8);
    EXPECT_EQ(g.chunk(), 8u);
    EXPECT_EQ(g.world(), (Dims{20, 8, 33}));
    EXPECT_EQ(g.chunks(), (Dims{3, 1, 5}));
    EXPECT_EQ(g.chunk_count(), 15u);
    EXPECT_EQ(g.voxels_of({0, 0, 0}), (Box{{0, 0, 0}, {8, 8, 8}}));
    EXPECT_EQ(g.voxels_of({2, 0, 4}), (Box{{16, 0, 32}, {20, 8, 33}}));
    EXPECT_EQ(g.voxels_of({2, 0, 4}).volume(), 4 * 8 * 1);
    EXPECT_TRUE(g.voxels_of({3, 0, 0}).empty());
    EXPECT_TRUE(g.voxels_of({-1, 0, 0}).empty());
    // The clipped chunks tile the world exactly.
    std::int64_t total = 0;
    for (std::int64_t z = 0; z < 5; ++z) {
        for (std::int64_t y = 0; y < 1; ++y) {
            for (std::int64_t x = 0; x < 3; ++x) {
                total += g.voxels_of({x, y, z}).volume();
            }
        }
    }
    EXPECT_EQ(total, 20 * 8 * 33);
}

TEST(Chunks, ChunkOfAndIndex) {
    const ChunkGrid g(Dims{20, 16, 33}, 8);
    EXPECT_EQ(g.chunk_of({0, 0, 0}), (Int3{0, 0, 0}));
    EXPECT_EQ(g.chunk_of({19, 15, 32}), (Int3{2, 1, 4}));
    EXPECT_EQ(g.chunk_of({-1, -8, -9}), (Int3{-1, -1, -2}));
    EXPECT_EQ(g.chunk_index({0, 0, 0}), 0u);
    EXPECT_EQ(g.chunk_index({1, 0, 0}), 1u);
    EXPECT_EQ(g.chunk_index({0, 1, 0}), 3u);
    EXPECT_EQ(g.chunk_index({0, 0, 1}), 6u);
    EXPECT_EQ(g.chunk_index({2, 1, 4}), 29u);
    EXPECT_THROW(g.chunk_index({3, 0, 0}), std::out_of_range);
    EXPECT_THROW(g.chunk_index({-1, 0, 0}), std::out_of_range);
}

TEST(Chunks, ChunksOverlapping) {
    const ChunkGrid g(Dims{20, 16, 33}, 8);
    EXPECT_EQ(g.chunks_overlapping(Box{{0, 0, 0}, {1, 1, 1}}), (Box{{0, 0, 0}, {1, 1, 1}}));
    EXPECT_EQ(g.chunks_overlapping(Box{{7, 7, 7}, {9, 9, 9}}), (Box{{0, 0, 0}, {2, 2, 2}}));
    EXPECT_EQ(g.chunks_overlapping(Box{{8, 8, 8}, {16, 16, 16}}), (Box{{1, 1, 1}, {2, 2, 2}}));
    // Clipped to the grid on both sides.
    EXPECT_EQ(g.chunks_overlapping(Box{{-100, -5, -1}, {100, 100, 100}}),
              (Box{{0, 0, 0}, {3, 2, 5}}));
    EXPECT_TRUE(g.chunks_overlapping(Box{{30, 0, 0}, {40, 4, 4}}).empty());
    EXPECT_TRUE(g.chunks_overlapping(Box{{-9, 0, 0}, {-1, 4, 4}}).empty());
    EXPECT_TRUE(g.chunks_overlapping(Box{{3, 3, 3}, {3, 5, 5}}).empty());
}

TEST(Chunks, RequireChunkFits) {
    EXPECT_NO_THROW(require_chunk_fits(Dims{16, 16, 16}, 16));
    EXPECT_NO_THROW(require_chunk_fits(Dims{20, 17, 33}, 16));
    EXPECT_THROW(require_chunk_fits(Dims{16, 16, 16}, 12), InputError);
    EXPECT_THROW(require_chunk_fits(Dims{16, 16, 16}, 0), InputError);
    try {
        require_chunk_fits(Dims{64, 8, 64}, 16);
        FAIL() << "chunk 16 in an 8-voxel-tall world accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("along y"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("use --chunk 8 or less"), std::string::npos)
            << e.what();
    }
    // The chunk suggested is a power of two that fits every axis, not the short axis's length.
    try {
        require_chunk_fits(Dims{40, 12, 1}, 8);
        FAIL() << "chunk 8 in a one-voxel-deep world accepted";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("use --chunk 1 or less"), std::string::npos)
            << e.what();
    }
}

TEST(Chunks, FocusBox) {
    const ChunkGrid grid(Dims{64, 32, 48}, 16);  // 4 x 2 x 3 chunks
    EXPECT_EQ(focus_chunks(grid, {{1, 1, 1}, 0}), (Box{{1, 1, 1}, {2, 2, 2}}));
    EXPECT_EQ(focus_chunks(grid, {{1, 0, 2}, 1}), (Box{{0, 0, 1}, {3, 2, 3}}));
    EXPECT_EQ(focus_chunks(grid, {{0, 0, 0}, 9}), (Box{{0, 0, 0}, {4, 2, 3}}));
    EXPECT_EQ(focus_chunks(grid, {{3, 1, 2}, std::numeric_limits<std::int64_t>::max()}),
              (Box{{0, 0, 0}, {4, 2, 3}}));
    EXPECT_THROW(focus_chunks(grid, {{4, 0, 0}, 1}), InputError);
    EXPECT_THROW(focus_chunks(grid, {{0, -1, 0}, 1}), InputError);
    EXPECT_THROW(focus_chunks(grid, {{0, 0, 0}, -1}), InputError);
}

}  // namespace
}  // namespace voxfield
