#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <random>
#include <utility>
#include <vector>

#include "test_util.hpp"
#include "voxfield/core/brush.hpp"

namespace voxfield {
namespace {

using test::expect_input_error;

// Independent membership rule, straight from DESIGN §4.
bool inside(BrushShape shape, std::int64_t r, std::int64_t dx, std::int64_t dy, std::int64_t dz) {
    if (shape == BrushShape::sphere) {
        return dx * dx + dy * dy + dz * dz <= r * r;
    }
    return std::max({dx < 0 ? -dx : dx, dy < 0 ? -dy : dy, dz < 0 ? -dz : dz}) <= r;
}

// Applies `b` voxel by voxel to a copy of `w`, the slow obvious way, and returns the expected
// changes in ascending index order.
std::vector<VoxelChange> expected_changes(const World& w, const Brush& b) {
    std::vector<VoxelChange> out;
    const Dims d = w.dims();
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                if (!inside(b.shape, b.radius, x - b.centre.x, y - b.centre.y, z - b.centre.z)) {
                    continue;
                }
                const std::uint8_t before = w.at(x, y, z);
                std::uint8_t after = before;
                if (b.op == BrushOp::place) {
                    after = b.material;
                } else if (b.op == BrushOp::erase) {
                    after = 0;
                } else if (before != 0) {
                    after = b.material;
                }
                if (after != before) {
                    out.push_back({d.index(x, y, z), before, after});
                }
            }
        }
    }
    return out;
}

Box bounds_of(const std::vector<VoxelChange>& changes, Dims d) {
    if (changes.empty()) {
        return Box{};
    }
    Box b{{1 << 30, 1 << 30, 1 << 30}, {-1, -1, -1}};
    for (const auto& c : changes) {
        const auto x = static_cast<std::int64_t>(c.index % d.x);
        const auto y = static_cast<std::int64_t>(c.index / d.x % d.y);
        const auto z = static_cast<std::int64_t>(c.index / (std::size_t{d.x} * d.y));
        b.min = {std::min(b.min.x, x), std::min(b.min.y, y), std::min(b.min.z, z)};
        b.max = {std::max(b.max.x, x + 1), std::max(b.max.y, y + 1), std::max(b.max.z, z + 1)};
    }
    return b;
}

// Applies `b` with apply_brush and checks every field of the result against the slow way.
EditResult check_brush(World& w, const Brush& b) {
    const World before = w;
    const std::vector<VoxelChange> want = expected_changes(before, b);
    const EditResult r = apply_brush(w, b);
    EXPECT_EQ(r.changes, want);
    std::vector<std::uint8_t> expected_voxels = before.voxels();
    std::size_t solid = 0, empty = 0, recoloured = 0;
    for (const auto& c : want) {
        expected_voxels[c.index] = c.after;
        solid += c.before == 0;
        empty += c.after == 0;
        recoloured += c.before != 0 && c.after != 0;
    }
    EXPECT_EQ(w.voxels(), expected_voxels);
    EXPECT_EQ(r.became_solid, solid);
    EXPECT_EQ(r.became_empty, empty);
    EXPECT_EQ(r.recoloured, recoloured);
    EXPECT_EQ(r.changed(), !want.empty());
    EXPECT_EQ(r.occupancy_changed(), solid + empty > 0);
    EXPECT_EQ(r.bounds, bounds_of(want, w.dims()));
    std::vector<VoxelChange> occupancy;
    for (const auto& c : want) {
        if ((c.before == 0) != (c.after == 0)) {
            occupancy.push_back(c);
        }
    }
    EXPECT_EQ(r.occupancy_bounds, bounds_of(occupancy, w.dims()));
    return r;
}

