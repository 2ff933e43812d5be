// The falling-sand reference automaton (core/sand.hpp): the rules on small hand-made worlds,
// conservation, static solids, sand at rest, water levelling, determinism, the bench scene.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "test_util.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/sand.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield {
namespace {

constexpr std::uint8_t kSand = SandRules{}.sand, kWater = SandRules{}.water, kRock = 1;

std::array<std::size_t, 256> histogram(const World& w) {
    std::array<std::size_t, 256> h{};
    for (const std::uint8_t v : w.voxels()) {
        ++h[v];
    }
    return h;
}

// Static solids (not air, sand or water) at random, then sand and water in the rest.
World random_world(Dims dims, std::uint64_t seed, double rock, double sand, double water) {
    World w(dims);
    std::mt19937_64 gen(seed);
    std::uniform_real_distribution<double> u(0, 1);
    std::uniform_int_distribution<int> rock_material(4, 9);
    for (std::uint8_t& v : w.voxels()) {
        const double p = u(gen);
        v = p < rock                  ? static_cast<std::uint8_t>(rock_material(gen))
            : p < rock + sand         ? kSand
            : p < rock + sand + water ? kWater
                                      : std::uint8_t{0};
    }
    return w;
}

// The position of the only voxel of material m.
Int3 only(const World& w, std::uint8_t m) {
    std::vector<Int3> found;
    const Dims d = w.dims();
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                if (w.at(x, y, z) == m) {
                    found.push_back({x, y, z});
                }
            }
        }
    }
    EXPECT_EQ(found.size(), 1u);
    return found.empty() ? Int3{} : found[0];
}

// Runs steps 0, 1, ... until eight consecutive steps change nothing; returns the number of
// steps run, or 0 when `limit` steps were not enough.
std::uint64_t run_until_still(World& w, std::uint64_t seed, std::uint64_t limit) {
    std::uint64_t quiet = 0;
    for (std::uint64_t step = 0; step < limit; ++step) {
        quiet = sand_step(w, SandRules{}, seed, step).empty() ? quiet + 1 : 0;
        if (quiet == 8) {  // a whole cycle of block offsets without a move: nothing can move
            return step + 1;
        }
    }
    return 0;
}

void floor_of(World& w, std::uint8_t material) {
    for (std::uint32_t z = 0; z < w.dims().z; ++z) {
        for (std::uint32_t x = 0; x < w.dims().x; ++x) {
            w.set(x, 0, z, material);
        }
    }
}

TEST(Sand, RulesAreChecked) {
    test::expect_input_error([] { check_sand_rules({0, 3}); }, {"1..255", "sand 0"});
    test::expect_input_error([] { check_sand_rules({2, 0}); }, {"1..255", "water 0"});
    test::expect_input_error([] { check_sand_rules({7, 7}); }, {"differ", "7"});
    World w(Dims{4, 4, 4});
    test::expect_input_error([&] { sand_step(w, {5, 5}, 1, 0); }, {"differ"});
    EXPECT_NO_THROW(check_sand_rules({255, 1}));
}

TEST(Sand, BlockOffsetsOfferEveryDirectionInEightSteps) {
    std::set<std::array<std::int64_t, 3>> seen;
    for (std::uint64_t step = 0; step < 8; ++step) {
        const Int3 o = sand_block_offset(step);
        EXPECT_EQ(o.y, static_cast<std::int64_t>(step & 1)) << step;
        seen.insert({o.x, o.y, o.z});
        EXPECT_EQ(sand_block_offset(step + 8), o);
    }
    EXPECT_EQ(seen.size(), 8u);
    EXPECT_EQ(sand_step_key(5, 3), sand_hash(sand_hash(5) ^ 3));
    EXPECT_NE(sand_step_key(5, 3), sand_step_key(6, 3));
}

