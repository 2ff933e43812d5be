// Falling sand and water on sparse worlds (cl/sparse_sand.hpp) on PoCL: after every step the
// world equals the CPU reference automaton's (core/sand.hpp) on the same dense world, and the
// field equals the dense bounded field of it; random worlds of sand, water and rock, awkward
// sizes, tiles cut by the world's edge, empty tiles between busy ones, several bounds, metrics
// and formats (signed too), both layouts, brushes between steps and a jump in the step numbers.
#include <gtest/gtest.h>

#include <random>
#include <string>

#include "cl_test_util.hpp"
#include "voxfield/cl/sparse_sand.hpp"
#include "voxfield/core/brush.hpp"

namespace voxfield {
namespace {

using ocl::Layout;
using test::pocl;

// Rock boxes, a pool of water, a heap of sand and grains in the air; the rest air.
World sandy_world(Dims d, std::mt19937& rng, const SandRules& rules) {
    World w(d);
    auto pick = [&](std::uint32_t n) {
        return std::uniform_int_distribution<std::uint32_t>(0, n - 1)(rng);
    };
    auto fill = [&](std::uint32_t x0, std::uint32_t y0, std::uint32_t z0, std::uint32_t r,
                    std::uint8_t m) {
        for (std::uint32_t z = z0 > r ? z0 - r : 0; z <= std::min(d.z - 1, z0 + r); ++z) {
            for (std::uint32_t y = y0 > r ? y0 - r : 0; y <= std::min(d.y - 1, y0 + r); ++y) {
                for (std::uint32_t x = x0 > r ? x0 - r : 0; x <= std::min(d.x - 1, x0 + r); ++x) {
                    w.set(x, y, z, m);
                }
            }
        }
    };
    for (int b = 0; b < 4; ++b) {
        fill(pick(d.x), pick(d.y / 2), pick(d.z), 2 + pick(6), 1);
    }
    for (int b = 0; b < 3; ++b) {
        fill(pick(d.x), d.y / 2 + pick(d.y - d.y / 2), pick(d.z), 1 + pick(5), rules.water);
        fill(pick(d.x), d.y / 2 + pick(d.y - d.y / 2), pick(d.z), 1 + pick(5), rules.sand);
    }
    std::bernoulli_distribution grain(0.002);
    for (auto& v : w.voxels()) {
        if (v == 0 && grain(rng)) {
            v = grain(rng) ? rules.water : rules.sand;
        }
    }
    return w;
}

ocl::GeneratorOptions bounded(double bound, Layout layout, Metric metric = Metric::manhattan,
                              bool signed_field = false, Format format = Format::u16) {
    ocl::GeneratorOptions o;
    o.metric = metric;
    o.signed_field = signed_field;
    o.format = format;
    o.layout = layout;
    o.max_distance = bound;
    return ocl::resolve_sparse_options(o, true);
}

// Steps `steps` times from `first` on both, comparing world and field after every step.
void expect_steps_equal(World& dense, ocl::SparseField& field, ocl::SparseSand& sim,
                        const Palette& p, const SandRules& rules, std::uint64_t seed,
                        std::uint64_t first, int steps, const std::string& what) {
    const ocl::GeneratorOptions& o = field.options();
    for (std::uint64_t s = first; s < first + static_cast<std::uint64_t>(steps); ++s) {
        const VoxelChanges want = sand_step(dense, rules, seed, s);
        const ocl::SparseSand::Step got = sim.step(seed, s);
        ASSERT_EQ(got.changed, want.size()) << what << " step " << s;
        ASSERT_EQ(field.world().to_dense().voxels(), dense.voxels()) << what << " step " << s;
        const std::string diff = test::first_difference(
            field.read_dense(), ocl::generate(pocl(), dense, p, o).bytes, o.format, dense.dims());
        ASSERT_EQ(diff, "") << what << " step " << s;
    }
}

TEST(SparseSand, StepsEqualDenseAutomatonAndBoundedField) {
    std::mt19937 rng(2024);
    const Palette p = Palette::magicavoxel_default();
    const SandRules rules{2, 3};
    struct Case {
        Dims dims;
        double bound;
        Layout layout;
        Metric metric;
        bool signed_field;
        Format format;
        int steps;
    };
    for (const Case& c :
         {Case{{70, 75, 67}, 4, Layout::cpu, Metric::manhattan, false, Format::u16, 20},
          Case{{129, 66, 65}, 9, Layout::gpu, Metric::euclidean, true, Format::i16, 12},
          Case{{64, 64, 64}, 16, Layout::cpu, Metric::manhattan, false, Format::u8, 12},
          Case{{41, 130, 33}, 3, Layout::cpu, Metric::chebyshev, false, Format::f32, 12},
          Case{{200, 40, 30}, 6, Layout::gpu, Metric::manhattan, true, Format::i16, 12},
          // Changes too far apart for one block of their hull: blocks per region or per tile.
          Case{{300, 70, 260}, 12, Layout::cpu, Metric::manhattan, false, Format::u8, 10}}) {
        World dense = sandy_world(c.dims, rng, rules);
        SparseWorld sparse = SparseWorld::from_dense(dense);
        ocl::SparseField field(pocl(), sparse, p,
                               bounded(c.bound, c.layout, c.metric, c.signed_field, c.format));
        field.run();
        ocl::SparseSand sim(pocl(), field, rules);
        const std::string what =
            c.dims.to_string() + " " + to_string(c.metric) + " D " + std::to_string(c.bound);
        expect_steps_equal(dense, field, sim, p, rules, 7, 0, c.steps, what);
    }
}

TEST(SparseSand, BrushesAndJumpsBetweenSteps) {
    std::mt19937 rng(77);
    const Palette p = Palette::magicavoxel_default();
    const SandRules rules{5, 9};
    // Empty tiles between: sand at one end, water at the other.
    World dense(Dims{260, 70, 66});
    for (std::uint32_t z = 10; z < 40; ++z) {
        for (std::uint32_t x = 0; x < 30; ++x) {
            for (std::uint32_t y = 40; y < 60; ++y) {
                dense.set(x, y, z, rules.sand);
                dense.set(259 - x, y, z, rules.water);
            }
        }
    }
    SparseWorld sparse = SparseWorld::from_dense(dense);
    ocl::SparseField field(pocl(), sparse, p, bounded(5, Layout::cpu));
    field.run();
    ocl::SparseSand sim(pocl(), field, rules);
    expect_steps_equal(dense, field, sim, p, rules, 3, 0, 12, "start");
    for (int e = 0; e < 3; ++e) {
        Brush b;
        b.op = BrushOp::place;
        b.material = e == 1 ? rules.water : rules.sand;
        b.centre = {std::uniform_int_distribution<std::int64_t>(0, 259)(rng), 60,
                    std::uniform_int_distribution<std::int64_t>(0, 65)(rng)};
        b.radius = 4;
        apply_brush(dense, b);
        field.apply_brush(b);
        sim.touched(brush_bounds(b, dense.dims()));
        expect_steps_equal(dense, field, sim, p, rules, 3, 12 + 3 * e, 3,
                           "after brush " + std::to_string(e));
    }
    // Step numbers that do not follow on: every tile near sand or water runs again.
    expect_steps_equal(dense, field, sim, p, rules, 3, 100, 10, "after a jump");
}

}  // namespace
}  // namespace voxfield