TEST(Brush, ContainsAtExactRadius) {
    // Sphere: on the boundary dx²+dy²+dz² == R² is inside, one step out is not.
    EXPECT_TRUE(brush_contains(BrushShape::sphere, 2, 2, 0, 0));
    EXPECT_TRUE(brush_contains(BrushShape::sphere, 2, 0, -2, 0));
    EXPECT_TRUE(brush_contains(BrushShape::sphere, 2, 1, 1, 1));   // 3 <= 4
    EXPECT_FALSE(brush_contains(BrushShape::sphere, 2, 2, 1, 0));  // 5 > 4
    EXPECT_FALSE(brush_contains(BrushShape::sphere, 2, 2, 2, 2));
    EXPECT_TRUE(brush_contains(BrushShape::sphere, 5, 3, 4, 0));  // 25 == 25
    EXPECT_TRUE(brush_contains(BrushShape::sphere, 5, 0, -3, -4));
    EXPECT_FALSE(brush_contains(BrushShape::sphere, 5, 3, 4, 1));  // 26 > 25
    EXPECT_FALSE(brush_contains(BrushShape::sphere, 5, 6, 0, 0));
    // Cube: max(|d|) == R is inside, R + 1 is not; corners are inside.
    EXPECT_TRUE(brush_contains(BrushShape::cube, 2, 2, 2, 2));
    EXPECT_TRUE(brush_contains(BrushShape::cube, 2, -2, 2, -2));
    EXPECT_FALSE(brush_contains(BrushShape::cube, 2, 3, 0, 0));
    EXPECT_FALSE(brush_contains(BrushShape::cube, 2, 0, 0, -3));
    // Large radii stay exact: (R, 0, 0) in, (R, 1, 0) out.
    const std::int64_t big = kMaxBrushRadius;
    EXPECT_TRUE(brush_contains(BrushShape::sphere, big, big, 0, 0));
    EXPECT_FALSE(brush_contains(BrushShape::sphere, big, big, 1, 0));
    EXPECT_FALSE(
        brush_contains(BrushShape::sphere, big, std::numeric_limits<std::int64_t>::min(), 0, 0));
    EXPECT_TRUE(brush_contains(BrushShape::cube, big, -big, big, -big));
}

TEST(Brush, VoxelCountsOfSpheresAndCubes) {
    // Lattice points with x²+y²+z² <= R²: 1, 7, 33, 123, 257 for R = 0..4.
    const std::size_t sphere_counts[] = {1, 7, 33, 123, 257};
    for (std::int64_t r = 0; r <= 4; ++r) {
        World w(Dims{11, 11, 11});
        const EditResult s =
            check_brush(w, Brush{BrushOp::place, BrushShape::sphere, {5, 5, 5}, r});
        EXPECT_EQ(s.changes.size(), sphere_counts[r]) << "R = " << r;
        EXPECT_EQ(s.became_solid, sphere_counts[r]);
        EXPECT_EQ(s.bounds, (Box{{5 - r, 5 - r, 5 - r}, {6 + r, 6 + r, 6 + r}}));

        World c(Dims{11, 11, 11});
        const EditResult k = check_brush(c, Brush{BrushOp::place, BrushShape::cube, {5, 5, 5}, r});
        EXPECT_EQ(k.changes.size(),
                  static_cast<std::size_t>((2 * r + 1) * (2 * r + 1) * (2 * r + 1)));
        EXPECT_EQ(k.bounds, s.bounds);
    }
}

TEST(Brush, RadiusZeroIsOneVoxel) {
    for (BrushShape shape : {BrushShape::sphere, BrushShape::cube}) {
        World w(Dims{4, 5, 6});
        const EditResult r = apply_brush(w, Brush{BrushOp::place, shape, {1, 2, 3}, 0, 9});
        ASSERT_EQ(r.changes.size(), 1u);
        EXPECT_EQ(r.changes[0], (VoxelChange{w.dims().index(1, 2, 3), 0, 9}));
        EXPECT_EQ(w.at(1, 2, 3), 9);
        EXPECT_EQ(w.solid_count(), 1u);
        EXPECT_EQ(r.bounds, (Box{{1, 2, 3}, {2, 3, 4}}));
        EXPECT_EQ(r.occupancy_bounds, r.bounds);
        EXPECT_EQ(brush_bounds(Brush{BrushOp::erase, shape, {1, 2, 3}, 0}, w.dims()), r.bounds);
    }
}

