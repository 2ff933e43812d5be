#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <random>
#include <set>
#include <stdexcept>
#include <tuple>
#include <vector>

#include "voxfield/core/chunks.hpp"
#include "voxfield/core/dirty.hpp"

namespace voxfield {
namespace {

constexpr double kExact = 0.0;
constexpr double kAlwaysMerge = std::numeric_limits<double>::infinity();

// One flag per world voxel: set where a box (clipped to the world) covers it.
std::vector<char> mask_of(const std::vector<Box>& boxes, Dims d) {
    std::vector<char> m(d.count(), 0);
    for (const Box& raw : boxes) {
        const Box b = intersect(raw, Box{{0, 0, 0}, {d.x, d.y, d.z}});
        for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
            for (std::int64_t y = b.min.y; y < b.max.y; ++y) {
                for (std::int64_t x = b.min.x; x < b.max.x; ++x) {
                    m[d.index(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y),
                              static_cast<std::uint32_t>(z))] = 1;
                }
            }
        }
    }
    return m;
}

// Regions are inside the world, non-empty and pairwise disjoint.
void expect_valid_regions(const std::vector<Box>& regions, Dims d) {
    const Box world{{0, 0, 0}, {d.x, d.y, d.z}};
    for (std::size_t i = 0; i < regions.size(); ++i) {
        EXPECT_FALSE(regions[i].empty());
        EXPECT_EQ(intersect(regions[i], world), regions[i]);
        for (std::size_t j = i + 1; j < regions.size(); ++j) {
            EXPECT_TRUE(intersect(regions[i], regions[j]).empty()) << "regions " << i << ", " << j;
        }
    }
}

// Chunks containing at least one voxel of a region, by brute force over voxels.
std::vector<std::size_t> chunks_by_voxel(const std::vector<Box>& regions, const ChunkGrid& g) {
    std::set<std::size_t> s;
    const Dims d = g.world();
    const std::vector<char> m = mask_of(regions, d);
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                if (m[d.index(x, y, z)]) {
                    s.insert(g.chunk_index({x / g.chunk(), y / g.chunk(), z / g.chunk()}));
                }
            }
        }
    }
    return {s.begin(), s.end()};
}

TEST(Dirty, StartsEmpty) {
    const DirtyTracker t(ChunkGrid(Dims{16, 16, 16}, 8));
    EXPECT_TRUE(t.empty());
    EXPECT_TRUE(t.regions().empty());
    EXPECT_TRUE(t.dirty_chunks().empty());
    EXPECT_EQ(t.pending_voxels(), 0);
}

TEST(Dirty, SingleBoxAndClipping) {
    DirtyTracker t(ChunkGrid(Dims{20, 8, 33}, 8));
    t.add(Box{{-5, 2, 30}, {3, 100, 40}});
    EXPECT_EQ(t.regions(), (std::vector<Box>{{{0, 2, 30}, {3, 8, 33}}}));
    EXPECT_EQ(t.pending_voxels(), 3 * 6 * 3);
    // Chunk grid 3x1x5: x chunk 0, y chunk 0, z chunk 3 (24..31) and 4 (32).
    EXPECT_EQ(t.dirty_chunks(), (std::vector<std::size_t>{9, 12}));
}

TEST(Dirty, EmptyAndOutsideBoxesAreIgnored) {
    DirtyTracker t(ChunkGrid(Dims{16, 16, 16}, 8));
    t.add(Box{});
    t.add(Box{{3, 3, 3}, {3, 9, 9}});       // zero width
    t.add(Box{{5, 5, 5}, {2, 9, 9}});       // inverted
    t.add(Box{{16, 0, 0}, {20, 4, 4}});     // beyond +x
    t.add(Box{{-4, 0, 0}, {0, 4, 4}});      // before -x
    t.add(Box{{0, 0, -10}, {16, 16, -1}});  // before -z
    EXPECT_TRUE(t.empty());
    EXPECT_TRUE(t.dirty_chunks().empty());
}

