// SparseWorld (core/sparse.hpp): dense <-> sparse round trips, lookups, the 64-tree layout,
// the tile hash and edits, against dense worlds.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <mutex>
#include <random>
#include <vector>

#include "voxfield/core/brush.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/sparse.hpp"

namespace voxfield {
namespace {

World random_world(Dims d, double density, std::mt19937& rng) {
    World w(d);
    std::bernoulli_distribution solid(density);
    std::uniform_int_distribution<int> material(1, 255);
    for (auto& v : w.voxels()) {
        v = solid(rng) ? static_cast<std::uint8_t>(material(rng)) : 0;
    }
    return w;
}

// Random solid blobs (boxes) in an otherwise empty world: empty tiles between solid ones.
World blob_world(Dims d, int blobs, std::mt19937& rng) {
    World w(d);
    for (int b = 0; b < blobs; ++b) {
        const auto cx = std::uniform_int_distribution<std::uint32_t>(0, d.x - 1)(rng);
        const auto cy = std::uniform_int_distribution<std::uint32_t>(0, d.y - 1)(rng);
        const auto cz = std::uniform_int_distribution<std::uint32_t>(0, d.z - 1)(rng);
        const auto r = std::uniform_int_distribution<std::uint32_t>(0, 6)(rng);
        const auto m = static_cast<std::uint8_t>(std::uniform_int_distribution<int>(1, 255)(rng));
        for (std::uint32_t z = cz > r ? cz - r : 0; z <= std::min(d.z - 1, cz + r); ++z) {
            for (std::uint32_t y = cy > r ? cy - r : 0; y <= std::min(d.y - 1, cy + r); ++y) {
                for (std::uint32_t x = cx > r ? cx - r : 0; x <= std::min(d.x - 1, cx + r); ++x) {
                    w.set(x, y, z, m);
                }
            }
        }
    }
    return w;
}

// Every structural invariant of the flat buffers, checked against the world's voxels.
void expect_consistent(const SparseWorld& s, const World& w) {
    ASSERT_EQ(s.dims(), w.dims());
    EXPECT_EQ(s.solid_count(), w.solid_count());
    std::uint64_t materials = 0;
    for (std::uint32_t t = 0; t < s.tile_count(); ++t) {
        const Int3 c = s.tile_coord(t);
        EXPECT_EQ(s.find_tile(c.x, c.y, c.z), t);
        const std::uint64_t base = s.node_bases()[t];
        const std::uint64_t root = s.node_masks()[base];
        EXPECT_NE(root, 0u) << "a stored tile holds a solid voxel";
        std::uint64_t nodes = 1 + static_cast<std::uint64_t>(std::popcount(root));
        for (int i = 0; i < std::popcount(root); ++i) {
            const std::uint64_t mid = s.node_masks()[base + 1 + i];
            EXPECT_NE(mid, 0u);
            nodes += static_cast<std::uint64_t>(std::popcount(mid));
        }
        EXPECT_EQ(nodes, s.node_counts()[t]);
        materials += s.material_counts()[t];
        const Box sb = s.solid_bounds(t);
        EXPECT_FALSE(sb.empty());
        for (std::int64_t z = sb.min.z; z < sb.max.z; ++z) {
            for (std::int64_t y = sb.min.y; y < sb.max.y; ++y) {
                for (std::int64_t x = sb.min.x; x < sb.max.x; ++x) {
                    ASSERT_TRUE(w.dims().contains(x, y, z));
                }
            }
        }
    }
    EXPECT_EQ(materials, s.solid_count());
    // Every tile with a solid voxel is stored; no other.
    std::uint64_t tiles_with_solids = 0;
    const Dims g = s.tile_grid();
    for (std::uint32_t tz = 0; tz < g.z; ++tz) {
        for (std::uint32_t ty = 0; ty < g.y; ++ty) {
            for (std::uint32_t tx = 0; tx < g.x; ++tx) {
                bool any = false;
                Box sb{};
                for (std::uint32_t z = tz * 64; z < std::min(w.dims().z, tz * 64 + 64); ++z) {
                    for (std::uint32_t y = ty * 64; y < std::min(w.dims().y, ty * 64 + 64); ++y) {
                        for (std::uint32_t x = tx * 64; x < std::min(w.dims().x, tx * 64 + 64);
                             ++x) {
                            if (w.at(x, y, z) != 0) {
                                any = true;
                                sb = hull(sb, Box{{x, y, z}, {x + 1, y + 1, z + 1}});
                            }
                        }
                    }
                }
                const std::uint32_t t = s.find_tile(tx, ty, tz);
                EXPECT_EQ(t != kNoTile, any) << "tile " << tx << "," << ty << "," << tz;
                if (any && t != kNoTile) {
                    EXPECT_EQ(s.solid_bounds(t), sb);
                }
                tiles_with_solids += any ? 1 : 0;
            }
        }
    }
    EXPECT_EQ(tiles_with_solids, s.tile_count());
    EXPECT_EQ(s.find_tile(-1, 0, 0), kNoTile);
    EXPECT_EQ(s.find_tile(g.x, 0, 0), kNoTile);
    // Lookups and the dense round trip.
    for (std::uint32_t z = 0; z < w.dims().z; ++z) {
        for (std::uint32_t y = 0; y < w.dims().y; ++y) {
            for (std::uint32_t x = 0; x < w.dims().x; ++x) {
                ASSERT_EQ(s.at(x, y, z), w.at(x, y, z)) << x << "," << y << "," << z;
            }
        }
    }
    EXPECT_EQ(s.to_dense().voxels(), w.voxels());
}

const Dims kSizes[] = {{1, 1, 1},   {64, 64, 64},  {65, 63, 1},    {130, 70, 66},
                       {3, 200, 5}, {128, 1, 129}, {100, 100, 100}};

TEST(SparseWorld, RoundTripsRandomWorldsOfAwkwardSizes) {
    std::mt19937 rng(11);
    for (const Dims& d : kSizes) {
        for (double density : {0.0, 0.001, 0.05, 0.5, 1.0}) {
            SCOPED_TRACE(d.to_string() + " density " + std::to_string(density));
            const World w = random_world(d, density, rng);
            expect_consistent(SparseWorld::from_dense(w), w);
        }
    }
}

TEST(SparseWorld, RoundTripsBlobsWithEmptyTilesBetween) {
    std::mt19937 rng(12);
    for (int i = 0; i < 6; ++i) {
        const Dims d{std::uniform_int_distribution<std::uint32_t>(1, 300)(rng),
                     std::uniform_int_distribution<std::uint32_t>(1, 150)(rng),
                     std::uniform_int_distribution<std::uint32_t>(1, 200)(rng)};
        SCOPED_TRACE(d.to_string());
        const World w = blob_world(d, 12, rng);
        expect_consistent(SparseWorld::from_dense(w), w);
    }
}

TEST(SparseWorld, BuildsFromABoxFillTileByTile) {
    const Dims d{200, 90, 131};
    std::vector<Box> boxes;
    std::mutex boxes_mutex;  // from_fill calls the fill from several threads
    const SparseWorld s = SparseWorld::from_fill(d, [&](const Box& b, std::span<std::uint8_t> out) {
        {
            const std::lock_guard<std::mutex> lock(boxes_mutex);
            boxes.push_back(b);
        }
        ASSERT_EQ(out.size(), static_cast<std::size_t>(b.volume()));
        std::size_t i = 0;
        for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
            for (std::int64_t y = b.min.y; y < b.max.y; ++y) {
                for (std::int64_t x = b.min.x; x < b.max.x; ++x) {
                    out[i++] =
                        y < 20 + (x * 7 + z * 3) % 40 ? static_cast<std::uint8_t>(1 + x % 7) : 0;
                }
            }
        }
    });
    // Every column of tiles (x, z) once, all its 2 tiles along y in one box, clipped.
    EXPECT_EQ(boxes.size(), 4u * 3u);
    std::int64_t volume = 0;
    for (const Box& b : boxes) {
        EXPECT_LE(b.max.x - b.min.x, 64);
        EXPECT_LE(b.max.z - b.min.z, 64);
        EXPECT_EQ(b.min.y, 0);
        EXPECT_LE(b.max.x, d.x);
        EXPECT_EQ(b.max.y, d.y);
        EXPECT_LE(b.max.z, d.z);
        volume += b.volume();
    }
    EXPECT_EQ(volume, static_cast<std::int64_t>(d.count()));
    World w(d);
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                w.set(x, y, z,
                      y < 20 + (x * 7 + z * 3) % 40 ? static_cast<std::uint8_t>(1 + x % 7) : 0);
            }
        }
    }
    expect_consistent(s, w);
}