TEST(Brush, ChangesAreAscendingWithOldAndNewValues) {
    World w = [] {
        World v(Dims{9, 7, 8});
        std::mt19937 rng(7);
        for (auto& voxel : v.voxels()) {
            voxel = rng() % 3 == 0 ? static_cast<std::uint8_t>(1 + rng() % 4) : 0;
        }
        return v;
    }();
    for (BrushOp op : {BrushOp::place, BrushOp::erase, BrushOp::paint}) {
        for (BrushShape shape : {BrushShape::sphere, BrushShape::cube}) {
            World copy = w;
            const EditResult r = check_brush(copy, Brush{op, shape, {4, 3, 4}, 3, 2});
            ASSERT_FALSE(r.changes.empty());
            for (std::size_t i = 1; i < r.changes.size(); ++i) {
                EXPECT_LT(r.changes[i - 1].index, r.changes[i].index);
            }
            for (const auto& c : r.changes) {
                EXPECT_NE(c.before, c.after);
                EXPECT_EQ(copy.voxels()[c.index], c.after);
                EXPECT_EQ(w.voxels()[c.index], c.before);
            }
        }
    }
}

TEST(Brush, ClippedAtEveryWorldFace) {
    const Dims d{10, 7, 12};
    const std::int64_t size[3] = {d.x, d.y, d.z};
    for (BrushShape shape : {BrushShape::sphere, BrushShape::cube}) {
        for (int axis = 0; axis < 3; ++axis) {
            // Centres on the face voxel, just outside and well outside each face.
            for (std::int64_t c : {std::int64_t{0}, std::int64_t{-1}, std::int64_t{-3},
                                   size[axis] - 1, size[axis], size[axis] + 2}) {
                Int3 centre{5, 3, 6};
                (axis == 0 ? centre.x : axis == 1 ? centre.y : centre.z) = c;
                const Brush b{BrushOp::place, shape, centre, 3, 4};
                World w(d);
                const EditResult r = check_brush(w, b);
                ASSERT_FALSE(r.changes.empty()) << "axis " << axis << " c " << c;
                const Box bounds = brush_bounds(b, d);
                EXPECT_FALSE(bounds.empty());
                EXPECT_GE(bounds.min.x, 0);
                EXPECT_GE(bounds.min.y, 0);
                EXPECT_GE(bounds.min.z, 0);
                EXPECT_LE(bounds.max.x, size[0]);
                EXPECT_LE(bounds.max.y, size[1]);
                EXPECT_LE(bounds.max.z, size[2]);
                // The changed box lies inside the brush bounds; for a cube they are equal.
                EXPECT_EQ(intersect(r.bounds, bounds), r.bounds);
                if (shape == BrushShape::cube) {
                    EXPECT_EQ(r.bounds, bounds);
                }
            }
        }
    }
    // Explicit numbers: a cube at (-1, 7, 13) with R = 2 keeps x 0..1, y 5..6, z 11.
    World w(d);
    const Brush corner{BrushOp::place, BrushShape::cube, {-1, 7, 13}, 2};
    EXPECT_EQ(brush_bounds(corner, d), (Box{{0, 5, 11}, {2, 7, 12}}));
    EXPECT_EQ(check_brush(w, corner).changes.size(), 4u);
}