TEST(Dirty, OverlappingAlignedBoxesMergeExactly) {
    for (double slack : {kExact, 0.25, kAlwaysMerge}) {
        DirtyTracker t(ChunkGrid(Dims{32, 32, 32}, 8), slack);
        t.add(Box{{2, 3, 4}, {10, 7, 9}});
        t.add(Box{{6, 3, 4}, {15, 7, 9}});  // overlaps in x, same y and z
        EXPECT_EQ(t.regions(), (std::vector<Box>{{{2, 3, 4}, {15, 7, 9}}})) << slack;
        t.add(Box{{4, 5, 5}, {8, 6, 8}});  // inside: nothing new
        EXPECT_EQ(t.regions(), (std::vector<Box>{{{2, 3, 4}, {15, 7, 9}}})) << slack;
        t.add(Box{{0, 0, 0}, {32, 32, 32}});  // swallows everything
        EXPECT_EQ(t.regions(), (std::vector<Box>{{{0, 0, 0}, {32, 32, 32}}})) << slack;
        EXPECT_EQ(t.pending_voxels(), 32 * 32 * 32);
    }
}

TEST(Dirty, TouchingBoxesMerge) {
    for (double slack : {kExact, 0.25, kAlwaysMerge}) {
        DirtyTracker t(ChunkGrid(Dims{32, 32, 32}, 8), slack);
        t.add(Box{{0, 0, 0}, {4, 4, 4}});
        t.add(Box{{4, 0, 0}, {8, 4, 4}});  // shares the face x = 4
        t.add(Box{{0, 4, 0}, {8, 6, 4}});  // shares the face y = 4 with both
        t.add(Box{{0, 0, 4}, {8, 6, 5}});  // shares the face z = 4
        EXPECT_EQ(t.regions(), (std::vector<Box>{{{0, 0, 0}, {8, 6, 5}}})) << slack;
    }
    // Not touching (a gap of one voxel): kept apart even when always merging.
    DirtyTracker t(ChunkGrid(Dims{32, 32, 32}, 8), kAlwaysMerge);
    t.add(Box{{0, 0, 0}, {4, 4, 4}});
    t.add(Box{{5, 0, 0}, {8, 4, 4}});
    EXPECT_EQ(t.regions(), (std::vector<Box>{{{0, 0, 0}, {4, 4, 4}}, {{5, 0, 0}, {8, 4, 4}}}));
}

TEST(Dirty, AlwaysMergeGivesBoundingBoxes) {
    DirtyTracker t(ChunkGrid(Dims{32, 32, 32}, 8), kAlwaysMerge);
    t.add(Box{{0, 0, 0}, {4, 4, 4}});
    t.add(Box{{2, 2, 2}, {10, 5, 6}});   // overlaps: bounding box
    t.add(Box{{10, 5, 6}, {12, 8, 9}});  // touches only at the corner (10, 5, 6): merged too
    EXPECT_EQ(t.regions(), (std::vector<Box>{{{0, 0, 0}, {12, 8, 9}}}));
    // A chain: a new box touching two separate regions pulls them all into one.
    DirtyTracker u(ChunkGrid(Dims{32, 32, 32}, 8), kAlwaysMerge);
    u.add(Box{{0, 0, 0}, {2, 2, 2}});
    u.add(Box{{20, 0, 0}, {22, 2, 2}});
    EXPECT_EQ(u.regions().size(), 2u);
    u.add(Box{{1, 1, 1}, {21, 2, 2}});
    EXPECT_EQ(u.regions(), (std::vector<Box>{{{0, 0, 0}, {22, 2, 2}}}));
}

TEST(Dirty, ExactModeSplitsOverlapsWithoutDuplicates) {
    const Dims d{16, 16, 16};
    DirtyTracker t(ChunkGrid(d, 4), kExact);
    const std::vector<Box> added = {{{0, 0, 0}, {6, 6, 6}}, {{3, 3, 3}, {9, 9, 9}}};
    for (const Box& b : added) {
        t.add(b);
    }
    const std::vector<Box> regions = t.regions();
    expect_valid_regions(regions, d);
    EXPECT_GT(regions.size(), 1u);
    // Exactly the union: 216 + 216 - 27 voxels, none twice.
    EXPECT_EQ(t.pending_voxels(), 216 + 216 - 27);
    EXPECT_EQ(mask_of(regions, d), mask_of(added, d));
}