// A world taller than 16 tiles: its columns of tiles are filled 16 tiles at a time.
TEST(SparseWorld, BuildsTallWorldsSixteenTilesAtATime) {
    const Dims d{70, 1100, 10};
    std::vector<Box> boxes;
    std::mutex boxes_mutex;
    auto value = [](std::int64_t x, std::int64_t y, std::int64_t z) -> std::uint8_t {
        return (x + 3 * y + 5 * z) % 11 < 2 ? static_cast<std::uint8_t>(1 + y % 9) : 0;
    };
    const SparseWorld s = SparseWorld::from_fill(d, [&](const Box& b, std::span<std::uint8_t> out) {
        {
            const std::lock_guard<std::mutex> lock(boxes_mutex);
            boxes.push_back(b);
        }
        std::size_t i = 0;
        for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
            for (std::int64_t y = b.min.y; y < b.max.y; ++y) {
                for (std::int64_t x = b.min.x; x < b.max.x; ++x) {
                    out[i++] = value(x, y, z);
                }
            }
        }
    });
    EXPECT_EQ(boxes.size(), 2u * 2u);  // 2 columns along x, 18 tiles along y in 16 + 2
    for (const Box& b : boxes) {
        EXPECT_TRUE(b.min.y == 0 ? b.max.y == 1024 : b.min.y == 1024 && b.max.y == d.y);
    }
    World w(d);
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                w.set(x, y, z, value(x, y, z));
            }
        }
    }
    expect_consistent(s, w);
}

