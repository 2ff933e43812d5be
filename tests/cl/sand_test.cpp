// Falling sand on PoCL (cl/sand.hpp): both kernel layouts, stepping in place, bit for bit equal
// to the CPU reference (core/sand.hpp), world, change list and change boxes, step after step;
// and the distance field kept by IncrementalField::apply_device_changes (the changes never
// leave the device) equal to a full regeneration after every step.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
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

// The world on the PoCL device, for a simulator of its own.
cl::Buffer upload(const World& w) {
    cl::Buffer b(pocl().context(), CL_MEM_READ_WRITE, w.size());
    pocl().queue().enqueueWriteBuffer(b, CL_TRUE, 0, w.size(), w.voxels().data());
    return b;
}

std::vector<std::uint8_t> download(const cl::Buffer& b, std::size_t n) {
    std::vector<std::uint8_t> v(n);
    pocl().queue().enqueueReadBuffer(b, CL_TRUE, 0, n, v.data());
    return v;
}

// The boxes of `changes` (all; occupancy only).
std::array<Box, 2> boxes_of(const VoxelChanges& changes, Dims d) {
    std::array<Box, 2> boxes;
    for (const VoxelChange& c : changes) {
        const auto x = static_cast<std::int64_t>(c.index % d.x);
        const auto y = static_cast<std::int64_t>(c.index / d.x % d.y);
        const auto z = static_cast<std::int64_t>(c.index / d.x / d.y);
        const Box voxel{{x, y, z}, {x + 1, y + 1, z + 1}};
        boxes[0] = hull(boxes[0], voxel);
        if ((c.before == 0) != (c.after == 0)) {
            boxes[1] = hull(boxes[1], voxel);
        }
    }
    return boxes;
}

// Runs `steps` steps on the device and on the CPU and compares both after each.
void expect_reference(World world, const SandRules& rules, std::uint64_t seed, std::uint64_t steps,
                      ocl::Layout layout) {
    const cl::Buffer voxels = upload(world);
    ocl::SandSimulator sim(pocl(), voxels, world.dims(), rules, layout, world.size());
    EXPECT_EQ(sim.variant(), name_of(layout));
    std::size_t moved = 0;
    for (std::uint64_t step = 0; step < steps; ++step) {
        const VoxelChanges want = sand_step(world, rules, seed, step);
        const ocl::SandStepResult got = sim.step(seed, step);
        const std::string where =
            world.dims().to_string() + ", " + name_of(layout) + ", step " + std::to_string(step);
        ASSERT_EQ(got.changes.count, want.size()) << where;
        ASSERT_FALSE(got.changes.overflow()) << where;
        ASSERT_EQ(sim.read_changes(), want) << where;
        const std::array<Box, 2> boxes = boxes_of(want, world.dims());
        EXPECT_EQ(got.changes.bounds, boxes[0]) << where;
        EXPECT_EQ(got.changes.occupancy_bounds, boxes[1]) << where;
        ASSERT_EQ(download(voxels, world.size()), world.voxels()) << where;
        moved += want.size();
    }
    EXPECT_GT(moved, 0u) << world.dims().to_string();
}

