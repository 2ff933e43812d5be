// The implicit discretiser on PoCL, both layouts: solid and crossed voxels equal brute-force
// sampling at every corner and centre of the same grid (pruning loses nothing), and the kept
// corner values and gradients equal the CPU evaluators', on random trees and the gallery.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "cl_test_util.hpp"
#include "sdf_random.hpp"
#include "voxfield/cl/implicit.hpp"

namespace voxfield::ocl {
namespace {

struct Check {
    std::size_t solid = 0, crossed = 0;
    float max_value_error = 0, max_gradient_error = 0;
    std::uint64_t leaves = 0;
    std::uint32_t tile_edge = 0;
};

// f at every corner and centre of the grid, by the device's brute-force kernels.
struct Brute {
    std::vector<float> corners, centres;
};
Brute brute_force(Context& ctx, const sdf::Part& part) {
    ImplicitDiscretiser job(ctx, part, {});
    return {job.sample_corners(), job.sample_centres()};
}
Brute brute_force(const sdf::Part& part) {
    return brute_force(test::pocl(), part);
}

// Brute-force flags (bit 0: f < 0 at the centre; bit 1: f < 0 differs among the 8 corners and
// the centre) from the device's samples at every corner and centre.
std::vector<std::uint8_t> brute_flags(const Dims d, const std::vector<float>& corners,
                                      const std::vector<float>& centres) {
    std::vector<std::uint8_t> f(d.count());
    auto corner = [&](std::uint32_t i, std::uint32_t j, std::uint32_t k) {
        return corners[(std::size_t{k} * (d.y + 1) + j) * (d.x + 1) + i];
    };
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                const float c = centres[d.index(x, y, z)];
                bool inside = c < 0, outside = !(c < 0);
                for (std::uint32_t k = 0; k < 8; ++k) {
                    const float v = corner(x + (k & 1), y + (k >> 1 & 1), z + (k >> 2));
                    inside |= v < 0;
                    outside |= !(v < 0);
                }
                f[d.index(x, y, z)] =
                    static_cast<std::uint8_t>((c < 0 ? 1 : 0) | (inside && outside ? 2 : 0));
            }
        }
    }
    return f;
}

// Compares a discretisation of `part` with brute force (flags, counts, corner values); returns
// counts and the largest errors against the CPU evaluators.
Check compare(const sdf::Part& part, const ImplicitGrid& grid, const std::string& what,
              const Brute& brute) {
    Check r;
    r.leaves = grid.leaves;
    r.tile_edge = grid.tile_edge;
    const std::vector<float>& corners = brute.corners;
    const std::vector<float>& centres = brute.centres;
    const std::vector<std::uint8_t> want = brute_flags(part.dims, corners, centres);
    const std::vector<std::uint8_t> got = grid.flags();
    const Dims d = part.dims;
    std::size_t mismatches = 0;
    for (std::size_t i = 0; i < want.size(); ++i) {
        r.solid += want[i] & 1;
        r.crossed += want[i] >> 1;
        if (got[i] != want[i] && mismatches++ < 5) {
            ADD_FAILURE() << what << ": voxel (" << i % d.x << "," << i / d.x % d.y << ","
                          << i / d.x / d.y << ") flags " << int(got[i]) << ", brute force "
                          << int(want[i]);
        }
    }
    EXPECT_EQ(mismatches, 0u) << what;
    EXPECT_EQ(grid.solid_count(), r.solid) << what;
    const auto crossed = grid.crossed();
    EXPECT_EQ(crossed.size(), r.crossed) << what;
    EXPECT_EQ(grid.crossed_count(), r.crossed) << what;
    for (const auto& c : crossed) {
        const sdf::ValueMaterial vm = sdf::evaluate_material(part.tape, part.centre(c.x, c.y, c.z));
        EXPECT_EQ(c.material, vm.material) << what;
        for (std::uint32_t k = 0; k < 8; ++k) {
            const std::uint32_t i = c.x + (k & 1), j = c.y + (k >> 1 & 1), l = c.z + (k >> 2);
            const float* v = c.corner[k];
            // The stored f is the device's sample of that corner, and f on the CPU to float
            // precision.
            EXPECT_EQ(v[3], corners[(std::size_t{l} * (d.y + 1) + j) * (d.x + 1) + i]) << what;
            const sdf::ValueGradient cpu = sdf::evaluate_gradient(part.tape, part.corner(i, j, l));
            const float scale = 1 + std::abs(cpu.value);
            r.max_value_error = std::max(r.max_value_error, std::abs(v[3] - cpu.value) / scale);
            // The stored gradient is per voxel: h grad f.
            const auto h = static_cast<float>(part.voxel_size);
            r.max_gradient_error = std::max(
                {r.max_gradient_error, std::abs(v[0] / h - cpu.gradient.x),
                 std::abs(v[1] / h - cpu.gradient.y), std::abs(v[2] / h - cpu.gradient.z)});
        }
    }
    return r;
}

