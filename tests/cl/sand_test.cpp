// Falling sand on PoCL (cl/sand.hpp): both kernel layouts bit for bit equal to the CPU
// reference (core/sand.hpp), world and change list, step after step; and the distance field
// kept by IncrementalField::apply_changes equal to a full regeneration after every step.
#include <gtest/gtest.h>

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "cl_test_util.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/incremental.hpp"
#include "voxfield/cl/sand.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/sand.hpp"

namespace voxfield {
namespace {

using test::pocl;

// Static solids at random (materials other than the rules'), then sand and water in the rest.
World random_world(Dims dims, std::uint64_t seed, const SandRules& rules) {
    static const std::uint8_t kRocks[] = {1, 4, 5, 6, 7, 10, 11};
    World w(dims);
    std::mt19937_64 gen(seed);
    std::uniform_real_distribution<double> u(0, 1);
    for (std::uint8_t& v : w.voxels()) {
        const double p = u(gen);
        std::uint8_t rock = kRocks[gen() % 7];
        rock = rock == rules.sand || rock == rules.water ? std::uint8_t{12} : rock;
        v = p < 0.15 ? rock : p < 0.4 ? rules.sand : p < 0.55 ? rules.water : std::uint8_t{0};
    }
    return w;
}

const char* name_of(ocl::Layout layout) {
    return layout == ocl::Layout::cpu ? "cpu layout" : "gpu layout";
}

// Runs `steps` steps on the device and on the CPU and compares both after each.
void expect_reference(World world, const SandRules& rules, std::uint64_t seed, std::uint64_t steps,
                      ocl::Layout layout) {
    ocl::SandSimulator sim(pocl(), world, rules, layout);
    EXPECT_EQ(sim.variant(), name_of(layout));
    std::size_t moved = 0;
    for (std::uint64_t step = 0; step < steps; ++step) {
        const VoxelChanges want = sand_step(world, rules, seed, step);
        const ocl::SandStepResult got = sim.step(seed, step);
        ASSERT_EQ(got.changes, want)
            << world.dims().to_string() << ", " << name_of(layout) << ", step " << step;
        ASSERT_EQ(sim.read_world(), world.voxels())
            << world.dims().to_string() << ", " << name_of(layout) << ", step " << step;
        EXPECT_GE(got.simulate_ms, 0.0);
        moved += want.size();
    }
    EXPECT_GT(moved, 0u) << world.dims().to_string();
}

TEST(SandCl, BothLayoutsMatchTheReferenceOnRandomWorlds) {
    const std::vector<std::pair<Dims, SandRules>> cases = {
        {Dims{23, 17, 19}, SandRules{}},   {Dims{16, 16, 16}, SandRules{}},
        {Dims{1, 9, 2}, SandRules{}},      {Dims{40, 8, 3}, SandRules{9, 8}},
        {Dims{7, 30, 5}, SandRules{3, 2}},
    };
    std::uint64_t seed = 1;
    for (const auto& [dims, rules] : cases) {
        const World w = random_world(dims, seed, rules);
        for (const ocl::Layout layout : {ocl::Layout::cpu, ocl::Layout::gpu}) {
            expect_reference(w, rules, seed * 1000 + 7, 48, layout);
        }
        ++seed;
    }
}

TEST(SandCl, BothLayoutsMatchTheReferenceOnTheBasinScene) {
    const World w = scene_sand(Dims{48, 40, 44}, 5);
    for (const ocl::Layout layout : {ocl::Layout::cpu, ocl::Layout::gpu}) {
        expect_reference(w, SandRules{}, 123456789, 96, layout);
    }
}

TEST(SandCl, AStepThatChangesEveryVoxelGrowsTheChangeList) {
    // Sand on every odd y, air on every even y: in step 0 (block offset 0) every grain falls,
    // so all 32^3 voxels change, past the first list's room (1/8 of the voxels).
    const Dims d{32, 32, 32};
    World w(d);
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 1; y < d.y; y += 2) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                w.set(x, y, z, SandRules{}.sand);
            }
        }
    }
    for (const ocl::Layout layout : {ocl::Layout::cpu, ocl::Layout::gpu}) {
        World ref = w;
        ocl::SandSimulator sim(pocl(), w, SandRules{}, layout);
        for (std::uint64_t step = 0; step < 6; ++step) {
            const VoxelChanges want = sand_step(ref, SandRules{}, 3, step);
            if (step == 0) {
                ASSERT_EQ(want.size(), d.count());
            }
            ASSERT_EQ(sim.step(3, step).changes, want) << name_of(layout) << ", step " << step;
            ASSERT_EQ(sim.read_world(), ref.voxels()) << name_of(layout) << ", step " << step;
        }
    }
}

// A 48 x 32 x 48 floor with a block of sand and water falling in one corner: the steps'
// changes span little of the world, so the field is updated incrementally.
World corner_sand() {
    World w(Dims{48, 32, 48});
    for (std::uint32_t z = 0; z < 48; ++z) {
        for (std::uint32_t x = 0; x < 48; ++x) {
            w.set(x, 0, z, 1);
        }
    }
    for (std::uint32_t z = 3; z < 9; ++z) {
        for (std::uint32_t y = 8; y < 14; ++y) {
            for (std::uint32_t x = 3; x < 9; ++x) {
                w.set(x, y, z, (x + y + z) % 3 == 0 ? SandRules{}.water : SandRules{}.sand);
            }
        }
    }
    return w;
}

TEST(SandCl, FieldEqualsAFullRegenerationAfterEveryStep) {
    // scene_sand changes voxels all over its world each step (the field is regenerated whole);
    // corner_sand's steps change a corner (updated incrementally).
    for (const World& start : {scene_sand(Dims{32, 28, 30}, 9), corner_sand()}) {
        const bool local = start.dims().x == 48;
        const Palette palette = Palette::magicavoxel_default();
        for (const Format format : {Format::u16, Format::packed32}) {
            ocl::GeneratorOptions o;
            o.format = format;
            o = ocl::resolve_options(o, start.dims());
            ocl::IncrementalField field(pocl(), start, palette, o);
            ocl::SandSimulator sim(pocl(), start, SandRules{});
            std::size_t changed = 0;
            for (std::uint64_t step = 0; step < 24; ++step) {
                const ocl::SandStepResult r = sim.step(42, step);
                changed += r.changes.size();
                const ocl::UpdateStats u = field.apply_changes(r.changes);
                if (!r.changes.empty()) {
                    EXPECT_EQ(u.full_regeneration, !local) << "step " << step;
                }
                ASSERT_EQ(field.world().voxels(), sim.read_world()) << "step " << step;
                const std::vector<std::uint8_t> full =
                    ocl::generate(pocl(), field.world(), palette, o).bytes;
                ASSERT_EQ(test::first_difference(field.read(), full, format, start.dims()), "")
                    << to_string(format) << ", after step " << step;
            }
            EXPECT_GT(changed, local ? 100u : 1000u);
        }
    }
}

}  // namespace
}  // namespace voxfield