TEST(SandCl, BothLayoutsMatchTheReferenceOnRandomWorlds) {
    const std::vector<std::pair<Dims, SandRules>> cases = {
        {Dims{23, 17, 19}, SandRules{}},   {Dims{16, 16, 16}, SandRules{}},
        {Dims{1, 9, 2}, SandRules{}},      {Dims{40, 8, 3}, SandRules{9, 8}},
        {Dims{7, 30, 5}, SandRules{3, 2}}, {Dims{37, 21, 2}, SandRules{}},
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

TEST(SandCl, AStepThatOverflowsTheListStillStepsTheWholeWorld) {
    // Sand on every odd y, air on every even y: in step 0 (block offset 0) every grain falls,
    // so all 32^3 voxels change, past the list's default room (1/8 of the voxels).
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
        const cl::Buffer voxels = upload(w);
        ocl::SandSimulator sim(pocl(), voxels, d, SandRules{}, layout);
        for (std::uint64_t step = 0; step < 6; ++step) {
            const VoxelChanges want = sand_step(ref, SandRules{}, 3, step);
            const ocl::SandStepResult got = sim.step(3, step);
            ASSERT_EQ(got.changes.count, want.size()) << name_of(layout) << ", step " << step;
            if (step == 0) {
                ASSERT_EQ(want.size(), d.count());
                EXPECT_TRUE(got.changes.overflow());
                EXPECT_THROW(sim.read_changes(), std::logic_error);
            }
            if (!got.changes.overflow()) {
                ASSERT_EQ(sim.read_changes(), want) << name_of(layout) << ", step " << step;
            }
            ASSERT_EQ(download(voxels, d.count()), ref.voxels())
                << name_of(layout) << ", step " << step;
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

std::array<std::size_t, 256> histogram(const World& w) {
    std::array<std::size_t, 256> h{};
    for (const std::uint8_t v : w.voxels()) {
        ++h[v];
    }
    return h;
}

struct FieldCase {
    const char* name;
    ocl::GeneratorOptions options;
    std::size_t capacity;  // the change list's room (0: the default)
};

std::vector<FieldCase> field_cases() {
    std::vector<FieldCase> cases;
    auto add = [&](const char* name, Format f, Metric m, ocl::Layout layout,
                   std::optional<double> bound, std::size_t capacity) {
        ocl::GeneratorOptions o;
        o.format = f;
        o.metric = m;
        o.layout = layout;
        o.max_distance = bound;
        cases.push_back({name, o, capacity});
    };
    add("L1 u16 cpu layout", Format::u16, Metric::manhattan, ocl::Layout::cpu, {}, 0);
    add("L1 u16 gpu layout", Format::u16, Metric::manhattan, ocl::Layout::gpu, {}, 0);
    add("L1 packed32", Format::packed32, Metric::manhattan, ocl::Layout::automatic, {}, 0);
    add("L1 bounded at 5", Format::u16, Metric::manhattan, ocl::Layout::automatic, 5.0, 0);
    add("L1, a list of 64", Format::u16, Metric::manhattan, ocl::Layout::automatic, {}, 64);
    add("L-inf u16", Format::u16, Metric::chebyshev, ocl::Layout::automatic, {}, 0);
    add("L2 f32 cpu layout", Format::f32, Metric::euclidean, ocl::Layout::cpu, {}, 0);
    add("L2 f32 gpu layout", Format::f32, Metric::euclidean, ocl::Layout::gpu, {}, 64);
    ocl::GeneratorOptions chunked;
    chunked.algorithm = ocl::Algorithm::jfa_fim;
    chunked.chunk = 8;
    chunked.format = Format::u16;
    cases.push_back({"jfa-fim chunk 8", chunked, 0});
    cases.push_back({"jfa-fim chunk 8, a list of 64", chunked, 64});
    return cases;
}

TEST(SandCl, FieldEqualsAFullRegenerationAfterEveryStepInPlace) {
    // scene_sand changes voxels all over its world each step (the field is regenerated whole);
    // corner_sand's steps change a corner (updated incrementally, from the device list); a
    // list of 64 overflows on most steps (regenerated, also on the device).
    const Palette palette = Palette::magicavoxel_default();
    for (const World& start : {scene_sand(Dims{32, 28, 30}, 9), corner_sand()}) {
        const bool local = start.dims().x == 48;
        for (const FieldCase& c : field_cases()) {
            const ocl::GeneratorOptions o = ocl::resolve_options(c.options, start.dims());
            ocl::IncrementalField field(pocl(), start, palette, o);
            ocl::SandSimulator sim(pocl(), field.voxels_buffer(), start.dims(), SandRules{},
                                   ocl::Layout::automatic, c.capacity);
            World ref = start;
            std::size_t changed = 0, local_updates = 0;
            for (std::uint64_t step = 0; step < 24; ++step) {
                const VoxelChanges want = sand_step(ref, SandRules{}, 42, step);
                const ocl::SandStepResult r = sim.step(42, step);
                ASSERT_EQ(r.changes.count, want.size()) << c.name << ", step " << step;
                changed += want.size();
                const ocl::UpdateStats u = field.apply_device_changes(r.changes);
                EXPECT_TRUE(u.edits.empty());
                if (!want.empty() && !u.full_regeneration) {
                    ++local_updates;
                }
                // A global field regenerates whole after changes all over the world (a
                // chunk-local one recomputes the chunks holding them, unless the list
                // overflowed).
                if (!local && !want.empty() && c.options.chunk == 0) {
                    EXPECT_TRUE(u.full_regeneration) << c.name << ", step " << step;
                }
                if (step % 3 == 0 || step == 23) {
                    ASSERT_EQ(field.world().voxels(), ref.voxels()) << c.name << ", step " << step;
                }
                const std::vector<std::uint8_t> full = ocl::generate(pocl(), ref, palette, o).bytes;
                ASSERT_EQ(test::first_difference(field.read(), full, o.format, start.dims()), "")
                    << c.name << ", " << start.dims().to_string() << ", after step " << step;
            }
            EXPECT_EQ(histogram(field.world()), histogram(start)) << c.name;
            EXPECT_GT(changed, local ? 100u : 1000u);
            if (local && c.capacity == 0) {
                EXPECT_GT(local_updates, 0u) << c.name;
            }
        }
    }
}

TEST(SandCl, HostEditsAfterDeviceStepsSeeTheSteppedWorld) {
    // A brush after steps made on the device: the host world is read back first, so the
    // brush's changes (and an undo of them) start from the world the steps left.
    const World start = corner_sand();
    ocl::GeneratorOptions o;
    o.format = Format::u16;
    o = ocl::resolve_options(o, start.dims());
    ocl::IncrementalField field(pocl(), start, Palette(), o);
    ocl::SandSimulator sim(pocl(), field.voxels_buffer(), start.dims(), SandRules{});
    World ref = start;
    for (std::uint64_t step = 0; step < 5; ++step) {
        sand_step(ref, SandRules{}, 7, step);
        field.apply_device_changes(sim.step(7, step).changes);
    }
    const Brush brush{BrushOp::place, BrushShape::sphere, {6, 10, 6}, 3, 5};
    const ocl::UpdateStats u = field.apply({brush});
    const EditResult want = apply_brush(ref, brush);
    ASSERT_EQ(u.edits.size(), 1u);
    EXPECT_EQ(u.edits[0].changes, want.changes);
    EXPECT_EQ(field.world().voxels(), ref.voxels());
    EXPECT_EQ(test::first_difference(field.read(), ocl::generate(pocl(), ref, Palette(), o).bytes,
                                     o.format, ref.dims()),
              "");
}

}  // namespace
}  // namespace voxfield