// Discretises `part` on PoCL and compares it with brute force.
Check check(const sdf::Part& part, ImplicitOptions options, const std::string& what,
            const Brute& brute) {
    ImplicitDiscretiser job(test::pocl(), part, options);
    EXPECT_EQ(job.gpu_layout(), options.layout == Layout::gpu);
    const Check r = compare(part, job.run(), what, brute);
    EXPECT_LE(r.max_value_error, 4 * 1.2e-7f) << what;
    EXPECT_LE(r.max_gradient_error, 1e-5f) << what;
    return r;
}

Check check(const sdf::Part& part, ImplicitOptions options, const std::string& what) {
    return check(part, options, what, brute_force(part));
}

// Two grids of one part hold the same discretisation: flags per voxel, and every crossed
// voxel's material and corners (the leaves append crossed voxels in no fixed order).
void expect_same_grid(const ImplicitGrid& got, const ImplicitGrid& want) {
    EXPECT_EQ(got.dims, want.dims);
    EXPECT_EQ(got.tiles, want.tiles);
    EXPECT_EQ(got.tile_edge, want.tile_edge);
    EXPECT_EQ(got.leaves, want.leaves);
    EXPECT_EQ(got.flags(), want.flags());
    auto sorted = [](std::vector<ImplicitGrid::Crossed> c) {
        std::sort(c.begin(), c.end(), [](const auto& a, const auto& b) {
            return std::tie(a.z, a.y, a.x) < std::tie(b.z, b.y, b.x);
        });
        return c;
    };
    const auto a = sorted(got.crossed()), b = sorted(want.crossed());
    ASSERT_EQ(a.size(), b.size());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
        differ += a[i].x != b[i].x || a[i].y != b[i].y || a[i].z != b[i].z ||
                  a[i].material != b[i].material ||
                  std::memcmp(a[i].corner, b[i].corner, sizeof a[i].corner) != 0;
    }
    EXPECT_EQ(differ, 0u);
}

// A tile table's entries as empty, full or a root (roots are numbered in no fixed order).
std::vector<std::uint32_t> tile_kinds(const ImplicitGrid& g) {
    std::vector<std::uint32_t> kinds(g.tile_table.size());
    for (std::size_t t = 0; t < kinds.size(); ++t) {
        const std::uint32_t e = g.tile_table[t];
        kinds[t] = e == VF_SDF_TILE_EMPTY || e == VF_SDF_TILE_FULL ? e : 0u;
    }
    return kinds;
}

class ImplicitLayouts : public ::testing::TestWithParam<Layout> {};

TEST_P(ImplicitLayouts, RandomTreesEqualBruteForce) {
    test::RandomPart gen(21);
    std::size_t crossed = 0, solid = 0;
    for (int t = 0; t < 24; ++t) {
        const double h = gen.real(0.025, 0.07);
        const sdf::Part part = sdf::parse_part(gen.part(4, h), "random");
        const std::uint32_t depth = static_cast<std::uint32_t>(t % 3);
        const Check c = check(part, {depth, GetParam()},
                              "tree " + std::to_string(t) + " depth " + std::to_string(depth));
        crossed += c.crossed;
        solid += c.solid;
    }
    EXPECT_GT(crossed, 10000u);  // the trees have surfaces to find
    EXPECT_GT(solid, 10000u);
}