TEST(Brush, FullyOutsideTouchesNothing) {
    const Dims d{8, 8, 8};
    const std::int64_t lo = std::numeric_limits<std::int64_t>::min();
    const std::int64_t hi = std::numeric_limits<std::int64_t>::max();
    const std::vector<std::pair<Int3, std::int64_t>> cases = {{{-3, 4, 4}, 2},
                                                              {{10, 4, 4}, 2},
                                                              {{4, -3, 4}, 2},
                                                              {{4, 11, 4}, 2},
                                                              {{4, 4, -3}, 2},
                                                              {{4, 4, 10}, 1},
                                                              {{-1, -1, -1}, 0},
                                                              {{8, 8, 8}, 0},
                                                              {{lo, 4, 4}, kMaxBrushRadius},
                                                              {{hi, 4, 4}, kMaxBrushRadius},
                                                              {{4, lo, hi}, 5}};
    for (const auto& [centre, radius] : cases) {
        for (BrushShape shape : {BrushShape::sphere, BrushShape::cube}) {
            const Brush b{BrushOp::place, shape, centre, radius, 3};
            EXPECT_TRUE(brush_bounds(b, d).empty());
            EXPECT_EQ(brush_bounds(b, d), Box{});
            World w(d);
            const EditResult r = apply_brush(w, b);
            EXPECT_FALSE(r.changed());
            EXPECT_EQ(r.bounds, Box{});
            EXPECT_EQ(r.occupancy_bounds, Box{});
            EXPECT_EQ(w.solid_count(), 0u);
        }
    }
    // A sphere whose bounding box reaches the world but whose ball does not: the corner voxel
    // (0,0,0) is at distance² 12 from (-2,-2,-2), outside R = 3.
    World w(d);
    const Brush b{BrushOp::place, BrushShape::sphere, {-2, -2, -2}, 3};
    EXPECT_EQ(brush_bounds(b, d), (Box{{0, 0, 0}, {2, 2, 2}}));
    EXPECT_FALSE(check_brush(w, b).changed());
    // The same as a cube reaches it.
    EXPECT_EQ(
        check_brush(w, Brush{BrushOp::place, BrushShape::cube, {-2, -2, -2}, 3}).changes.size(),
        8u);
}

TEST(Brush, HugeRadiusCoversTheWorld) {
    World w(Dims{5, 4, 3});
    const Brush b{BrushOp::place, BrushShape::sphere, {-1000, 2, 1}, kMaxBrushRadius, 7};
    const EditResult r = apply_brush(w, b);
    EXPECT_EQ(r.changes.size(), w.size());
    EXPECT_EQ(r.bounds, (Box{{0, 0, 0}, {5, 4, 3}}));
    EXPECT_EQ(w.solid_count(), w.size());
}

TEST(Brush, PaintRecoloursSolidVoxelsOnly) {
    World w(Dims{5, 1, 1});
    w.set(1, 0, 0, 4);
    w.set(2, 0, 0, 6);
    w.set(3, 0, 0, 9);  // already the target colour
    const EditResult r = check_brush(w, Brush{BrushOp::paint, BrushShape::cube, {2, 0, 0}, 2, 9});
    ASSERT_EQ(r.changes.size(), 2u);
    EXPECT_EQ(r.changes[0], (VoxelChange{1, 4, 9}));
    EXPECT_EQ(r.changes[1], (VoxelChange{2, 6, 9}));
    EXPECT_EQ(r.recoloured, 2u);
    EXPECT_EQ(r.became_solid, 0u);
    EXPECT_EQ(r.became_empty, 0u);
    EXPECT_FALSE(r.occupancy_changed());
    EXPECT_EQ(r.bounds, (Box{{1, 0, 0}, {3, 1, 1}}));
    EXPECT_EQ(r.occupancy_bounds, Box{});
    EXPECT_EQ(w.at(0, 0, 0), 0);  // air stays air
    EXPECT_EQ(w.at(4, 0, 0), 0);
    EXPECT_EQ(w.at(3, 0, 0), 9);
    // Painting air only changes nothing.
    World air(Dims{6, 6, 6});
    EXPECT_FALSE(
        check_brush(air, Brush{BrushOp::paint, BrushShape::sphere, {3, 3, 3}, 3, 5}).changed());
    EXPECT_EQ(air.solid_count(), 0u);
}

