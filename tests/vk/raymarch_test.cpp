// The Vulkan ray marcher on lavapipe (or any Vulkan device) against an independent CPU ray
// caster: exact voxel traversal of the world itself (no distance field) in double precision.
// Every scene runs in both field formats (packed32 and compact).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "voxfield/core/error.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/layout.h"
#include "voxfield/vk/raymarcher.hpp"
#include "vulkan_env.hpp"

namespace voxfield::test {
namespace {

using vk::Vec3;

// One Vulkan context for the whole suite; without a Vulkan device every test fails.
vk::Context& vulkan() {
    return validated_vulkan();
}

std::vector<std::uint32_t> packed_field(const World& world, const Palette& palette) {
    const auto bytes = encode_field(reference_manhattan(world), world, palette, Format::packed32);
    std::vector<std::uint32_t> out(world.size());
    std::memcpy(out.data(), bytes.data(), bytes.size());
    return out;
}

// compact: (min(d, 255) << 8) | material, from the CPU reference distances.
std::vector<std::uint16_t> compact_field(const World& world) {
    const auto d = reference_manhattan(world);
    std::vector<std::uint16_t> out(world.size());
    for (std::size_t i = 0; i < out.size(); ++i) {
        out[i] = static_cast<std::uint16_t>((std::min<std::uint32_t>(d[i], 255) << 8) |
                                            world.voxels()[i]);
    }
    return out;
}

void upload(vk::Raymarcher& marcher, const World& world, const Palette& palette,
            vk::FieldFormat format) {
    if (format == vk::FieldFormat::packed32) {
        marcher.upload(world, palette, packed_field(world, palette));
    } else {
        marcher.upload_compact(world.dims(), palette, compact_field(world));
    }
}

// ---- The CPU reference caster (independent of vk/: its own camera and traversal). ----

Vec3 normalized(Vec3 v) {
    const double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    return {v[0] / n, v[1] / n, v[2] / n};
}

// The palette colour of the first solid voxel along the ray, or nullopt-like false on a miss.
bool cast(const World& world, const Vec3& o, const Vec3& d, std::uint8_t& material) {
    const Dims dims = world.dims();
    const std::array<double, 3> size = {double(dims.x), double(dims.y), double(dims.z)};
    double t0 = 0, t1 = INFINITY;
    for (std::size_t a = 0; a < 3; ++a) {
        if (d[a] == 0) {
            if (o[a] < 0 || o[a] >= size[a]) {
                return false;
            }
            continue;
        }
        double ta = (0 - o[a]) / d[a], tb = (size[a] - o[a]) / d[a];
        if (ta > tb) {
            std::swap(ta, tb);
        }
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    if (!(t0 < t1)) {
        return false;
    }
    // Start in the cell containing the midpoint of the first short stretch inside the box,
    // which is robust against the entry point lying on a face.
    const double tm = t0 + std::min(1e-9, (t1 - t0) / 2);
    std::array<std::int64_t, 3> cell{}, step{};
    std::array<double, 3> t_next{};
    for (std::size_t a = 0; a < 3; ++a) {
        const double p = o[a] + d[a] * tm;
        cell[a] = std::clamp<std::int64_t>(static_cast<std::int64_t>(std::floor(p)), 0,
                                           static_cast<std::int64_t>(size[a]) - 1);
        step[a] = d[a] > 0 ? 1 : (d[a] < 0 ? -1 : 0);
        t_next[a] =
            step[a] == 0 ? INFINITY : (double(cell[a] + (step[a] > 0 ? 1 : 0)) - o[a]) / d[a];
    }
    for (;;) {
        const std::uint8_t v =
            world.at(static_cast<std::uint32_t>(cell[0]), static_cast<std::uint32_t>(cell[1]),
                     static_cast<std::uint32_t>(cell[2]));
        if (v != 0) {
            material = v;
            return true;
        }
        std::size_t a = 0;
        if (t_next[1] < t_next[a]) {
            a = 1;
        }
        if (t_next[2] < t_next[a]) {
            a = 2;
        }
        cell[a] += step[a];
        if (cell[a] < 0 || cell[a] >= static_cast<std::int64_t>(size[a])) {
            return false;
        }
        t_next[a] = (double(cell[a] + (step[a] > 0 ? 1 : 0)) - o[a]) / d[a];
    }
}

// RGBA8 image of flat shading: the palette colour of the hit voxel (alpha 255), else sky.
std::vector<std::uint8_t> cpu_render(const World& world, const Palette& palette,
                                     const vk::RenderOptions& r) {
    const Vec3 p = r.camera.position;
    const Vec3 f = normalized(
        {r.camera.target[0] - p[0], r.camera.target[1] - p[1], r.camera.target[2] - p[2]});
    Vec3 right = {-f[2], 0, f[0]};  // cross(f, +y)
    if (std::hypot(right[0], right[2]) < 1e-9) {
        right = {1, 0, 0};
    }
    right = normalized(right);
    const Vec3 up = {right[1] * f[2] - right[2] * f[1], right[2] * f[0] - right[0] * f[2],
                     right[0] * f[1] - right[1] * f[0]};
    const double h = std::tan(r.camera.fov_deg / 2 * M_PI / 180);
    const double aspect = double(r.width) / double(r.height);
    std::vector<std::uint8_t> out(std::size_t{r.width} * r.height * 4);
    for (std::uint32_t j = 0; j < r.height; ++j) {
        for (std::uint32_t i = 0; i < r.width; ++i) {
            const double sx = ((i + 0.5) / r.width * 2 - 1) * aspect * h;
            const double sy = (1 - (j + 0.5) / r.height * 2) * h;
            const Vec3 d =
                normalized({f[0] + sx * right[0] + sy * up[0], f[1] + sx * right[1] + sy * up[1],
                            f[2] + sx * right[2] + sy * up[2]});
            std::uint8_t m = 0;
            const Rgba c = cast(world, p, d, m) ? palette[m] : r.sky;
            std::uint8_t* px = &out[(std::size_t{j} * r.width + i) * 4];
            px[0] = c.r;
            px[1] = c.g;
            px[2] = c.b;
            px[3] = 255;
        }
    }
    return out;
}

struct Comparison {
    std::size_t differing = 0, sky = 0, pixels = 0;
};

Comparison compare(const std::vector<std::uint8_t>& got, const std::vector<std::uint8_t>& want,
                   Rgba sky) {
    Comparison c;
    c.pixels = want.size() / 4;
    for (std::size_t i = 0; i < c.pixels; ++i) {
        if (std::memcmp(&got[i * 4], &want[i * 4], 4) != 0) {
            ++c.differing;
        }
        if (want[i * 4] == sky.r && want[i * 4 + 1] == sky.g && want[i * 4 + 2] == sky.b) {
            ++c.sky;
        }
    }
    return c;
}

// Renders on the GPU and on the CPU and requires <= 0.5% differing pixels (ties at voxel
// edges); also that the image is not trivial (some hits, and some sky when `want_sky`).
void expect_matches(vk::FieldFormat format, const World& world, const Palette& palette,
                    const vk::RenderOptions& r, std::uint64_t max_binding_bytes = 0,
                    bool want_sky = true, std::uint32_t* bindings = nullptr) {
    vk::Raymarcher marcher(vulkan(), max_binding_bytes);
    upload(marcher, world, palette, format);
    if (bindings != nullptr) {
        *bindings = marcher.field_bindings();
    }
    const vk::Image img = marcher.render(r);
    ASSERT_EQ(img.rgba.size(), std::size_t{r.width} * r.height * 4);
    const auto want = cpu_render(world, palette, r);
    const Comparison c = compare(img.rgba, want, r.sky);
    EXPECT_LE(double(c.differing), 0.005 * double(c.pixels))
        << c.differing << " of " << c.pixels << " pixels differ";
    EXPECT_LT(c.sky, c.pixels) << "nothing was hit: the test would prove nothing";
    if (want_sky) {
        EXPECT_GT(c.sky, 0u) << "no ray missed";
    }
}

vk::RenderOptions options(std::uint32_t w, std::uint32_t h, Vec3 camera, Vec3 target,
                          double fov = 60) {
    vk::RenderOptions r;
    r.width = w;
    r.height = h;
    r.camera.position = camera;
    r.camera.target = target;
    r.camera.fov_deg = fov;
    r.sky = Rgba{0x33, 0x66, 0x99, 255};
    return r;
}

class Raymarch : public ::testing::TestWithParam<vk::FieldFormat> {};

TEST_P(Raymarch, SingleVoxelIncludingABlackMaterial) {
    World world(Dims{8, 8, 8});
    world.set(3, 4, 5, 5);
    Palette palette;
    palette[5] = Rgba{0, 0, 0, 255};  // solid and black: distance 0 marks solids, not colour
    expect_matches(GetParam(), world, palette, options(64, 48, {-6, 9, -4}, {3.5, 4.5, 5.5}, 30));
    world.set(3, 4, 5, 79);
    expect_matches(GetParam(), world, palette, options(64, 48, {12, -3, 14}, {3.5, 4.5, 5.5}, 25));
}

TEST_P(Raymarch, FloorAndSpheres) {
    const World world = scene_floor_spheres(Dims{64, 64, 64}, 6683787);
    vk::RenderOptions r = options(128, 96, {}, {});
    r.camera = vk::default_camera(world.dims());
    expect_matches(GetParam(), world, Palette(), r);
}

TEST_P(Raymarch, MengerSpongeThroughTunnels) {
    const World world = scene_menger(Dims{81, 81, 81});
    ASSERT_GT(world.solid_count(), 0u);
    // Down the z tunnels, slightly off axis so that rays travel far through them.
    expect_matches(GetParam(), world, Palette(),
                   options(96, 96, {40.3, 40.6, -50}, {40.5, 40.5, 81}, 50), 0, false);
    // Oblique, from a corner.
    expect_matches(GetParam(), world, Palette(),
                   options(96, 72, {-30, 95, -40}, {40.5, 40.5, 40.5}));
}

TEST_P(Raymarch, ThinWallsAtGrazingAngles) {
    World world(Dims{64, 64, 64});
    for (std::uint32_t z = 0; z < 64; ++z) {
        for (std::uint32_t y = 0; y < 64; ++y) {
            world.set(32, y, z, 20);  // a one-voxel wall at x = 32
        }
        for (std::uint32_t x = 0; x < 64; ++x) {
            world.set(x, 0, z, 100);  // a one-voxel floor
        }
    }
    // Nearly parallel to the wall and to the floor.
    expect_matches(GetParam(), world, Palette(),
                   options(96, 72, {31.2, 1.3, -80}, {33.4, 0.8, 64}, 40));
    expect_matches(GetParam(), world, Palette(), options(96, 72, {20, 30, -10}, {36, 28, 70}, 70));
}

TEST_P(Raymarch, CameraInsideTheWorld) {
    const World world = scene_floor_spheres(Dims{64, 64, 64}, 6683787);
    expect_matches(GetParam(), world, Palette(), options(96, 72, {10, 20, 12}, {40, 10, 50}, 90), 0,
                   false);
    // Inside a solid voxel: every ray hits it at once.
    World filled(Dims{16, 16, 16});
    filled.set(5, 6, 7, 42);
    expect_matches(GetParam(), filled, Palette(), options(16, 16, {5.5, 6.5, 7.5}, {9, 9, 9}), 0,
                   false);
}

TEST_P(Raymarch, CameraOutsideLookingPast) {
    const World world = scene_floor_spheres(Dims{64, 64, 64}, 6683787);
    // The world is at the right edge of the view; most rays miss it.
    expect_matches(GetParam(), world, Palette(), options(96, 72, {-20, 30, -20}, {-25, 28, 60}));
    // Looking straight away from it: nothing is hit.
    vk::Raymarcher marcher(vulkan());
    upload(marcher, world, Palette(), GetParam());
    const auto r = options(32, 24, {-20, 30, -20}, {-60, 30, -60});
    const auto img = marcher.render(r);
    EXPECT_EQ(compare(img.rgba, cpu_render(world, Palette(), r), r.sky).differing, 0u);
    EXPECT_EQ(compare(img.rgba, cpu_render(world, Palette(), r), r.sky).sky, 32u * 24u);
}

TEST_P(Raymarch, DistantCamera) {
    const World world = scene_floor_spheres(Dims{64, 64, 64}, 6683787);
    // About 5000 voxels away with a narrow field of view: float must not lose the voxels.
    expect_matches(GetParam(), world, Palette(),
                   options(96, 72, {-2900, 2400, -3300}, {32, 20, 32}, 1.2));
}

TEST_P(Raymarch, StraightDownAlongY) {
    const World world = scene_floor_spheres(Dims{48, 40, 32}, 3);
    expect_matches(GetParam(), world, Palette(), options(64, 64, {20.3, 90, 15.2}, {20.3, 0, 15.2}),
                   0, false);
}

TEST_P(Raymarch, FieldSplitAcrossBindings) {
    const World world = scene_floor_spheres(Dims{64, 64, 64}, 6683787);
    vk::RenderOptions r = options(96, 72, {}, {});
    r.camera = vk::default_camera(world.dims());
    std::uint32_t bindings = 0;
    // Ten z-slices per binding: 7 bindings, the last one shorter.
    expect_matches(GetParam(), world, Palette(), r, 64 * 64 * vk::element_size(GetParam()) * 10,
                   true, &bindings);
    EXPECT_EQ(bindings, 7u);
}

TEST_P(Raymarch, RefusesMoreBindingsThanItHas) {
    const World world = scene_floor_spheres(Dims{16, 16, 64}, 1);
    // One slice per binding: 64 > 8.
    vk::Raymarcher marcher(vulkan(), 16 * 16 * vk::element_size(GetParam()));
    EXPECT_THROW(upload(marcher, world, Palette(), GetParam()), InputError);
}

// 520x256x256 packed32 = 136 MiB, more than lavapipe's 128 MiB maxStorageBufferRange.
TEST_P(Raymarch, WorldLargerThanOneBinding) {
    const World world = scene_floor_spheres(Dims{520, 256, 256}, 6683787);
    vk::RenderOptions r = options(64, 48, {}, {});
    r.camera = vk::default_camera(world.dims());
    std::uint32_t bindings = 0;
    expect_matches(GetParam(), world, Palette(), r, 0, true, &bindings);
    const std::uint64_t field_bytes = world.size() * vk::element_size(GetParam());
    if (vulkan().info().max_storage_buffer_range < field_bytes) {
        EXPECT_GE(bindings, 2u);
    }
    // A second view from inside, along the long axis.
    expect_matches(GetParam(), world, Palette(), options(48, 32, {5, 40, 128}, {515, 20, 120}, 70),
                   0, false);
}

TEST_P(Raymarch, LitShadingHitsWhatFlatHits) {
    const World world = scene_floor_spheres(Dims{64, 64, 64}, 6683787);
    vk::Raymarcher marcher(vulkan());
    upload(marcher, world, Palette(), GetParam());
    vk::RenderOptions r = options(96, 72, {}, {});
    r.camera = vk::default_camera(world.dims());
    r.shading = vk::Shading::lit;
    const auto lit = marcher.render(r);
    const auto want = cpu_render(world, Palette(), r);
    std::size_t mask_differs = 0, hits = 0;
    std::vector<std::uint32_t> colours;
    for (std::size_t i = 0; i < want.size() / 4; ++i) {
        const bool cpu_sky =
            want[i * 4] == r.sky.r && want[i * 4 + 1] == r.sky.g && want[i * 4 + 2] == r.sky.b;
        const bool gpu_sky = lit.rgba[i * 4] == r.sky.r && lit.rgba[i * 4 + 1] == r.sky.g &&
                             lit.rgba[i * 4 + 2] == r.sky.b;
        mask_differs += cpu_sky != gpu_sky;
        hits += !cpu_sky;
        std::uint32_t c = 0;
        std::memcpy(&c, &lit.rgba[i * 4], 4);
        colours.push_back(c);
        EXPECT_EQ(lit.rgba[i * 4 + 3], 255);
    }
    std::sort(colours.begin(), colours.end());
    EXPECT_GT(hits, 0u);
    EXPECT_LE(double(mask_differs), 0.005 * double(want.size() / 4));
    EXPECT_GT(std::unique(colours.begin(), colours.end()) - colours.begin(), 10);
    // The gradient sky is not flat.
    r.sky_gradient = true;
    const auto sky = marcher.render(r);
    EXPECT_NE(std::memcmp(&sky.rgba[0], &sky.rgba[(std::size_t{r.height} - 1) * r.width * 4], 3),
              0);
}

TEST_P(Raymarch, GpuTimestamps) {
    if (!vulkan().info().timestamps) {
        GTEST_SKIP() << vulkan().info().name << " has no compute timestamps";
    }
    const World world = scene_floor_spheres(Dims{32, 32, 32}, 1);
    vk::Raymarcher marcher(vulkan());
    upload(marcher, world, Palette(), GetParam());
    vk::RenderOptions r = options(64, 64, {}, {});
    r.camera = vk::default_camera(world.dims());
    const auto img = marcher.render(r);
    EXPECT_GT(img.raymarch_ms, 0);
}

TEST_P(Raymarch, CameraValidation) {
    vk::RenderOptions r = options(64, 64, {1, 2, 3}, {1, 2, 3});
    EXPECT_THROW(vk::validate(r), InputError);
    r.camera.target = {4, 5, 6};
    EXPECT_NO_THROW(vk::validate(r));
    for (double fov : {0.0, -5.0, 180.0, 200.0, std::nan("")}) {
        r.camera.fov_deg = fov;
        EXPECT_THROW(vk::validate(r), InputError) << fov;
    }
    r.camera.fov_deg = 60;
    for (std::uint32_t size : {0u, vk::kMaxImageSize + 1}) {
        r.width = size;
        EXPECT_THROW(vk::validate(r), InputError) << size;
        r.width = 64;
        r.height = size;
        EXPECT_THROW(vk::validate(r), InputError) << size;
        r.height = 64;
    }
}

// 520x256x512 compact = 136 MiB, more than lavapipe's 128 MiB maxStorageBufferRange (the
// packed32 test world above is only 68 MiB compact).
TEST(RaymarchCompact, WorldLargerThanOneBinding) {
    const World world = scene_floor_spheres(Dims{520, 256, 512}, 6683787);
    vk::RenderOptions r = options(64, 48, {}, {});
    r.camera = vk::default_camera(world.dims());
    std::uint32_t bindings = 0;
    expect_matches(vk::FieldFormat::compact, world, Palette(), r, 0, true, &bindings);
    if (vulkan().info().max_storage_buffer_range < world.size() * 2) {
        EXPECT_GE(bindings, 2u);
    }
}

// Per-8^3-block minima of the unsaturated reference distance (layout.h VF_RAYMARCH_BLOCK).
std::vector<std::uint32_t> block_minima(const World& world) {
    const auto d = reference_manhattan(world);
    const Dims n = world.dims();
    const std::uint32_t b = VF_RAYMARCH_BLOCK;
    const Dims nb{(n.x + b - 1) / b, (n.y + b - 1) / b, (n.z + b - 1) / b};
    std::vector<std::uint32_t> out(nb.count(), 0xFFFFFFFFu);
    for (std::uint32_t z = 0; z < n.z; ++z) {
        for (std::uint32_t y = 0; y < n.y; ++y) {
            for (std::uint32_t x = 0; x < n.x; ++x) {
                auto& m = out[nb.index(x / b, y / b, z / b)];
                m = std::min(m, d[n.index(x, y, z)]);
            }
        }
    }
    return out;
}

TEST(RaymarchCompact, CoarseSkippingBeyondSaturatedDistances) {
    // Solids hundreds of voxels apart: the 8-bit field saturates at 255 around x = 300, where
    // the block minima let rays take longer strides. Images must not change (and inflated
    // minima would carry rays through the wall at x = 600: the comparison has teeth).
    World world(Dims{700, 24, 24});
    world.set(690, 12, 12, 9);
    world.set(5, 20, 2, 33);
    for (std::uint32_t z = 0; z < 24; ++z) {
        for (std::uint32_t y = 0; y < 24; ++y) {
            world.set(600, y, z, 44);  // a wall across the world
        }
    }

    const Palette palette;
    for (const vk::RenderOptions& r : {options(160, 60, {-30, 12, 12}, {700, 12, 12}, 20),
                                       options(120, 80, {300, 60, -200}, {600, 12, 12}, 30),
                                       options(100, 100, {699.5, 23.5, 23.5}, {0, 0, 0}, 40)}) {
        vk::Raymarcher marcher(vulkan());
        marcher.upload_compact(world.dims(), palette, compact_field(world));
        const auto plain = marcher.render(r);
        marcher.set_block_min(block_minima(world));
        const auto coarse = marcher.render(r);
        const auto want = cpu_render(world, palette, r);
        const Comparison c = compare(coarse.rgba, want, r.sky);
        EXPECT_LE(double(c.differing), 0.005 * double(c.pixels));
        EXPECT_LT(c.sky, c.pixels) << "nothing was hit: the test would prove nothing";
        EXPECT_EQ(coarse.rgba, plain.rgba) << "coarse skipping changed the image";
    }
    vk::Raymarcher marcher(vulkan());
    marcher.upload_compact(world.dims(), palette, compact_field(world));
    EXPECT_THROW(marcher.set_block_min(std::vector<std::uint32_t>(3, 0)), InputError);
}

TEST(RaymarchCompact, PlanAlignsSlabsAndNamesFormats) {
    vk::Raymarcher marcher(vulkan(), 33 * 17 * 2 * 5 + 2);  // a multiple of 4
    const vk::FieldLayout l = marcher.plan(Dims{33, 17, 23}, vk::FieldFormat::compact);
    EXPECT_EQ(l.slab_depth, 5u);
    EXPECT_EQ(l.slabs, 5u);
    EXPECT_EQ(l.slab_stride % VF_FIELD_SLAB_ALIGN, 0u);
    EXPECT_GE(l.slab_stride, l.slab_bytes(0));
    EXPECT_EQ(l.slab_bytes(0), (33u * 17 * 5 * 2 + 3) / 4 * 4);  // odd voxel count: padded
    EXPECT_EQ(l.slab_bytes(4), 33u * 17 * 3 * 2 + 2);
    EXPECT_EQ(vk::parse_field_format("compact"), vk::FieldFormat::compact);
    EXPECT_EQ(vk::parse_field_format("packed32"), vk::FieldFormat::packed32);
    EXPECT_THROW(vk::parse_field_format("u16"), InputError);
}

TEST(VulkanDevice, ListsAndSelects) {
    const auto devices = vk::list_devices();
    ASSERT_FALSE(devices.empty()) << "no Vulkan device (install mesa-vulkan-drivers)";
    EXPECT_TRUE(vulkan().info().rejected.empty());
    EXPECT_GE(vulkan().info().max_storage_buffer_range, 1u << 20);
    EXPECT_THROW(vk::Context("banana"), vk::DeviceSelectionError);
    EXPECT_THROW(vk::Context("999"), vk::DeviceSelectionError);
}

INSTANTIATE_TEST_SUITE_P(Formats, Raymarch,
                         ::testing::Values(vk::FieldFormat::packed32, vk::FieldFormat::compact),
                         [](const auto& p) { return vk::to_string(p.param); });

}  // namespace
}  // namespace voxfield::test