// Coarse voxels against the features: many voxels whose corners lie within a voxel of the
// surface, where the CPU layout samples a centre only when no corner decides its sign (the
// 1-Lipschitz bound) and every level specialises its parent's tape.
TEST_P(ImplicitLayouts, CoarseRandomTreesEqualBruteForce) {
    test::RandomPart gen(77);
    std::size_t crossed = 0;
    for (int t = 0; t < 160; ++t) {
        const double h = gen.real(0.06, 0.2);
        const sdf::Part part = sdf::parse_part(gen.part(5, h), "random");
        const std::uint32_t depth = static_cast<std::uint32_t>(t % 2);
        crossed += check(part, {depth, GetParam()},
                         "coarse tree " + std::to_string(t) + " depth " + std::to_string(depth))
                       .crossed;
    }
    EXPECT_GT(crossed, 5000u);
}

// The mutation that shows the centre bound matters: a shell thinner than a voxel is crossed
// at many voxels only by their centres (every corner outside, a corner up to the half diagonal
// away); leaves that take a corner's sign for the centre from |f| above 0.7 of the half diagonal
// miss them, and brute force catches it, in both layouts; the default bound does not.
TEST_P(ImplicitLayouts, ACentreBoundBelowTheHalfDiagonalIsCaught) {
    const double h = 0.05;
    const sdf::Part part = sdf::parse_part(
        R"({"version": 1, "voxel_size": 0.05, "bounds": [[-1, -1, -1], [1, 1, 1]],
            "shape": {"shell": {"thickness": 0.004,
              "of": {"sphere": {"center": [0.013, -0.021, 0.007], "radius": 0.61}}}}})",
        "thin shell");
    const Brute b = brute_force(part);
    const std::vector<std::uint8_t> want = brute_flags(part.dims, b.corners, b.centres);
    for (std::uint32_t depth : {0u, 1u}) {
        const std::string what = "thin shell depth " + std::to_string(depth);
        check(part, {depth, GetParam()}, what, b);
        ImplicitDiscretiser job(test::pocl(), part, {depth, GetParam()});
        const float half_diagonal = static_cast<float>(0.5 * std::sqrt(3.0) * h);
        EXPECT_GT(job.centre_bound(), half_diagonal);
        job.set_centre_bound(0.7f * half_diagonal);
        const std::vector<std::uint8_t> got = job.run().flags();
        std::size_t missed = 0;
        for (std::size_t i = 0; i < want.size(); ++i) {
            missed += got[i] != want[i];
        }
        EXPECT_GT(missed, 20u) << what;
    }
}

// The readback through page-locked staging memory (a GPU's default) gives the direct
// readback's grid, run after run into one reused grid. The first run counts each level on the
// host (a wait per level, one for the leaves' counts and one for the output); later runs wait
// once: they zero the counters, launch the tiles, the levels and the leaves, and read the
// counters, tile table, nodes, voxels and vertices in one go.
TEST_P(ImplicitLayouts, PinnedReadbackEqualsDirect) {
    const sdf::Part part =
        sdf::load_part(std::filesystem::path(VOXFIELD_DATA_DIR) / "parts" / "bracket.sdf.json");
    for (std::uint32_t depth : {1u, 2u}) {
        ImplicitDiscretiser direct(test::pocl(), part, {depth, GetParam()});
        EXPECT_FALSE(direct.pinned_readback());  // PoCL computes in host memory
        const ImplicitGrid want = direct.run();
        EXPECT_TRUE(direct.timing().counted);
        // The tiles, each level, the leaves, the output; and every rerun past a first guess.
        EXPECT_EQ(direct.timing().syncs, 1u + depth + 1u + 1u + direct.timing().level_reruns +
                                             (direct.timing().passes - 1u));
        ImplicitDiscretiser job(test::pocl(), part, {depth, GetParam()});
        job.set_pinned_readback(true);
        ImplicitGrid got;
        for (int i = 0; i < 3; ++i) {
            job.run(got);
            expect_same_grid(got, want);
            EXPECT_EQ(tile_kinds(got), tile_kinds(want));
            EXPECT_EQ(job.counts(), direct.counts());
            if (i > 0) {
                EXPECT_FALSE(job.timing().counted);
                EXPECT_EQ(job.timing().syncs, 1u);
                EXPECT_EQ(job.timing().enqueues, 1u + 1u + depth + 1u + 5u);
                EXPECT_EQ(job.timing().passes, 1u);
            }
        }
    }
}