TEST(Brush, EraseAndPlaceReportOnlyRealChanges) {
    World w(Dims{6, 6, 6});
    // Erasing air reports nothing.
    EXPECT_FALSE(check_brush(w, Brush{BrushOp::erase, BrushShape::cube, {3, 3, 3}, 2}).changed());
    // Place, then the same place again: the second reports nothing.
    const EditResult first =
        check_brush(w, Brush{BrushOp::place, BrushShape::sphere, {3, 3, 3}, 1, 2});
    EXPECT_EQ(first.became_solid, 7u);
    EXPECT_FALSE(
        check_brush(w, Brush{BrushOp::place, BrushShape::sphere, {3, 3, 3}, 1, 2}).changed());
    // Place with another material over part of it: recolours the old, fills the new.
    const EditResult over =
        check_brush(w, Brush{BrushOp::place, BrushShape::cube, {3, 3, 3}, 1, 5});
    EXPECT_EQ(over.recoloured, 7u);
    EXPECT_EQ(over.became_solid, 20u);
    EXPECT_EQ(over.occupancy_bounds, (Box{{2, 2, 2}, {5, 5, 5}}));
    // Erase a part: only solid voxels are reported, all as became_empty.
    const EditResult erased = check_brush(w, Brush{BrushOp::erase, BrushShape::cube, {4, 4, 4}, 1});
    EXPECT_EQ(erased.became_empty, 8u);
    EXPECT_EQ(erased.recoloured, 0u);
    EXPECT_EQ(erased.bounds, (Box{{3, 3, 3}, {5, 5, 5}}));
    EXPECT_EQ(w.solid_count(), 27u - 8u);
}

TEST(Brush, MaterialAndRadiusAreChecked) {
    World w(Dims{4, 4, 4});
    for (BrushOp op : {BrushOp::place, BrushOp::paint}) {
        expect_input_error(
            [&] {
                apply_brush(w, Brush{op, BrushShape::cube, {1, 1, 1}, 1, 0});
            },
            {"material 0", "1..255"});
    }
    EXPECT_EQ(w.solid_count(), 0u);
    // Erase ignores the material field.
    w.set(1, 1, 1, 3);
    EXPECT_EQ(apply_brush(w, Brush{BrushOp::erase, BrushShape::cube, {1, 1, 1}, 0, 0}).became_empty,
              1u);
    // 1 and 255 are the limits of place's range.
    EXPECT_EQ(
        apply_brush(w, Brush{BrushOp::place, BrushShape::cube, {0, 0, 0}, 0, 1}).changes[0].after,
        1);
    EXPECT_EQ(
        apply_brush(w, Brush{BrushOp::place, BrushShape::cube, {0, 0, 0}, 0, 255}).changes[0].after,
        255);
    for (std::int64_t bad : {std::int64_t{-1}, std::int64_t{-100}, kMaxBrushRadius + 1}) {
        for (BrushOp op : {BrushOp::place, BrushOp::erase, BrushOp::paint}) {
            const Brush b{op, BrushShape::sphere, {1, 1, 1}, bad};
            const World before = w;
            expect_input_error([&] { apply_brush(w, b); }, {"radius " + std::to_string(bad)});
            expect_input_error([&] { brush_bounds(b, w.dims()); }, {"radius"});
            EXPECT_EQ(w.voxels(), before.voxels());
        }
        expect_input_error([&] { brush_contains(BrushShape::cube, bad, 0, 0, 0); }, {"radius"});
    }
}

TEST(Brush, RandomBrushesMatchTheDefinition) {
    std::mt19937 rng(1234);
    World w(Dims{13, 9, 11});
    for (int i = 0; i < 200; ++i) {
        Brush b;
        b.op = static_cast<BrushOp>(rng() % 3);
        b.shape = static_cast<BrushShape>(rng() % 2);
        b.centre = {static_cast<std::int64_t>(rng() % 21) - 4,
                    static_cast<std::int64_t>(rng() % 17) - 4,
                    static_cast<std::int64_t>(rng() % 19) - 4};
        b.radius = rng() % 6;
        b.material = static_cast<std::uint8_t>(1 + rng() % 4);
        check_brush(w, b);
    }
    EXPECT_GT(w.solid_count(), 0u);
}

TEST(Brush, Names) {
    EXPECT_EQ(to_string(BrushOp::place), "place");
    EXPECT_EQ(to_string(BrushOp::erase), "erase");
    EXPECT_EQ(to_string(BrushOp::paint), "paint");
    EXPECT_EQ(to_string(BrushShape::sphere), "sphere");
    EXPECT_EQ(to_string(BrushShape::cube), "cube");
}

}  // namespace
}  // namespace voxfield