TEST(Sand, FreeGrainsFallOneCellPerStepStraightDown) {
    for (const std::uint8_t m : {kSand, kWater}) {
        for (const std::uint32_t start : {10u, 11u}) {
            World w(Dims{7, 13, 6});
            w.set(3, start, 2, m);
            std::int64_t y = start;
            // Until it lands (then water flows on along the bottom of the world).
            for (std::uint64_t step = 0; y > 0; ++step) {
                const VoxelChanges c = sand_step(w, SandRules{}, 9, step);
                const Int3 p = only(w, m);
                EXPECT_EQ(p.x, 3);
                EXPECT_EQ(p.z, 2);
                // Step 0 has odd y in its blocks' top layers: an even start waits a step.
                const std::int64_t want = step == 0 && start % 2 == 0 ? y : y - 1;
                ASSERT_EQ(p.y, want) << "material " << int{m} << ", step " << step;
                EXPECT_EQ(c.size(), p.y == y ? 0u : 2u);
                y = p.y;
            }
            // Sand stays where it landed.
            for (std::uint64_t step = 20; m == kSand && step < 36; ++step) {
                EXPECT_TRUE(sand_step(w, SandRules{}, 9, step).empty());
            }
        }
    }
}

TEST(Sand, SandSinksThroughWater) {
    World w(Dims{1, 6, 1});
    w.set(0, 0, 0, kRock);
    for (std::uint32_t y = 1; y <= 3; ++y) {
        w.set(0, y, 0, kWater);
    }
    w.set(0, 4, 0, kSand);
    for (std::uint64_t step = 0; step < 8; ++step) {
        sand_step(w, SandRules{}, 1, step);
    }
    EXPECT_EQ(w.at(0, 1, 0), kSand);
    for (std::uint32_t y = 2; y <= 4; ++y) {
        EXPECT_EQ(w.at(0, y, 0), kWater) << y;
    }
    EXPECT_EQ(w.at(0, 5, 0), 0);
}

TEST(Sand, SandOnALevelFloorStays) {
    World w(Dims{9, 5, 7});
    floor_of(w, kRock);
    for (std::uint32_t z = 0; z < 7; ++z) {
        for (std::uint32_t x = 0; x < 9; ++x) {
            w.set(x, 1, z, kSand);
        }
    }
    const World start = w;
    for (std::uint64_t step = 0; step < 16; ++step) {
        EXPECT_TRUE(sand_step(w, SandRules{}, 3, step).empty()) << step;
    }
    EXPECT_EQ(w.voxels(), start.voxels());
}

TEST(Sand, WaterFlowsSidewaysButSandDoesNot) {
    World w(Dims{9, 3, 9});
    floor_of(w, kRock);
    w.set(4, 1, 4, kWater);
    w.set(1, 1, 1, kSand);
    std::set<std::array<std::int64_t, 2>> visited;
    for (std::uint64_t step = 0; step < 64; ++step) {
        sand_step(w, SandRules{}, 11, step);
        const Int3 p = only(w, kWater);
        EXPECT_EQ(p.y, 1);
        visited.insert({p.x, p.z});
        EXPECT_EQ(w.at(1, 1, 1), kSand);
    }
    EXPECT_GT(visited.size(), 4u);
}

