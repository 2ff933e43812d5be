#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "test_util.hpp"
#include "voxfield/core/sand.hpp"
#include "voxfield/core/scenes.hpp"

namespace voxfield {
namespace {

using test::expect_input_error;

TEST(Scenes, Empty) {
    const World w = scene_empty(Dims{4, 5, 6});
    EXPECT_EQ(w.dims(), (Dims{4, 5, 6}));
    EXPECT_EQ(w.solid_count(), 0u);
}

TEST(Scenes, FloorSpheresDeterministicAndSeeded) {
    const Dims d{48, 40, 56};
    const World a = scene_floor_spheres(d, 1);
    const World b = scene_floor_spheres(d, 1);
    const World c = scene_floor_spheres(d, 2);
    EXPECT_EQ(a.voxels(), b.voxels());
    EXPECT_NE(a.voxels(), c.voxels());
    // Floor: every voxel at y = 0 is solid.
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t x = 0; x < d.x; ++x) {
            ASSERT_NE(a.at(x, 0, z), 0);
        }
    }
    // Spheres add solid voxels above the floor, all with dissertation colours 1..11.
    std::size_t above = 0;
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 1; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                const auto v = a.at(x, y, z);
                ASSERT_LE(v, 11);
                above += v != 0 ? 1 : 0;
            }
        }
    }
    EXPECT_GT(above, 0u);
    // Radius at most min dim / 8 = 5, so 16 spheres hold at most 16 * (4/3 pi 5^3) voxels.
    EXPECT_LE(above, 16u * 524u);
    EXPECT_EQ(scene_floor_spheres(d, 1, 0).solid_count(), std::size_t{d.x} * d.z);
    // Tiny worlds work.
    EXPECT_EQ(scene_floor_spheres(Dims{1, 1, 1}, 3).solid_count(), 1u);
}

TEST(Scenes, TerrainDeterministicAndHeightmap) {
    const Dims d{40, 32, 24};
    const World a = scene_terrain(d, 5);
    EXPECT_EQ(a.voxels(), scene_terrain(d, 5).voxels());
    EXPECT_NE(a.voxels(), scene_terrain(d, 6).voxels());
    std::uint32_t lo = d.y, hi = 0;
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t x = 0; x < d.x; ++x) {
            std::uint32_t h = 0;
            while (h < d.y && a.at(x, h, z) != 0) {
                ++h;
            }
            for (std::uint32_t y = h; y < d.y; ++y) {
                ASSERT_EQ(a.at(x, y, z), 0) << "overhang at " << x << "," << y << "," << z;
            }
            ASSERT_GE(h, 1u);
            lo = std::min(lo, h);
            hi = std::max(hi, h);
        }
    }
    EXPECT_LT(lo, hi);  // not flat
}

TEST(Scenes, MengerHasHoles) {
    const World m = scene_menger(Dims{27, 27, 27});
    // Level 3 sponge: 20^3 solid cells of 27^3.
    EXPECT_EQ(m.solid_count(), 8000u);
    EXPECT_EQ(m.at(13, 13, 13), 0);  // the centre tunnel crossing
    EXPECT_EQ(m.at(13, 13, 0), 0);   // the face-centre tunnel goes through
    EXPECT_NE(m.at(0, 0, 0), 0);
    EXPECT_EQ(m.at(1, 1, 0), 0);  // level-1 hole in the first sub-cube
    EXPECT_NE(m.at(1, 0, 0), 0);
    EXPECT_EQ(scene_menger(Dims{9, 9, 9}).solid_count(), 400u);
    EXPECT_EQ(scene_menger(Dims{2, 2, 2}).solid_count(), 8u);  // level 0: a full cube
    // Scaled to a non-cubic world: 54x30x27 is level 3 scaled by 2 along x.
    const World s = scene_menger(Dims{54, 30, 27});
    EXPECT_GT(s.solid_count(), 0u);
    EXPECT_LT(s.solid_count(), s.size());
    EXPECT_EQ(s.at(27, 15, 13), 0);
    EXPECT_EQ(s.at(0, 0, 0), m.at(0, 0, 0));
}

