// The sparse viewer's picking (view_input.hpp pick_sparse_voxel) against core's pick_voxel on
// the same voxels as a dense World: the same hit voxel, face and distance (or none) for many
// random rays (origins inside and outside, axis-parallel directions, finite and infinite
// reach) over random worlds of awkward sizes and the models in data/vox.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <random>
#include <string>

#include "view_input.hpp"
#include "voxfield/core/pick.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield::cli {
namespace {

// Rays through and around `world`: `count` of them from the seed.
void expect_same_picks(const World& world, std::uint64_t seed, int count) {
    const SparseWorld sparse = SparseWorld::from_dense(world);
    const Dims d = world.dims();
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> unit(-1, 1), frac(0, 1);
    std::uniform_int_distribution<int> pick(0, 9);
    int hits = 0;
    for (int i = 0; i < count; ++i) {
        const double margin = 0.5 * std::max({d.x, d.y, d.z});
        Vec3d origin{(frac(rng) * (1 + 2 * margin / d.x) - margin / d.x) * d.x,
                     (frac(rng) * (1 + 2 * margin / d.y) - margin / d.y) * d.y,
                     (frac(rng) * (1 + 2 * margin / d.z) - margin / d.z) * d.z};
        if (pick(rng) == 0) {
            origin = {std::floor(origin[0]), std::floor(origin[1]), origin[2]};  // on planes
        }
        Vec3d dir{unit(rng), unit(rng), unit(rng)};
        if (pick(rng) < 2) {
            dir[static_cast<std::size_t>(pick(rng) % 3)] = 0;  // parallel to an axis plane
        }
        if (pick(rng) == 0) {
            // Toward a voxel's centre: grazing the solids rather than missing them.
            const Vec3d to{frac(rng) * d.x, frac(rng) * d.y, frac(rng) * d.z};
            dir = {to[0] - origin[0], to[1] - origin[1], to[2] - origin[2]};
        }
        const double reach =
            pick(rng) < 3 ? frac(rng) * 2 * margin : std::numeric_limits<double>::infinity();
        const auto want = pick_voxel(world, origin, dir, reach);
        const auto got = pick_sparse_voxel(sparse, origin, dir, reach);
        ASSERT_EQ(got.has_value(), want.has_value()) << "ray " << i;
        if (want) {
            ++hits;
            EXPECT_EQ(got->voxel, want->voxel) << "ray " << i;
            EXPECT_EQ(got->normal, want->normal) << "ray " << i;
            EXPECT_EQ(got->distance, want->distance) << "ray " << i;
        }
    }
    EXPECT_GT(hits, 0) << "no ray hit anything: the comparison says little";
}

TEST(SparsePick, RandomWorldsOfAwkwardSizes) {
    const Dims sizes[] = {{1, 1, 1}, {70, 40, 90}, {130, 17, 65}, {64, 64, 64}, {5, 200, 3}};
    std::uint64_t seed = 1;
    for (const Dims& d : sizes) {
        SCOPED_TRACE(d.to_string());
        expect_same_picks(scene_random(d, d.count() < 1000 ? 0.5 : 0.02, seed), seed, 3000);
        expect_same_picks(scene_floor_spheres(d, seed, 6), seed + 100, 1000);
        ++seed;
    }
}

TEST(SparsePick, DegenerateRays) {
    const World w = scene_random(Dims{20, 20, 20}, 0.05, 3);
    const SparseWorld s = SparseWorld::from_dense(w);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    EXPECT_FALSE(pick_sparse_voxel(s, {1, 1, 1}, {0, 0, 0}));
    EXPECT_FALSE(pick_sparse_voxel(s, {nan, 1, 1}, {1, 0, 0}));
    EXPECT_FALSE(pick_sparse_voxel(s, {1, 1, 1}, {1, nan, 0}));
    EXPECT_FALSE(pick_sparse_voxel(s, {-5, 30, 5}, {1, 0, 0}));  // outside, parallel
    // Origin inside a solid voxel: that voxel, no face.
    const Int3 solid = [&] {
        for (std::uint32_t i = 0; i < w.size(); ++i) {
            if (w.voxels()[i] != 0) {
                return Int3{i % 20, i / 20 % 20, i / 400};
            }
        }
        return Int3{};
    }();
    const auto hit = pick_sparse_voxel(
        s, {double(solid.x) + 0.5, double(solid.y) + 0.5, double(solid.z) + 0.5}, {0, 1, 0});
    ASSERT_TRUE(hit);
    EXPECT_EQ(hit->voxel, solid);
    EXPECT_EQ(hit->normal, (Int3{0, 0, 0}));
}

TEST(SparsePick, ModelsInDataVox) {
    int models = 0;
    for (const auto& entry :
         std::filesystem::directory_iterator(std::filesystem::path(VOXFIELD_DATA_DIR) / "vox")) {
        if (entry.path().extension() != ".vox") {
            continue;
        }
        SCOPED_TRACE(entry.path().filename().string());
        const VoxModel m = load_world(entry.path());
        expect_same_picks(m.world, 7, 1500);
        ++models;
    }
    EXPECT_GT(models, 0);
}

}  // namespace
}  // namespace voxfield::cli