// Runs after the first (one wait) equal brute force, run after run; so do runs sized from
// counts that are too small at any one level, or for the leaves' records (the one-wait attempt
// overflows, and the run is redone counted), and runs sized from larger counts (one wait).
TEST_P(ImplicitLayouts, OneWaitRunsEqualBruteForceAndOverflowsRerunCounted) {
    const sdf::Part part =
        sdf::load_part(std::filesystem::path(VOXFIELD_DATA_DIR) / "parts" / "pipe_elbow.sdf.json");
    const Brute brute = brute_force(part);
    const std::vector<std::uint8_t> want = brute_flags(part.dims, brute.corners, brute.centres);
    for (std::uint32_t depth : {0u, 1u, 2u}) {
        const std::string what = "depth " + std::to_string(depth);
        ImplicitDiscretiser job(test::pocl(), part, {depth, GetParam()});
        job.set_pinned_readback(depth == 1);  // both readbacks
        ImplicitGrid grid;
        job.run(grid);
        const ImplicitGrid first = grid;
        const ImplicitCounts counts = job.counts();
        ASSERT_EQ(counts.nodes.size(), depth + 1u);
        EXPECT_EQ(counts.nodes.back(), grid.leaves);
        EXPECT_EQ(counts.voxels, grid.crossed_count());
        EXPECT_EQ(counts.vertices, grid.vertex_count());
        EXPECT_EQ(grid.flags(), want) << what;
        for (int i = 0; i < 2; ++i) {
            job.run(grid);
            EXPECT_FALSE(job.timing().counted) << what;
            EXPECT_EQ(job.timing().syncs, 1u) << what;
            EXPECT_EQ(grid.flags(), want) << what;
            expect_same_grid(grid, first);
        }
        // Too small: each level in turn, then the vertices and the voxels.
        std::vector<ImplicitCounts> small;
        for (std::uint32_t l = 0; l <= depth; ++l) {
            small.push_back(counts);
            small.back().nodes[l] /= 2;
        }
        small.push_back(counts);
        small.back().vertices -= 1;
        small.push_back(counts);
        small.back().voxels /= 3;
        for (std::size_t s = 0; s < small.size(); ++s) {
            job.expect(small[s]);
            job.run(grid);
            EXPECT_TRUE(job.timing().counted) << what << " small " << s;
            EXPECT_GT(job.timing().syncs, 1u + depth) << what << " small " << s;
            EXPECT_EQ(job.counts(), counts) << what << " small " << s;
            EXPECT_EQ(grid.flags(), want) << what << " small " << s;
            expect_same_grid(grid, first);
        }
        // Larger: one wait, the same grid, the true counts kept.
        ImplicitCounts large = counts;
        for (auto& n : large.nodes) {
            n = n * 2 + 5;
        }
        large.vertices = large.vertices * 2 + 7;
        large.voxels = large.voxels * 2 + 3;
        job.expect(large);
        job.run(grid);
        EXPECT_FALSE(job.timing().counted) << what;
        // (The pinned stage, grown for the larger sizes, is mapped again: a second wait.)
        EXPECT_EQ(job.timing().syncs, job.pinned_readback() ? 2u : 1u) << what;
        EXPECT_EQ(job.counts(), counts) << what;
        EXPECT_EQ(grid.flags(), want) << what;
        expect_same_grid(grid, first);
    }
}

