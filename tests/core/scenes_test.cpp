#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
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
                                                       "random", "sand"}));
    EXPECT_EQ(make_scene("empty", d, 1).solid_count(), 0u);
    EXPECT_EQ(make_scene("spheres", d, 4).voxels(), scene_floor_spheres(d, 4).voxels());
    EXPECT_EQ(make_scene("terrain", d, 4).voxels(), scene_terrain(d, 4).voxels());
    EXPECT_EQ(make_scene("menger", d, 4).voxels(), scene_menger(d).voxels());
    EXPECT_EQ(make_scene("random", d, 4).voxels(), scene_random(d, 0.1, 4).voxels());
    EXPECT_EQ(make_scene("sand", d, 4).voxels(), scene_sand(d, 4).voxels());
    expect_input_error([&] { make_scene("cube", d, 1); },
                       {"'cube'", "empty, spheres, terrain, menger, random"});
}

}  // namespace
}  // namespace voxfield
