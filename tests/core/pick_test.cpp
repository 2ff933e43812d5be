#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <optional>
#include <random>

#include "voxfield/core/pick.hpp"
#include "voxfield/core/scenes.hpp"

namespace voxfield {
namespace {

// Independent reference: the nearest solid voxel by a slab test against every voxel cube.
std::optional<PickHit> brute_pick(const World& w, const Vec3d& o, const Vec3d& d) {
    std::optional<PickHit> best;
    const Dims dims = w.dims();
    for (std::uint32_t z = 0; z < dims.z; ++z) {
        for (std::uint32_t y = 0; y < dims.y; ++y) {
            for (std::uint32_t x = 0; x < dims.x; ++x) {
                if (w.at(x, y, z) == 0) {
                    continue;
                }
                const double lo[3] = {double(x), double(y), double(z)};
                double t0 = 0, t1 = std::numeric_limits<double>::infinity();
                int axis = -1;
                bool miss = false;
                for (int a = 0; a < 3 && !miss; ++a) {
                    if (d[a] == 0) {
                        miss = o[a] < lo[a] || o[a] >= lo[a] + 1;
                        continue;
                    }
                    double ta = (lo[a] - o[a]) / d[a], tb = (lo[a] + 1 - o[a]) / d[a];
                    if (ta > tb) {
                        std::swap(ta, tb);
                    }
                    if (ta > t0) {
                        t0 = ta;
                        axis = a;
                    }
                    t1 = std::min(t1, tb);
                }
                if (miss || t0 >= t1) {
                    continue;
                }
                if (!best || t0 < best->distance) {
                    PickHit h;
                    h.voxel = {x, y, z};
                    std::int64_t n[3] = {0, 0, 0};
                    if (axis >= 0) {
                        n[axis] = d[axis] > 0 ? -1 : 1;
                    }
                    h.normal = {n[0], n[1], n[2]};
                    h.distance = t0;
                    best = h;
                }
            }
        }
    }
    return best;
}

TEST(Pick, MatchesABruteForceCaster) {
    const World w = scene_random(Dims{12, 9, 7}, 0.1, 11);
    std::mt19937_64 rng(5);
    std::uniform_real_distribution<double> pos(-10, 20), dir(-1, 1);
    int hits = 0;
    for (int i = 0; i < 3000; ++i) {
        const Vec3d o = {pos(rng), pos(rng), pos(rng)};
        // Half of the rays aim at a random point of the world, half go anywhere.
        Vec3d d = {dir(rng), dir(rng), dir(rng)};
        if (i % 2 == 0) {
            d = {12 * (dir(rng) + 1) / 2 - o[0], 9 * (dir(rng) + 1) / 2 - o[1],
                 7 * (dir(rng) + 1) / 2 - o[2]};
        }
        const auto got = pick_voxel(w, o, d);
        const auto want = brute_pick(w, o, d);
        ASSERT_EQ(got.has_value(), want.has_value()) << "ray " << i;
        if (got) {
            ++hits;
            EXPECT_EQ(got->voxel, want->voxel) << "ray " << i;
            EXPECT_EQ(got->normal, want->normal) << "ray " << i;
            EXPECT_NEAR(got->distance, want->distance, 1e-9) << "ray " << i;
        }
    }
    EXPECT_GT(hits, 1000);
}

TEST(Pick, NeverHitsBehindTheCamera) {
    // The dissertation's walk could start behind the camera and pick the voxel behind it.
    World w(Dims{16, 4, 4});
    w.set(2, 1, 1, 5);   // behind
    w.set(12, 1, 1, 6);  // ahead
    const auto hit = pick_voxel(w, {6.5, 1.5, 1.5}, {1, 0, 0});
    ASSERT_TRUE(hit);
    EXPECT_EQ(hit->voxel, (Int3{12, 1, 1}));
    EXPECT_EQ(hit->normal, (Int3{-1, 0, 0}));
    EXPECT_DOUBLE_EQ(hit->distance, 5.5);
    // Turned around it sees the other one; past the last solid, nothing.
    EXPECT_EQ(pick_voxel(w, {6.5, 1.5, 1.5}, {-1, 0, 0})->voxel, (Int3{2, 1, 1}));
    EXPECT_FALSE(pick_voxel(w, {13.5, 1.5, 1.5}, {1, 0, 0}));
    // From outside the world, pointing away from it: no hit.
    EXPECT_FALSE(pick_voxel(w, {-5, 1.5, 1.5}, {-1, 0, 0}));
    // Max distance.
    EXPECT_FALSE(pick_voxel(w, {6.5, 1.5, 1.5}, {1, 0, 0}, 5.0));
    EXPECT_TRUE(pick_voxel(w, {6.5, 1.5, 1.5}, {1, 0, 0}, 5.5));
}

TEST(Pick, ShallowDirectionsAreExact) {
    // An inverse direction rounded to an integer (the dissertation) walks the wrong cells
    // for a ray that is almost parallel to an axis.
    World w(Dims{64, 8, 8});
    w.set(60, 2, 3, 7);
    w.set(60, 1, 3, 8);
    const Vec3d o = {0.5, 1.9, 3.5};
    const Vec3d d = {1, 0.0030, 0};  // reaches y = 2 at x = 0.5 + 0.1/0.003 = 33.8
    const auto hit = pick_voxel(w, o, d);
    ASSERT_TRUE(hit);
    EXPECT_EQ(hit->voxel, (Int3{60, 2, 3}));
    EXPECT_EQ(hit->normal, (Int3{-1, 0, 0}));
}

TEST(Pick, InsideASolidAndFromOutside) {
    World w(Dims{4, 4, 4});
    w.set(1, 1, 1, 3);
    const auto inside = pick_voxel(w, {1.5, 1.5, 1.5}, {0, 1, 0});
    ASSERT_TRUE(inside);
    EXPECT_EQ(inside->voxel, (Int3{1, 1, 1}));
    EXPECT_EQ(inside->normal, (Int3{0, 0, 0}));
    EXPECT_EQ(inside->distance, 0);
    // From above the world, straight down onto the top face.
    const auto top = pick_voxel(w, {1.5, 100, 1.5}, {0, -2, 0});
    ASSERT_TRUE(top);
    EXPECT_EQ(top->voxel, (Int3{1, 1, 1}));
    EXPECT_EQ(top->normal, (Int3{0, 1, 0}));
    EXPECT_DOUBLE_EQ(top->distance, (100 - 2) / 2.0);
    // Entering the world through a face of a boundary voxel.
    w.set(3, 0, 0, 1);
    const auto edge = pick_voxel(w, {10, 0.5, 0.5}, {-1, 0, 0});
    ASSERT_TRUE(edge);
    EXPECT_EQ(edge->voxel, (Int3{3, 0, 0}));
    EXPECT_EQ(edge->normal, (Int3{1, 0, 0}));
    // Degenerate rays.
    EXPECT_FALSE(pick_voxel(w, {1, 1, 1}, {0, 0, 0}));
    EXPECT_FALSE(pick_voxel(w, {NAN, 1, 1}, {1, 0, 0}));
    EXPECT_FALSE(pick_voxel(w, {1, 1, 1}, {INFINITY, 0, 0}));
}

}  // namespace
}  // namespace voxfield