// A part whose first guesses are far too small (thin slabs every 3 voxels: every tile and
// every child ambiguous, many kept corners per leaf): the counted first run reruns the tile
// test (depth 0: 4096 tiles), a level (depth 1: 4096 children of 64 tiles) and the leaves at the
// counts they reached, and equals brute force; the next run waits once for the same grid.
TEST_P(ImplicitLayouts, CountedRunsRerunLevelsPastTheirGuesses) {
    nlohmann::json kids = nlohmann::json::array();
    const double h = 1.0 / 32;
    for (int k = 0; k < 21; ++k) {
        kids.push_back(
            {{"box", {{"center", {(3 * k + 1.5) * h, 1, 1}}, {"half_size", {0.4 * h, 3, 3}}}}});
    }
    const nlohmann::json doc = {{"version", 1},
                                {"voxel_size", h},
                                {"bounds", {{0, 0, 0}, {2, 2, 2}}},
                                {"shape", {{"union", kids}}}};
    const sdf::Part part = sdf::parse_part(doc.dump(), "slabs");
    const Brute brute = brute_force(part);
    for (std::uint32_t depth : {0u, 1u}) {
        const std::string what = "slabs depth " + std::to_string(depth);
        ImplicitDiscretiser job(test::pocl(), part, {depth, GetParam()});
        const ImplicitGrid first = job.run();
        EXPECT_TRUE(job.timing().counted) << what;
        EXPECT_EQ(job.timing().level_reruns, 1u) << what;
        EXPECT_EQ(job.timing().passes, 2u) << what;
        EXPECT_EQ(job.counts().nodes[depth], depth == 0 ? 4096u : 4096u) << what;
        check(part, {depth, GetParam()}, what, brute);
        ImplicitGrid again;
        job.run(again);
        EXPECT_EQ(job.timing().syncs, 1u) << what;
        expect_same_grid(again, first);
    }
}

TEST_P(ImplicitLayouts, ExpectRejectsCountsOfAnotherDepth) {
    const sdf::Part part =
        sdf::load_part(std::filesystem::path(VOXFIELD_DATA_DIR) / "parts" / "bracket.sdf.json");
    ImplicitDiscretiser job(test::pocl(), part, {2, GetParam()});
    ImplicitCounts c;
    c.nodes = {1, 2};
    EXPECT_THROW(job.expect(c), std::invalid_argument);
}

TEST_P(ImplicitLayouts, GalleryEqualsBruteForceAndPrunes) {
    for (const char* name : {"bracket", "gear_ring", "pipe_elbow"}) {
        const sdf::Part part = sdf::load_part(std::filesystem::path(VOXFIELD_DATA_DIR) / "parts" /
                                              (std::string(name) + ".sdf.json"));
        const Brute brute = brute_force(part);
        for (std::uint32_t depth : {1u, 2u}) {
            const std::string what = std::string(name) + " depth " + std::to_string(depth);
            const Check c = check(part, {depth, GetParam()}, what, brute);
            EXPECT_GT(c.crossed, 1000u) << what;
            // Pruning: far fewer voxels sampled in leaves than in the grid.
            EXPECT_LT(c.leaves * 64, part.dims.count() / 2) << what;
            EXPECT_EQ(c.tile_edge, depth == 1 ? 16u : 64u);
        }
    }
}

TEST_P(ImplicitLayouts, CapacityOverflowRerunsWithTheReachedSizes) {
    // A thin shell of many crossings per leaf: more kept corners than the first guess.
    const sdf::Part part = sdf::parse_part(
        R"({"version": 1, "voxel_size": 0.02, "bounds": [[-1, -1, -1], [1, 1, 1]],
            "shape": {"intersection": [{"box": {"center": [0, 0, 0], "half_size": [0.9, 0.9, 0.9]}},
              {"union": [{"plane": {"normal": [0, 1, 0], "offset": 0.011}},
                         {"shell": {"thickness": 0.001, "of": {"sphere": {"center": [0, 0, 0], "radius": 0.5}}}},
                         {"shell": {"thickness": 0.001, "of": {"sphere": {"center": [0, 0, 0], "radius": 0.53}}}},
                         {"shell": {"thickness": 0.001, "of": {"sphere": {"center": [0, 0, 0], "radius": 0.56}}}},
                         {"shell": {"thickness": 0.001, "of": {"sphere": {"center": [0, 0, 0], "radius": 0.59}}}}]}]}})",
        "shells");
    ImplicitDiscretiser job(test::pocl(), part, {1, GetParam()});
    const ImplicitGrid first = job.run();
    EXPECT_EQ(job.timing().passes, 2u);
    check(part, {1, GetParam()}, "shells");
    // The next run starts from the reached sizes: one pass, the same grid.
    ImplicitGrid again;
    job.run(again);
    EXPECT_EQ(job.timing().passes, 1u);
    expect_same_grid(again, first);
}