TEST(Scenes, RandomDensity) {
    const Dims d{32, 32, 32};
    for (double density : {0.0, 0.05, 0.3, 0.9, 1.0}) {
        const World w = scene_random(d, density, 11);
        const double got = static_cast<double>(w.solid_count()) / static_cast<double>(w.size());
        EXPECT_NEAR(got, density, 0.02) << density;
    }
    EXPECT_EQ(scene_random(d, 0.0, 1).solid_count(), 0u);
    EXPECT_EQ(scene_random(d, 1.0, 1).solid_count(), d.count());
    EXPECT_EQ(scene_random(d, 0.4, 9).voxels(), scene_random(d, 0.4, 9).voxels());
    EXPECT_NE(scene_random(d, 0.4, 9).voxels(), scene_random(d, 0.4, 10).voxels());
    // Colours spread over 1..255.
    const World full = scene_random(d, 1.0, 3);
    std::vector<bool> seen(256, false);
    for (auto v : full.voxels()) {
        seen[v] = true;
    }
    EXPECT_FALSE(seen[0]);
    EXPECT_TRUE(seen[1]);
    EXPECT_TRUE(seen[255]);
    for (double bad : {-0.1, 1.5, std::numeric_limits<double>::quiet_NaN()}) {
        expect_input_error([&] { scene_random(d, bad, 1); }, {"density"});
    }
}

TEST(Scenes, MakeSceneByName) {
    const Dims d{16, 16, 16};
    EXPECT_EQ(scene_names(), (std::vector<std::string>{"empty", "spheres", "terrain", "menger",
                                                       "random", "sand", "city"}));
    EXPECT_EQ(make_scene("empty", d, 1).solid_count(), 0u);
    EXPECT_EQ(make_scene("spheres", d, 4).voxels(), scene_floor_spheres(d, 4).voxels());
    EXPECT_EQ(make_scene("terrain", d, 4).voxels(), scene_terrain(d, 4).voxels());
    EXPECT_EQ(make_scene("menger", d, 4).voxels(), scene_menger(d).voxels());
    EXPECT_EQ(make_scene("random", d, 4).voxels(), scene_random(d, 0.1, 4).voxels());
    EXPECT_EQ(make_scene("sand", d, 4).voxels(), scene_sand(d, 4).voxels());
    EXPECT_EQ(make_scene("city", d, 4).voxels(), scene_city(d, 4).voxels());
    expect_input_error([&] { make_scene("cube", d, 1); },
                       {"'cube'", "empty, spheres, terrain, menger, random"});
}

// The city's voxels of `box`, filled on their own.
std::vector<std::uint8_t> fill_box(const CityScene& city, const Box& box) {
    std::vector<std::uint8_t> out(static_cast<std::size_t>(box.volume()));
    city.fill(box, out);
    return out;
}

TEST(Scenes, CityDeterministicAndSeeded) {
    const Dims d{200, 90, 170};
    const World a = scene_city(d, 11);
    EXPECT_EQ(a.voxels(), scene_city(d, 11).voxels());
    EXPECT_NE(a.voxels(), scene_city(d, 12).voxels());
    EXPECT_GT(a.solid_count(), 0u);
    EXPECT_LT(a.solid_count(), a.size());
}

TEST(Scenes, CityBoxFillsEqualTheWholeWorld) {
    // Tiles of 64^3 cut by the world's edge on every axis, then random boxes.
    const Dims d{300, 96, 260};
    const CityScene city(d, 5);
    const World whole = scene_city(d, 5);
    std::size_t wrong = 0;
    for (std::int64_t z0 = 0; z0 < d.z; z0 += 64) {
        for (std::int64_t y0 = 0; y0 < d.y; y0 += 64) {
            for (std::int64_t x0 = 0; x0 < d.x; x0 += 64) {
                const Box b{
                    {x0, y0, z0},
                    {std::min<std::int64_t>(x0 + 64, d.x), std::min<std::int64_t>(y0 + 64, d.y),
                     std::min<std::int64_t>(z0 + 64, d.z)}};
                const auto got = fill_box(city, b);
                std::size_t i = 0;
                for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
                    for (std::int64_t y = b.min.y; y < b.max.y; ++y) {
                        for (std::int64_t x = b.min.x; x < b.max.x; ++x) {
                            wrong += got[i++] != whole.at(static_cast<std::uint32_t>(x),
                                                          static_cast<std::uint32_t>(y),
                                                          static_cast<std::uint32_t>(z));
                        }
                    }
                }
            }
        }
    }
    EXPECT_EQ(wrong, 0u);
    std::mt19937_64 rng(9);
    for (int k = 0; k < 50; ++k) {
        Box b;
        const std::array<std::uint32_t, 3> n = {d.x, d.y, d.z};
        std::array<std::int64_t, 3> lo{}, hi{};
        for (std::size_t a = 0; a < 3; ++a) {
            lo[a] = static_cast<std::int64_t>(rng() % n[a]);
            hi[a] = lo[a] + 1 + static_cast<std::int64_t>(rng() % (n[a] - lo[a]));
        }
        b = Box{{lo[0], lo[1], lo[2]}, {hi[0], hi[1], hi[2]}};
        const auto got = fill_box(city, b);
        std::size_t i = 0, bad = 0;
        for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
            for (std::int64_t y = b.min.y; y < b.max.y; ++y) {
                for (std::int64_t x = b.min.x; x < b.max.x; ++x) {
                    bad += got[i++] != whole.at(static_cast<std::uint32_t>(x),
                                                static_cast<std::uint32_t>(y),
                                                static_cast<std::uint32_t>(z));
                }
            }
        }
        EXPECT_EQ(bad, 0u) << "box " << k;
    }
}