TEST(Dirty, SlackMergesNearlyBoxShapedUnions) {
    const Dims d{64, 64, 64};
    // Two 10³ boxes offset by (1, 1, 0): the bounding box 11x11x10 = 1210 voxels has
    // 1210 - (2000 - 810) = 20 more than the union, 1.7%.
    const Box a{{0, 0, 0}, {10, 10, 10}}, b{{1, 1, 0}, {11, 11, 10}};
    DirtyTracker loose(ChunkGrid(d, 8), 0.25);
    loose.add(a);
    loose.add(b);
    EXPECT_EQ(loose.regions(), (std::vector<Box>{{{0, 0, 0}, {11, 11, 10}}}));
    DirtyTracker exact(ChunkGrid(d, 8), kExact);
    exact.add(a);
    exact.add(b);
    EXPECT_EQ(exact.pending_voxels(), 1190);
    // Two boxes meeting only at an edge: the bounding box doubles the voxels, over any
    // reasonable slack, so they stay two regions.
    DirtyTracker edge(ChunkGrid(d, 8), 0.25);
    edge.add(Box{{0, 0, 0}, {4, 4, 8}});
    edge.add(Box{{4, 4, 0}, {8, 8, 8}});
    EXPECT_EQ(edge.regions().size(), 2u);
    EXPECT_EQ(edge.pending_voxels(), 2 * 128);
}

TEST(Dirty, RandomBoxesStayDisjointAndCoverEverything) {
    const Dims d{23, 17, 29};
    const ChunkGrid g(d, 8);
    std::mt19937 rng(99);
    for (double slack : {kExact, 0.1, 0.25, 1.0, kAlwaysMerge}) {
        for (int round = 0; round < 30; ++round) {
            DirtyTracker t(g, slack);
            std::vector<Box> added;
            const int n = 1 + static_cast<int>(rng() % 12);
            for (int i = 0; i < n; ++i) {
                Box b;
                b.min = {static_cast<std::int64_t>(rng() % 30) - 4,
                         static_cast<std::int64_t>(rng() % 24) - 4,
                         static_cast<std::int64_t>(rng() % 36) - 4};
                b.max = {b.min.x + static_cast<std::int64_t>(rng() % 9),
                         b.min.y + static_cast<std::int64_t>(rng() % 9),
                         b.min.z + static_cast<std::int64_t>(rng() % 9)};
                added.push_back(b);
                t.add(b);
            }
            const std::vector<Box> regions = t.regions();
            expect_valid_regions(regions, d);
            const std::vector<char> got = mask_of(regions, d);
            const std::vector<char> want = mask_of(added, d);
            std::int64_t covered = 0;
            for (std::size_t i = 0; i < want.size(); ++i) {
                EXPECT_TRUE(!want[i] || got[i]) << "voxel " << i << " lost";
                covered += got[i];
            }
            EXPECT_EQ(covered, t.pending_voxels());  // disjoint: volumes add up
            if (slack == kExact) {
                EXPECT_EQ(got, want);
            }
            EXPECT_TRUE(
                std::is_sorted(regions.begin(), regions.end(), [](const Box& x, const Box& y) {
                    return std::tie(x.min.z, x.min.y, x.min.x) <
                           std::tie(y.min.z, y.min.y, y.min.x);
                }));
            EXPECT_EQ(t.dirty_chunks(), chunks_by_voxel(regions, g));
        }
    }
}

TEST(Dirty, ChunkMappingAtChunkBorders) {
    const ChunkGrid g(Dims{20, 8, 33}, 8);  // chunks 3x1x5, the last x and z ones partial
    auto chunks_for = [&](const Box& b) {
        DirtyTracker t(g);
        t.add(b);
        return t.dirty_chunks();
    };
    // The last voxel of chunk 0, the first of chunk 1, and both.
    EXPECT_EQ(chunks_for({{7, 0, 0}, {8, 1, 1}}), (std::vector<std::size_t>{0}));
    EXPECT_EQ(chunks_for({{8, 0, 0}, {9, 1, 1}}), (std::vector<std::size_t>{1}));
    EXPECT_EQ(chunks_for({{7, 0, 0}, {9, 1, 1}}), (std::vector<std::size_t>{0, 1}));
    // max is exclusive: [0, 8) stays in chunk 0.
    EXPECT_EQ(chunks_for({{0, 0, 0}, {8, 8, 8}}), (std::vector<std::size_t>{0}));
    // Along z the index steps by 3 (x fastest, then y, then z).
    EXPECT_EQ(chunks_for({{0, 0, 7}, {1, 1, 9}}), (std::vector<std::size_t>{0, 3}));
    // Partial chunks at the far faces: x 16..19 is chunk 2, z 32 is chunk 4.
    EXPECT_EQ(chunks_for({{16, 0, 32}, {20, 8, 33}}), (std::vector<std::size_t>{14}));
    EXPECT_EQ(chunks_for({{18, 7, 31}, {50, 50, 50}}), (std::vector<std::size_t>{11, 14}));
    // From outside the world at -x: clipped, never a negative chunk.
    EXPECT_EQ(chunks_for({{-9, 0, 0}, {1, 1, 1}}), (std::vector<std::size_t>{0}));
    // The whole world: every chunk once.
    std::vector<std::size_t> all(15);
    for (std::size_t i = 0; i < all.size(); ++i) {
        all[i] = i;
    }
    EXPECT_EQ(chunks_for({{-1, -1, -1}, {100, 100, 100}}), all);
}