// A grid reused by run(out) holds nothing of what it held before: a larger part's grid, then a
// gallery part's, equals the gallery part's fresh grid.
TEST_P(ImplicitLayouts, RunsIntoAReusedGridEqualFreshOnes) {
    const sdf::Part big = sdf::parse_part(
        R"({"version": 1, "voxel_size": 0.02, "bounds": [[-1, -1, -1], [1, 1, 1]],
            "shape": {"shell": {"thickness": 0.001, "of": {"sphere": {"center": [0, 0, 0], "radius": 0.7}}}}})",
        "big");
    const sdf::Part part =
        sdf::load_part(std::filesystem::path(VOXFIELD_DATA_DIR) / "parts" / "bracket.sdf.json");
    ImplicitGrid reused;
    ImplicitDiscretiser(test::pocl(), big, {1, GetParam()}).run(reused);
    ASSERT_GT(reused.crossed_count(), 0u);
    ImplicitDiscretiser job(test::pocl(), part, {2, GetParam()});
    job.run(reused);
    const ImplicitGrid fresh = ImplicitDiscretiser(test::pocl(), part, {2, GetParam()}).run();
    expect_same_grid(reused, fresh);
    EXPECT_EQ(tile_kinds(reused), tile_kinds(fresh));
    // And the same discretiser again into its own output.
    job.run(reused);
    expect_same_grid(reused, fresh);
}

TEST_P(ImplicitLayouts, TapesTooLongToSpecialiseRunWhole) {
    // A union of 300 spheres: 599 instructions, more than VF_SDF_SPECIALISE_MAX.
    test::RandomPart gen(31);
    nlohmann::json kids = nlohmann::json::array();
    for (int i = 0; i < 300; ++i) {
        kids.push_back(
            {{"sphere",
              {{"center", {gen.real(-0.8, 0.8), gen.real(-0.8, 0.8), gen.real(-0.8, 0.8)}},
               {"radius", gen.real(0.05, 0.15)}}}});
    }
    const nlohmann::json doc = {{"version", 1},
                                {"voxel_size", 0.04},
                                {"bounds", {{-1, -1, -1}, {1, 1, 1}}},
                                {"shape", {{"union", kids}}}};
    const sdf::Part part = sdf::parse_part(doc.dump(), "spheres");
    ASSERT_GT(part.tape.code.size(), std::size_t{VF_SDF_SPECIALISE_MAX});
    const Check c = check(part, {1, GetParam()}, "300 spheres");
    EXPECT_GT(c.crossed, 1000u);
}

INSTANTIATE_TEST_SUITE_P(Pocl, ImplicitLayouts, ::testing::Values(Layout::cpu, Layout::gpu),
                         [](const auto& p) { return p.param == Layout::cpu ? "cpu" : "gpu"; });

TEST(Implicit, FullAndEmptyTilesAreNotSubdivided) {
    // A plane y < 0.51 over [0, 4]^3 at h = 1/32: 128^3 voxels, tiles of 16^3 (depth 1).
    const sdf::Part part = sdf::parse_part(
        R"({"version": 1, "voxel_size": 0.03125, "bounds": [[0, 0, 0], [4, 4, 4]],
            "shape": {"plane": {"normal": [0, 1, 0], "offset": 0.51}}})",
        "plane");
    ImplicitDiscretiser job(test::pocl(), part, {1, Layout::cpu});
    const ImplicitGrid grid = job.run();
    std::size_t full = 0, empty = 0;
    for (std::uint32_t t : grid.tile_table) {
        full += t == VF_SDF_TILE_FULL;
        empty += t == VF_SDF_TILE_EMPTY;
    }
    // Tile row 0 (y in [0, 0.5]) is full, row 1 (y in [0.5, 1]) holds the surface, rows 2..7
    // are empty.
    EXPECT_EQ(full, 64u);
    EXPECT_EQ(empty, 6u * 64u);
    EXPECT_EQ(grid.tile_table.size(), 512u);
    check(part, {1, Layout::cpu}, "plane");
}