TEST(Scenes, CityHasTerrainWaterRoadsAndBuildings) {
    // Materials: 3 rock, 10 grass, 2 snow, 7 water, 1 road, 4/5/6/11 walls, 8 windows, 9 roofs.
    std::array<std::uint64_t, 256> counts{};
    for (const std::uint64_t seed : {1u, 2u, 3u}) {
        const World w = scene_city(Dims{512, 128, 512}, seed);
        for (const std::uint8_t v : w.voxels()) {
            ++counts[v];
        }
        // Every column is solid from y = 0 up to its top, except above a building's roof.
        const World& c = w;
        for (std::uint32_t z = 0; z < 512; z += 37) {
            for (std::uint32_t x = 0; x < 512; x += 41) {
                EXPECT_NE(c.at(x, 0, z), 0) << x << "," << z;
            }
        }
    }
    for (const int m : {3, 10, 7, 1, 8, 9}) {
        EXPECT_GT(counts[static_cast<std::size_t>(m)], 0u) << "material " << m;
    }
    EXPECT_GT(counts[4] + counts[5] + counts[6] + counts[11], 0u);
}

TEST(Scenes, CityOfAnySizeFillsTileByTile) {
    // 4096 x 512 x 4096 (8.6 G voxels) is never made dense: a few of its tiles are filled, and a
    // tile equals its halves filled on their own.
    const CityScene city(Dims{4096, 512, 4096}, 42);
    std::mt19937_64 rng(1);
    std::size_t solid = 0;
    for (int k = 0; k < 12; ++k) {
        const std::int64_t x0 = static_cast<std::int64_t>(rng() % 64) * 64;
        const std::int64_t y0 = static_cast<std::int64_t>(rng() % 8) * 64;
        const std::int64_t z0 = static_cast<std::int64_t>(rng() % 64) * 64;
        const Box tile{{x0, y0, z0}, {x0 + 64, y0 + 64, z0 + 64}};
        const auto whole = fill_box(city, tile);
        const auto low = fill_box(city, Box{{x0, y0, z0}, {x0 + 64, y0 + 64, z0 + 32}});
        const auto high = fill_box(city, Box{{x0, y0, z0 + 32}, {x0 + 64, y0 + 64, z0 + 64}});
        EXPECT_TRUE(std::equal(low.begin(), low.end(), whole.begin()));
        EXPECT_TRUE(std::equal(high.begin(), high.end(), whole.begin() + 64 * 64 * 32));
        solid += static_cast<std::size_t>(
            std::count_if(whole.begin(), whole.end(), [](std::uint8_t v) { return v != 0; }));
    }
    EXPECT_GT(solid, 0u);
    // Refused: a box outside the world, a wrong buffer, a world over 2^20 per axis.
    std::vector<std::uint8_t> small(8);
    expect_input_error(
        [&] {
            city.fill(Box{{4095, 0, 0}, {4097, 2, 2}}, small);
        },
        {"does not fit the world 4096x512x4096"});
    expect_input_error([&] { city.fill(Box{{0, 0, 0}, {2, 2, 3}}, small); }, {"8 bytes"});
    expect_input_error([&] { CityScene(Dims{1u << 21, 4, 4}, 1); }, {"city scene", "1048576"});
}

}  // namespace
}  // namespace voxfield