// The tiles are filled and encoded on several threads: any thread count gives the same
// buffers, tile for tile, as one thread (a world of 7 x 3 x 5 tiles, cut by its edges).
TEST(SparseWorld, FromFillIsTheSameOnAnyNumberOfThreads) {
    const Dims d{420, 150, 300};
    auto fill = [&](const Box& b, std::span<std::uint8_t> out) {
        std::size_t i = 0;
        for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
            for (std::int64_t y = b.min.y; y < b.max.y; ++y) {
                for (std::int64_t x = b.min.x; x < b.max.x; ++x) {
                    const std::int64_t h = 10 + (x * 13 + z * 7) % 90;
                    out[i++] = y < h && (x / 64 + z / 64) % 3 != 1
                                   ? static_cast<std::uint8_t>(1 + (x + y) % 9)
                                   : 0;
                }
            }
        }
    };
    const SparseWorld one = SparseWorld::from_fill(d, fill, 1);
    EXPECT_GT(one.tile_count(), 20u);
    for (unsigned threads : {2u, 3u, 8u}) {
        SCOPED_TRACE(threads);
        const SparseWorld many = SparseWorld::from_fill(d, fill, threads);
        EXPECT_EQ(many.tile_coords(), one.tile_coords());
        EXPECT_EQ(many.node_masks(), one.node_masks());
        EXPECT_EQ(many.node_offsets(), one.node_offsets());
        EXPECT_EQ(many.materials(), one.materials());
        EXPECT_EQ(many.node_bases(), one.node_bases());
    }
}

// A fill that throws on some tile: from_fill rethrows it (whichever thread met it).
TEST(SparseWorld, FromFillPassesOnAFillsError) {
    const Dims d{300, 64, 300};
    auto fill = [&](const Box& b, std::span<std::uint8_t> out) {
        if (b.min.x == 128 && b.min.z == 192) {
            throw InputError("tile (2, 0, 3) cannot be filled");
        }
        std::fill(out.begin(), out.end(), std::uint8_t{1});
    };
    for (unsigned threads : {1u, 4u}) {
        EXPECT_THROW(SparseWorld::from_fill(d, fill, threads), InputError);
    }
}

TEST(SparseWorld, EncodesTheBlogsNodeLayout) {
    World w({64, 64, 64});
    w.set(5, 17, 40, 9);   // 16^3 child (0,1,2), 4^3 child (1,0,2), voxel (1,1,0)
    w.set(63, 63, 63, 3);  // the last child at every level
    const SparseWorld s = SparseWorld::from_dense(w);
    ASSERT_EQ(s.tile_count(), 1u);
    const auto& m = s.node_masks();
    const auto& o = s.node_offsets();
    ASSERT_EQ(m.size(), 5u);  // root, two 16^3 nodes, two leaves
    EXPECT_EQ(m[0], (1ull << (2 << 4 | 1 << 2 | 0)) | (1ull << 63));
    EXPECT_EQ(o[0], 1u);
    EXPECT_EQ(m[1], 1ull << (2 << 4 | 0 << 2 | 1));
    EXPECT_EQ(o[1], 3u);
    EXPECT_EQ(m[2], 1ull << 63);
    EXPECT_EQ(o[2], 4u);
    EXPECT_EQ(m[3], 1ull << (0 << 4 | 1 << 2 | 1));
    EXPECT_EQ(o[3], 0u);
    EXPECT_EQ(m[4], 1ull << 63);
    EXPECT_EQ(o[4], 1u);
    EXPECT_EQ(s.materials(), (std::vector<std::uint8_t>{9, 3}));
}