// drop_crossed forgets exactly the crossed voxels it is asked to: their occupied bits and
// records; every other crossed voxel keeps its record (material and corners).
TEST(Implicit, DropCrossedForgetsOnlyThoseVoxels) {
    const sdf::Part part =
        sdf::load_part(std::filesystem::path(VOXFIELD_DATA_DIR) / "parts" / "gear_ring.sdf.json");
    ImplicitGrid grid = ImplicitDiscretiser(test::pocl(), part, {1, Layout::cpu}).run();
    const auto before = grid.crossed();
    const std::vector<std::uint8_t> flags = grid.flags();
    auto dropped = [](std::uint32_t x, std::uint32_t y, std::uint32_t z) {
        return (x + 2 * y + 3 * z) % 3 == 0;
    };
    const std::size_t n = grid.drop_crossed(dropped);
    std::vector<ImplicitGrid::Crossed> want;
    for (const auto& c : before) {
        if (!dropped(c.x, c.y, c.z)) {
            want.push_back(c);
        }
    }
    EXPECT_EQ(n, before.size() - want.size());
    EXPECT_GT(n, 1000u);
    EXPECT_EQ(grid.crossed_count(), want.size());
    const auto after = grid.crossed();
    ASSERT_EQ(after.size(), want.size());
    for (std::size_t i = 0; i < want.size(); ++i) {
        EXPECT_TRUE(after[i].x == want[i].x && after[i].y == want[i].y && after[i].z == want[i].z &&
                    after[i].material == want[i].material &&
                    std::memcmp(after[i].corner, want[i].corner, sizeof want[i].corner) == 0)
            << i;
    }
    const std::vector<std::uint8_t> now = grid.flags();
    const Dims d = part.dims;
    for (std::size_t i = 0; i < now.size(); ++i) {
        const auto x = static_cast<std::uint32_t>(i % d.x),
                   y = static_cast<std::uint32_t>(i / d.x % d.y),
                   z = static_cast<std::uint32_t>(i / d.x / d.y);
        const std::uint8_t expect =
            (flags[i] & 2) && dropped(x, y, z) ? std::uint8_t(flags[i] & 1) : flags[i];
        ASSERT_EQ(now[i], expect) << x << "," << y << "," << z;
    }
}

TEST(Implicit, RejectsATileDepthOutOfRange) {
    const sdf::Part part = sdf::parse_part(
        R"({"version": 1, "voxel_size": 0.1, "bounds": [[0, 0, 0], [1, 1, 1]],
            "shape": {"sphere": {"center": [0, 0, 0], "radius": 1}}})",
        "s");
    EXPECT_THROW(ImplicitDiscretiser(test::pocl(), part, {9, Layout::cpu}), InputError);
}

// On a GPU when there is one (the kernel tests run on PoCL; this one checks the device the GPU
// layout is for): the gallery with the device's defaults (GPU layout, pinned readback), run after
// run into one grid (the counted first run, then one-wait runs), equals that device's brute force.
TEST(ImplicitOnGpu, GalleryEqualsBruteForceRunAfterRun) {
    std::unique_ptr<Context> gpu;
    for (const DeviceInfo& d : list_devices()) {
        if (d.type == "gpu" && d.available && d.compiler_available) {
            gpu = std::make_unique<Context>(d);
            break;
        }
    }
    if (!gpu) {
        GTEST_SKIP() << "no OpenCL GPU";
    }
    for (const char* name : {"bracket", "gear_ring", "pipe_elbow"}) {
        const sdf::Part part = sdf::load_part(std::filesystem::path(VOXFIELD_DATA_DIR) / "parts" /
                                              (std::string(name) + ".sdf.json"));
        const Brute brute = brute_force(*gpu, part);
        for (std::uint32_t depth : {1u, 2u}) {
            ImplicitDiscretiser job(*gpu, part, {depth, Layout::automatic});
            EXPECT_TRUE(job.gpu_layout());
            ImplicitGrid grid;
            for (int i = 0; i < 3; ++i) {
                const std::string what = std::string(name) + " depth " + std::to_string(depth) +
                                         " run " + std::to_string(i) + " on " + gpu->info().name;
                job.run(grid);
                EXPECT_EQ(job.timing().counted, i == 0) << what;
                if (i > 0) {
                    EXPECT_EQ(job.timing().syncs, 1u) << what;
                }
                const Check c = compare(part, grid, what, brute);
                EXPECT_GT(c.crossed, 1000u) << what;
                // Against the CPU's float evaluation: a GPU may contract a * b + c into fma.
                EXPECT_LE(c.max_value_error, 1e-5f) << what;
                EXPECT_LE(c.max_gradient_error, 1e-4f) << what;
            }
        }
    }
}

}  // namespace
}  // namespace voxfield::ocl