TEST(Sand, ConservesEveryMaterialKeepsStaticSolidsAndReportsEveryChange) {
    std::vector<World> worlds = {random_world(Dims{23, 17, 19}, 1, 0.2, 0.2, 0.15),
                                 random_world(Dims{5, 5, 5}, 2, 0.0, 0.4, 0.4),
                                 random_world(Dims{1, 9, 2}, 3, 0.1, 0.3, 0.3),
                                 scene_sand(Dims{32, 24, 28}, 4)};
    for (World& w : worlds) {
        const auto counts = histogram(w);
        std::vector<std::size_t> rocks;
        for (std::size_t i = 0; i < w.size(); ++i) {
            const std::uint8_t v = w.voxels()[i];
            if (v != 0 && v != kSand && v != kWater) {
                rocks.push_back(i);
            }
        }
        const std::vector<std::uint8_t> rock_values = [&] {
            std::vector<std::uint8_t> v;
            for (const std::size_t i : rocks) {
                v.push_back(w.voxels()[i]);
            }
            return v;
        }();
        std::size_t moves = 0;
        for (std::uint64_t step = 0; step < 200; ++step) {
            const std::vector<std::uint8_t> before = w.voxels();
            const VoxelChanges changes = sand_step(w, SandRules{}, 77, step);
            moves += changes.size();
            ASSERT_EQ(histogram(w), counts) << w.dims().to_string() << " step " << step;
            // The changes are exactly the difference, in ascending index order.
            VoxelChanges diff;
            for (std::size_t i = 0; i < w.size(); ++i) {
                if (before[i] != w.voxels()[i]) {
                    diff.push_back({i, before[i], w.voxels()[i]});
                }
            }
            ASSERT_EQ(changes, diff) << w.dims().to_string() << " step " << step;
        }
        for (std::size_t k = 0; k < rocks.size(); ++k) {
            ASSERT_EQ(w.voxels()[rocks[k]], rock_values[k]) << "static voxel " << rocks[k];
        }
        EXPECT_GT(moves, 0u) << w.dims().to_string();
    }
}

TEST(Sand, SandComesToRestOnSomethingAndSpreadsEveryWay) {
    // A one-voxel tower on a floor, a heap on a floating ledge, grains in the air.
    World w(Dims{31, 24, 29});
    floor_of(w, kRock);
    for (std::uint32_t y = 1; y <= 12; ++y) {
        w.set(7, y, 7, kSand);
    }
    for (std::uint32_t z = 14; z < 22; ++z) {
        for (std::uint32_t x = 16; x < 26; ++x) {
            w.set(x, 10, z, kRock);
            for (std::uint32_t y = 11; y < 16; ++y) {
                w.set(x, y, z, kSand);
            }
        }
    }
    std::mt19937_64 gen(5);
    for (int i = 0; i < 150; ++i) {
        w.set(static_cast<std::uint32_t>(gen() % 31), 16 + static_cast<std::uint32_t>(gen() % 8),
              static_cast<std::uint32_t>(gen() % 29), kSand);
    }
    const std::uint64_t steps = run_until_still(w, 21, 5000);
    ASSERT_NE(steps, 0u) << "the sand did not come to rest in 5000 steps";
    const Dims d = w.dims();
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 1; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                if (w.at(x, y, z) == kSand) {
                    ASSERT_NE(w.at(x, y - 1, z), 0) << "sand on air at " << x << "," << y << ","
                                                    << z << " after " << steps << " steps";
                }
            }
        }
    }
    // The tower collapsed into a heap around its foot, on every side.
    EXPECT_NE(w.at(7, 12, 7), kSand);
    for (const auto& [x, z] : {std::pair{6u, 7u}, {8u, 7u}, {7u, 6u}, {7u, 8u}}) {
        EXPECT_EQ(w.at(x, 1, z), kSand) << x << "," << z;
    }
}

TEST(Sand, WaterInAClosedBasinSettlesLevel) {
    // Basin interior x, z in 1..12, walls up to y = 9; 400 water voxels dropped in one corner
    // (2.78 layers of 144).
    World w(Dims{14, 24, 14});
    floor_of(w, kRock);
    for (std::uint32_t z = 0; z < 14; ++z) {
        for (std::uint32_t x = 0; x < 14; ++x) {
            if (x == 0 || z == 0 || x == 13 || z == 13) {
                for (std::uint32_t y = 1; y <= 9; ++y) {
                    w.set(x, y, z, kRock);
                }
            }
        }
    }
    std::size_t placed = 0;
    for (std::uint32_t y = 10; y < 24 && placed < 400; ++y) {
        for (std::uint32_t z = 1; z <= 5 && placed < 400; ++z) {
            for (std::uint32_t x = 1; x <= 6 && placed < 400; ++x) {
                w.set(x, y, z, kWater);
                ++placed;
            }
        }
    }
    ASSERT_EQ(placed, 400u);
    const auto surface_spread = [&] {
        std::uint32_t lo = 1000, hi = 0;
        for (std::uint32_t z = 1; z <= 12; ++z) {
            for (std::uint32_t x = 1; x <= 12; ++x) {
                std::uint32_t top = 0;  // the column's highest water voxel (0: none)
                for (std::uint32_t y = 1; y < 24; ++y) {
                    top = w.at(x, y, z) == kWater ? y : top;
                }
                lo = std::min(lo, top);
                hi = std::max(hi, top);
            }
        }
        return hi - lo;
    };
    std::uint64_t step = 0;
    for (; step < 1500; ++step) {
        sand_step(w, SandRules{}, 8, step);
    }
    // Level now and for the steps after (the top layer keeps flowing).
    for (; step < 1532; ++step) {
        sand_step(w, SandRules{}, 8, step);
        ASSERT_LE(surface_spread(), 1u) << "after step " << step;
    }
}