TEST(SparseWorld, RandomEditsMatchTheDenseWorld) {
    std::mt19937 rng(13);
    for (const Dims& d : {Dims{130, 70, 66}, Dims{64, 64, 64}, Dims{200, 33, 150}}) {
        SCOPED_TRACE(d.to_string());
        World w = blob_world(d, 6, rng);
        SparseWorld s = SparseWorld::from_dense(w);
        for (int e = 0; e < 60; ++e) {
            Brush b;
            b.op = static_cast<BrushOp>(std::uniform_int_distribution<int>(0, 2)(rng));
            b.shape = static_cast<BrushShape>(std::uniform_int_distribution<int>(0, 1)(rng));
            b.centre = {std::uniform_int_distribution<std::int64_t>(-5, d.x + 5)(rng),
                        std::uniform_int_distribution<std::int64_t>(-5, d.y + 5)(rng),
                        std::uniform_int_distribution<std::int64_t>(-5, d.z + 5)(rng)};
            b.radius = std::uniform_int_distribution<std::int64_t>(0, 20)(rng);
            b.material = static_cast<std::uint8_t>(std::uniform_int_distribution<int>(1, 255)(rng));
            const EditResult want = apply_brush(w, b);
            const Box got = apply_brush(s, b);
            EXPECT_EQ(got, want.bounds) << "edit " << e;
            if (e % 15 == 14) {
                expect_consistent(s, w);
            }
        }
        // Erase everything: no tile is left.
        const Box all{{0, 0, 0}, {d.x, d.y, d.z}};
        s.edit(all, [](std::int64_t, std::int64_t, std::int64_t, std::uint8_t) {
            return std::uint8_t{0};
        });
        EXPECT_EQ(s.tile_count(), 0u);
        EXPECT_EQ(s.solid_count(), 0u);
        expect_consistent(s, World(d));
    }
}

TEST(SparseWorld, SingleVoxelSetsAndCompaction) {
    std::mt19937 rng(14);
    const Dims d{150, 80, 70};
    World w(d);
    SparseWorld s(d);
    std::uniform_int_distribution<std::uint32_t> x(0, d.x - 1), y(0, d.y - 1), z(0, d.z - 1);
    std::uniform_int_distribution<int> v(0, 3);
    // Every set rewrites a tile: the garbage grows until compaction reclaims it.
    for (int i = 0; i < 3000; ++i) {
        const std::uint32_t px = x(rng), py = y(rng), pz = z(rng);
        const auto value = static_cast<std::uint8_t>(v(rng));
        w.set(px, py, pz, value);
        s.set(px, py, pz, value);
    }
    EXPECT_GT(s.layout_generation(), 0u) << "no compaction ran";
    expect_consistent(s, w);
    EXPECT_THROW(s.set(d.x, 0, 0, 1), InputError);
}

TEST(SparseWorld, ReadsBoxesAcrossTilesAndBeyondTheWorld) {
    std::mt19937 rng(15);
    const Dims d{140, 70, 90};
    const World w = random_world(d, 0.3, rng);
    const SparseWorld s = SparseWorld::from_dense(w);
    const Box box{{-7, 3, 60}, {150, 75, 70}};
    std::vector<std::uint8_t> out(static_cast<std::size_t>(box.volume()), 7);
    s.read_box(box, out);
    std::size_t i = 0;
    for (std::int64_t pz = box.min.z; pz < box.max.z; ++pz) {
        for (std::int64_t py = box.min.y; py < box.max.y; ++py) {
            for (std::int64_t px = box.min.x; px < box.max.x; ++px, ++i) {
                const std::uint8_t want =
                    d.contains(px, py, pz)
                        ? w.at(static_cast<std::uint32_t>(px), static_cast<std::uint32_t>(py),
                               static_cast<std::uint32_t>(pz))
                        : 0;
                ASSERT_EQ(out[i], want) << px << "," << py << "," << pz;
            }
        }
    }
}

TEST(SparseWorld, HugeWorldsStoreOnlyTheirSolidTiles) {
    const Dims d{kMaxSparseAxis, 1000, kMaxSparseAxis};
    SparseWorld s(d);
    EXPECT_EQ(s.tile_grid(), (Dims{16384, 16, 16384}));
    s.set(kMaxSparseAxis - 1, 999, kMaxSparseAxis - 1, 4);
    s.set(0, 0, 0, 5);
    s.set(524288, 500, 777777, 6);
    EXPECT_EQ(s.tile_count(), 3u);
    EXPECT_EQ(s.solid_count(), 3u);
    EXPECT_EQ(s.at(kMaxSparseAxis - 1, 999, kMaxSparseAxis - 1), 4);
    EXPECT_EQ(s.at(524288, 500, 777777), 6);
    EXPECT_EQ(s.at(524289, 500, 777777), 0);
    EXPECT_LT(s.bytes(), 1u << 20);
    EXPECT_THROW(s.to_dense(), InputError);
    EXPECT_THROW(SparseWorld(Dims{kMaxSparseAxis + 1, 1, 1}), InputError);
    EXPECT_THROW(SparseWorld(Dims{0, 1, 1}), InputError);
}

}  // namespace
}  // namespace voxfield
