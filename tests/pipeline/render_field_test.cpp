// pipeline::RenderField on PoCL + lavapipe, validated (synchronisation included): after random
// edits, with a frame in flight during each, the ray marcher reads exactly the field a fresh
// conversion gives; path 3 moves only the changed boxes and blocks (counted), in place and
// ordered behind the frames by the queue; paths 1/2 wait only for the frames that read the field.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <vector>

#include "../cl/cl_test_util.hpp"
#include "../vk/vulkan_env.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/incremental.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/undo.hpp"
#include "voxfield/layout.h"
#include "voxfield/pipeline/render_field.hpp"

namespace voxfield::test {
namespace {

constexpr Dims kDims{40, 24, 32};

vk::RenderOptions view(const World& world) {
    vk::RenderOptions r;
    r.width = 64;
    r.height = 48;
    r.camera = vk::default_camera(world, r.width, r.height, r.camera.fov_deg);
    return r;
}

// The compact render field of a u16 field of `world` (layout.h VF_COMPACT_*), from the host.
std::vector<std::uint16_t> compact_of(const std::vector<std::uint8_t>& field, const World& world) {
    std::vector<std::uint16_t> out(world.size());
    for (std::size_t i = 0; i < out.size(); ++i) {
        std::uint16_t d = 0;
        std::memcpy(&d, &field[2 * i], 2);
        out[i] = static_cast<std::uint16_t>(
            (std::min<std::uint32_t>(d, VF_COMPACT_DISTANCE_MAX) << VF_COMPACT_DISTANCE_SHIFT) |
            world.voxels()[i]);
    }
    return out;
}

std::uint64_t volume_in(const std::vector<Box>& boxes, const Box& world) {
    std::uint64_t v = 0;
    for (const Box& b : boxes) {
        const Box c = intersect(b, world);
        v += c.empty() ? 0 : static_cast<std::uint64_t>(c.volume());
    }
    return v;
}

// What an edit changed for a render field: the recomputed distances' boxes and the boxes of
// the voxels the brushes changed (recoloured voxels keep their distance), as pipeline::Scene
// lists them.
std::vector<Box> changed_regions(const ocl::UpdateStats& s) {
    std::vector<Box> regions = s.regions;
    for (const EditResult& e : s.edits) {
        if (e.changed()) {
            regions.push_back(e.bounds);
        }
    }
    return regions;
}

ocl::GeneratorOptions u16_manhattan() {
    ocl::GeneratorOptions g;
    g.format = Format::u16;
    g.metric = Metric::manhattan;
    return ocl::resolve_options(g, kDims);
}

class RenderFieldEdits : public ::testing::TestWithParam<vk::SharingPath> {};

TEST_P(RenderFieldEdits, RandomEditsWithFramesInFlightShowTheFreshField) {
    vk::Context& ctx = validated_vulkan();
    const Palette palette;
    ocl::IncrementalField field(pocl(), make_scene("spheres", kDims, 11), palette, u16_manhattan());
    vk::Raymarcher marcher(ctx);
    pipeline::RenderField render(pocl(), ctx, marcher, kDims, GetParam());
    ASSERT_EQ(render.path(), GetParam()) << render.why_not();
    render.attach(marcher, field.field_buffer(), Format::u16, Metric::manhattan,
                  field.voxels_buffer(), palette);
    const vk::RenderOptions r = view(field.world());
    const Box world{{0, 0, 0}, {kDims.x, kDims.y, kDims.z}};
    RandomEdits edits(kDims, 8, 2024);
    for (int i = 0; i < 12; ++i) {
        SCOPED_TRACE("edit " + std::to_string(i));
        // A frame in flight reads the field while the edit rewrites it.
        ctx.submit_unwaited([&](VkCommandBuffer cmd) { marcher.record(cmd, r); }, "frame");
        const std::vector<Box> regions = changed_regions(field.apply({edits.next()}));
        const std::uint64_t copied = marcher.bytes_copied();
        const std::uint64_t table = marcher.block_min_bytes_copied();
        render.update(marcher, regions);
        if (GetParam() == vk::SharingPath::copy) {
            // Exactly the changed boxes' voxels and their blocks' minima moved.
            EXPECT_EQ(marcher.bytes_copied() - copied, 2 * volume_in(regions, world));
            EXPECT_LT(marcher.bytes_copied() - copied, 2 * kDims.count() / 4);
            const std::uint32_t b = VF_RAYMARCH_BLOCK;
            std::vector<Box> blocks;
            for (const Box& x : regions) {
                const Box c = intersect(x, world);
                if (!c.empty()) {
                    blocks.push_back(
                        Box{{c.min.x / b, c.min.y / b, c.min.z / b},
                            {(c.max.x + b - 1) / b, (c.max.y + b - 1) / b, (c.max.z + b - 1) / b}});
                }
            }
            EXPECT_EQ(marcher.block_min_bytes_copied() - table, 4 * volume_in(blocks, world));
            EXPECT_EQ(marcher.read_compact(), compact_of(field.read(), field.world()));
        } else {
            EXPECT_EQ(marcher.bytes_copied(), 0u) << "the shared field was copied";
        }
    }
    // The edited field (and its block minima) renders as a fresh conversion of it.
    vk::Raymarcher fresh(ctx);
    pipeline::RenderField fresh_field(pocl(), ctx, fresh, kDims, vk::SharingPath::copy);
    fresh_field.attach(fresh, field.field_buffer(), Format::u16, Metric::manhattan,
                       field.voxels_buffer(), palette);
    EXPECT_EQ(marcher.render(r).rgba, fresh.render(r).rgba);
    if (GetParam() == vk::SharingPath::copy) {
        EXPECT_EQ(marcher.read_compact(), fresh.read_compact());
    }
}

INSTANTIATE_TEST_SUITE_P(Paths, RenderFieldEdits,
                         ::testing::Values(vk::SharingPath::host_pointer, vk::SharingPath::copy),
                         [](const auto& p) {
                             return p.param == vk::SharingPath::copy ? std::string("Copy")
                                                                     : std::string("HostPointer");
                         });

// The packed32 render format (always copied): an edit moves its boxes' words and materials
// (5 bytes per voxel), in place behind a frame in flight, and the image equals a fresh upload.
TEST(PackedField, RandomEditsCopyOnlyTheirBoxes) {
    vk::Context& ctx = validated_vulkan();
    const Palette palette;
    ocl::GeneratorOptions g;
    g.format = Format::packed32;
    ocl::IncrementalField field(pocl(), make_scene("spheres", kDims, 12), palette,
                                ocl::resolve_options(g, kDims));
    const auto words = [&] {
        const std::vector<std::uint8_t> bytes = field.read();
        std::vector<std::uint32_t> w(bytes.size() / 4);
        std::memcpy(w.data(), bytes.data(), bytes.size());
        return w;
    };
    vk::Raymarcher marcher(ctx);
    marcher.upload(field.world(), palette, words());
    const vk::RenderOptions r = view(field.world());
    const Box world{{0, 0, 0}, {kDims.x, kDims.y, kDims.z}};
    RandomEdits edits(kDims, 8, 77);
    for (int i = 0; i < 10; ++i) {
        SCOPED_TRACE("edit " + std::to_string(i));
        ctx.submit_unwaited([&](VkCommandBuffer cmd) { marcher.record(cmd, r); }, "frame");
        const std::vector<Box> regions = changed_regions(field.apply({edits.next()}));
        const std::uint64_t copied = marcher.bytes_copied();
        pipeline::update_packed32(pocl(), marcher, field.field_buffer(), field.voxels_buffer(),
                                  kDims, regions);
        EXPECT_EQ(marcher.bytes_copied() - copied, 5 * volume_in(regions, world));
    }
    vk::Raymarcher fresh(ctx);
    fresh.upload(field.world(), palette, words());
    EXPECT_EQ(marcher.render(r).rgba, fresh.render(r).rgba);
    vk::RenderOptions lit = r;
    lit.shading = vk::Shading::lit;
    EXPECT_EQ(marcher.render(lit).rgba, fresh.render(lit).rgba);
}

}  // namespace
}  // namespace voxfield::test