TEST(Sand, SameSeedSameRunOtherSeedOtherRun) {
    const World start = scene_sand(Dims{32, 32, 32}, 7);
    World a = start, b = start, c = start;
    bool differed = false;
    for (std::uint64_t step = 0; step < 60; ++step) {
        EXPECT_EQ(sand_step(a, SandRules{}, 100, step), sand_step(b, SandRules{}, 100, step));
        ASSERT_EQ(a.voxels(), b.voxels()) << step;
        sand_step(c, SandRules{}, 101, step);
        differed |= a.voxels() != c.voxels();
    }
    EXPECT_TRUE(differed);
    EXPECT_NE(a.voxels(), start.voxels());
}

TEST(Sand, OtherMaterialsFollowTheRules) {
    // Material 2 (the default sand) is static rock when sand is 9 and water 8.
    World w(Dims{4, 6, 4});
    w.set(1, 5, 1, 2);
    w.set(2, 5, 2, 9);
    w.set(3, 5, 3, 8);
    for (std::uint64_t step = 0; step < 12; ++step) {
        sand_step(w, SandRules{9, 8}, 1, step);
    }
    EXPECT_EQ(w.at(1, 5, 1), 2);
    EXPECT_EQ(w.at(2, 0, 2), 9);
    EXPECT_EQ(only(w, 8).y, 0);
}

TEST(Sand, SceneHasFloorPileBasinAndGrains) {
    const Dims d{64, 64, 64};
    const World w = scene_sand(d, 3);
    EXPECT_EQ(w.voxels(), scene_sand(d, 3).voxels());
    EXPECT_NE(w.voxels(), scene_sand(d, 4).voxels());
    const auto h = histogram(w);
    EXPECT_EQ(w.at(0, 0, 0), kRock);
    EXPECT_EQ(w.at(63, 0, 63), kRock);
    EXPECT_GT(h[4], 0u);                // basin walls
    EXPECT_GT(h[kWater], 0u);           // its water
    EXPECT_EQ(w.at(16, 1, 32), kSand);  // the pile's foot
    std::size_t grains = 0;
    for (std::uint32_t z = 0; z < 64; ++z) {
        for (std::uint32_t y = 40; y < 64; ++y) {
            for (std::uint32_t x = 0; x < 64; ++x) {
                grains += w.at(x, y, z) == kSand ? 1 : 0;
            }
        }
    }
    EXPECT_GT(grains, 64u * 24 * 64 / 128);
    EXPECT_LT(grains, 64u * 24 * 64 / 32);
    for (const Dims small : {Dims{1, 1, 1}, Dims{2, 2, 2}, Dims{3, 5, 2}, Dims{9, 4, 17}}) {
        World s = scene_sand(small, 1);
        EXPECT_EQ(s.at(0, 0, 0), kRock) << small.to_string();
        const auto counts = histogram(s);
        for (std::uint64_t step = 0; step < 8; ++step) {
            sand_step(s, SandRules{}, 1, step);
        }
        EXPECT_EQ(histogram(s), counts) << small.to_string();
    }
}

}  // namespace
}  // namespace voxfield