TEST(Dirty, DirtyChunksHaveNoDuplicates) {
    DirtyTracker t(ChunkGrid(Dims{32, 32, 32}, 8), kExact);
    t.add(Box{{0, 0, 0}, {3, 3, 3}});
    t.add(Box{{5, 5, 5}, {7, 7, 7}});        // same chunk, disjoint box
    t.add(Box{{6, 0, 0}, {10, 2, 2}});       // chunks 0 and 1
    t.add(Box{{30, 30, 30}, {32, 32, 32}});  // the last chunk
    EXPECT_EQ(t.regions().size(), 4u);
    EXPECT_EQ(t.dirty_chunks(), (std::vector<std::size_t>{0, 1, 63}));
}

TEST(Dirty, MergedRegionsMarkEveryChunkTheyCover) {
    // Two boxes meeting at an edge, in chunks 0 and 3 of a 2x2x1 grid: always-merge joins them
    // into a bounding box that also covers chunks 1 and 2, which are then dirty.
    DirtyTracker t(ChunkGrid(Dims{16, 16, 8}, 8), kAlwaysMerge);
    t.add(Box{{0, 0, 0}, {8, 8, 1}});
    t.add(Box{{8, 8, 0}, {16, 16, 1}});
    EXPECT_EQ(t.regions(), (std::vector<Box>{{{0, 0, 0}, {16, 16, 1}}}));
    EXPECT_EQ(t.dirty_chunks(), (std::vector<std::size_t>{0, 1, 2, 3}));
    EXPECT_EQ(t.take().chunks, (std::vector<std::size_t>{0, 1, 2, 3}));
}

TEST(Dirty, TakeClearsPending) {
    DirtyTracker t(ChunkGrid(Dims{16, 16, 8}, 8));  // chunks 2x2x1
    t.add(Box{{1, 1, 1}, {3, 3, 3}});
    t.add(Box{{1, 1, 1}, {2, 2, 2}});
    t.add(Box{{10, 10, 0}, {12, 12, 8}});
    const DirtyTracker::Snapshot s = t.take();
    EXPECT_EQ(s.regions, (std::vector<Box>{{{10, 10, 0}, {12, 12, 8}}, {{1, 1, 1}, {3, 3, 3}}}));
    EXPECT_EQ(s.chunks, (std::vector<std::size_t>{0, 3}));
    EXPECT_TRUE(t.empty());
    EXPECT_TRUE(t.regions().empty());
    EXPECT_TRUE(t.dirty_chunks().empty());
    const DirtyTracker::Snapshot none = t.take();
    EXPECT_TRUE(none.regions.empty());
    EXPECT_TRUE(none.chunks.empty());
}

TEST(Dirty, RejectsNegativeSlack) {
    const ChunkGrid g(Dims{8, 8, 8}, 4);
    EXPECT_THROW(DirtyTracker(g, -0.5), std::invalid_argument);
    EXPECT_THROW(DirtyTracker(g, std::numeric_limits<double>::quiet_NaN()), std::invalid_argument);
    EXPECT_EQ(DirtyTracker(g).merge_slack(), 0.25);
    EXPECT_EQ(DirtyTracker(g, kAlwaysMerge).merge_slack(), kAlwaysMerge);
}

}  // namespace
}  // namespace voxfield
