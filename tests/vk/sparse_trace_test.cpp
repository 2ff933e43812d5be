// The sparse tracer (vk::SparseTracer, vk/shaders/sparse_trace.comp) on lavapipe with the
// validation layer: its flat images against the dense ray marcher's (vk::Raymarcher over the
// exact Manhattan field of the same world, byte for byte) and against an independent CPU caster
// (exact voxel traversal in double precision, this file's own), on worlds whose sizes are not
// multiples of 64, with tiles cut by the world's edge, empty tiles and directory blocks between
// solid ones, cameras inside and outside, nodes and materials cut into more chunks than a shader
// stage binds storage buffers (and edited through the arena); its lit images against the CPU
// caster's model of the same lighting (sun blocked or not by a ray toward it, occlusion taps);
// `voxfield render` of sparse inputs end to end. Without a Vulkan device the tests skip.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "../cli/cli_test_util.hpp"
#include "../cli/far_grid_util.hpp"
#include "sparse_brush.hpp"
#include "voxfield/core/brush.hpp"
#include "voxfield/core/camera.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/core/vox.hpp"
#include "voxfield/vk/raymarcher.hpp"
#include "voxfield/vk/sparse_trace_layout.h"
#include "voxfield/vk/sparse_tracer.hpp"
#include "vulkan_env.hpp"

namespace voxfield::test {
namespace {

using vk::Vec3;

// ---- The CPU caster: exact voxel traversal in double precision over the dense world. ----

struct CpuHit {
    bool hit = false;
    std::array<std::int64_t, 3> cell{};
    int axis = -1;              // the axis of the face it entered through; -1: started in it
    std::array<int, 3> step{};  // the ray's step per axis
    double t = 0;               // where it entered the cell (0 when the ray starts in it)
    std::uint8_t material = 0;
};

// The first solid voxel along o + t d (d unit), Amanatides & Woo from the ray's entry into the
// world box (the cell of a point just past the entry, robust against entry on a face).
CpuHit cpu_cast(const World& world, const Vec3& o, const Vec3& d) {
    const Dims n = world.dims();
    const std::array<double, 3> size{double(n.x), double(n.y), double(n.z)};
    CpuHit h;
    double t0 = 0, t1 = INFINITY;
    int entry_axis = -1;
    for (int a = 0; a < 3; ++a) {
        const auto i = static_cast<std::size_t>(a);
        if (d[i] == 0) {
            if (o[i] < 0 || o[i] >= size[i]) {
                return h;
            }
            continue;
        }
        const double ta = -o[i] / d[i], tb = (size[i] - o[i]) / d[i];
        if (std::min(ta, tb) > t0) {
            t0 = std::min(ta, tb);
            entry_axis = a;
        }
        t1 = std::min(t1, std::max(ta, tb));
    }
    if (!(t0 < t1)) {
        return h;
    }
    const double tm = t0 + std::min(1e-9, (t1 - t0) / 2);
    std::array<double, 3> t_next{};
    for (std::size_t a = 0; a < 3; ++a) {
        h.cell[a] =
            std::clamp<std::int64_t>(static_cast<std::int64_t>(std::floor(o[a] + d[a] * tm)), 0,
                                     static_cast<std::int64_t>(size[a]) - 1);
        h.step[a] = d[a] > 0 ? 1 : (d[a] < 0 ? -1 : 0);
        t_next[a] =
            h.step[a] == 0 ? INFINITY : (double(h.cell[a] + (h.step[a] > 0 ? 1 : 0)) - o[a]) / d[a];
    }
    h.axis = entry_axis;
    h.t = t0;
    for (;;) {
        const std::uint8_t v =
            world.at(static_cast<std::uint32_t>(h.cell[0]), static_cast<std::uint32_t>(h.cell[1]),
                     static_cast<std::uint32_t>(h.cell[2]));
        if (v != 0) {
            h.hit = true;
            h.material = v;
            return h;
        }
        std::size_t a = 0;
        if (t_next[1] < t_next[a]) {
            a = 1;
        }
        if (t_next[2] < t_next[a]) {
            a = 2;
        }
        h.t = t_next[a];
        h.axis = static_cast<int>(a);
        h.cell[a] += h.step[a];
        if (h.cell[a] < 0 || h.cell[a] >= static_cast<std::int64_t>(size[a])) {
            return CpuHit{};
        }
        t_next[a] = (double(h.cell[a] + (h.step[a] > 0 ? 1 : 0)) - o[a]) / d[a];
    }
}

// DESIGN §4's pinhole camera in double precision (core's image model).
Vec3 pixel_dir(const vk::RenderOptions& r, double px, double py) {
    const Vec3 p = r.camera.position, t = r.camera.target;
    return pixel_direction({t[0] - p[0], t[1] - p[1], t[2] - p[2]}, r.camera.fov_deg,
                           double(r.width), double(r.height), px, py);
}

Rgba flat_colour(const World& world, const Palette& palette, const vk::RenderOptions& r,
                 const Vec3& dir) {
    const CpuHit h = cpu_cast(world, r.camera.position, dir);
    return h.hit ? palette[h.material] : r.sky;
}

bool same(const std::uint8_t* px, const Rgba& c) {
    return px[0] == c.r && px[1] == c.g && px[2] == c.b && px[3] == 255;
}

// A flat image against the caster: pixels that differ must be ties, i.e. the image's colour is
// what the caster finds through a point within 0.01 pixels of the pixel's centre (a ray through
// a voxel edge or corner, decided by the shader's float rounding). Returns the unexplained ones.
std::size_t unexplained_pixels(const std::vector<std::uint8_t>& got, const World& world,
                               const Palette& palette, const vk::RenderOptions& r) {
    std::size_t bad = 0;
    for (std::uint32_t j = 0; j < r.height; ++j) {
        for (std::uint32_t i = 0; i < r.width; ++i) {
            const std::uint8_t* px = &got[(std::size_t{j} * r.width + i) * 4];
            if (same(px, flat_colour(world, palette, r, pixel_dir(r, i + 0.5, j + 0.5)))) {
                continue;
            }
            bool tie = false;
            for (const double radius : {0.01 / 16, 0.01 / 4, 0.01}) {
                for (int k = 0; k < 8 && !tie; ++k) {
                    const double a = k * M_PI / 4;
                    tie = same(px, flat_colour(world, palette, r,
                                               pixel_dir(r, i + 0.5 + radius * std::cos(a),
                                                         j + 0.5 + radius * std::sin(a))));
                }
            }
            bad += tie ? 0 : 1;
        }
    }
    return bad;
}

// The dense ray marcher's image of the world (compact field of the exact Manhattan distances).
vk::Image dense_image(vk::Context& ctx, const World& world, const Palette& palette,
                      const vk::RenderOptions& r) {
    const std::vector<std::uint32_t> d = reference_manhattan(world);
    std::vector<std::uint16_t> compact(world.size());
    for (std::size_t i = 0; i < compact.size(); ++i) {
        compact[i] = static_cast<std::uint16_t>((std::min<std::uint32_t>(d[i], 255) << 8) |
                                                world.voxels()[i]);
    }
    vk::Raymarcher marcher(ctx);
    marcher.upload_compact(world.dims(), palette, compact);
    return marcher.render(r);
}

std::size_t differing(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b) {
    std::size_t n = 0;
    for (std::size_t i = 0; i + 3 < a.size(); i += 4) {
        n += std::memcmp(&a[i], &b[i], 4) != 0 ? 1 : 0;
    }
    return n;
}

std::size_t sky_pixels(const std::vector<std::uint8_t>& img, Rgba sky) {
    std::size_t n = 0;
    for (std::size_t i = 0; i + 3 < img.size(); i += 4) {
        n += same(&img[i], sky) ? 1 : 0;
    }
    return n;
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

// The sparse image of `world` equals the dense ray marcher's byte for byte and (with `caster`)
// the caster's up to ties; it hits something, and misses somewhere when `want_sky`. Returns it.
vk::Image expect_flat_matches(vk::Context& ctx, const World& world, const Palette& palette,
                              const vk::RenderOptions& r, bool want_sky = true,
                              bool caster = true) {
    SCOPED_TRACE(world.dims().to_string() + " seen from " + std::to_string(r.camera.position[0]) +
                 "," + std::to_string(r.camera.position[1]) + "," +
                 std::to_string(r.camera.position[2]));
    const SparseWorld sparse = SparseWorld::from_dense(world);
    vk::SparseTracer tracer(ctx);
    tracer.upload(sparse, palette);
    const vk::Image got = tracer.render(r);
    EXPECT_EQ(got.rgba.size(), std::size_t{r.width} * r.height * 4);
    const vk::Image dense = dense_image(ctx, world, palette, r);
    EXPECT_EQ(differing(got.rgba, dense.rgba), 0u)
        << "pixels differ from the dense ray marcher's image";
    if (caster) {
        EXPECT_EQ(unexplained_pixels(got.rgba, world, palette, r), 0u)
            << "pixels differ from the CPU caster beyond ties";
    }
    const std::size_t sky = sky_pixels(got.rgba, r.sky);
    EXPECT_LT(sky, std::size_t{r.width} * r.height) << "nothing was hit: the test proves nothing";
    if (want_sky) {
        EXPECT_GT(sky, 0u) << "no ray missed";
    }
    return got;
}

TEST(SparseTrace, SingleVoxel) {
    REQUIRE_VULKAN(ctx);
    World world(Dims{8, 8, 8});
    world.set(3, 4, 5, 79);
    expect_flat_matches(*ctx, world, Palette(), options(64, 48, {-6, 9, -4}, {3.5, 4.5, 5.5}, 30));
    expect_flat_matches(*ctx, world, Palette(), options(64, 48, {12, -3, 14}, {3.5, 4.5, 5.5}, 25));
}

TEST(SparseTrace, FloorAndSpheres) {
    REQUIRE_VULKAN(ctx);
    const World world = scene_floor_spheres(Dims{64, 64, 64}, 6683787);
    vk::RenderOptions r = options(128, 96, {}, {});
    r.camera = vk::default_camera(world.dims());
    expect_flat_matches(*ctx, world, Palette(), r);
    // Several tiles, cut by the world's edge on every axis.
    const World wide = scene_floor_spheres(Dims{150, 70, 130}, 17, 40);
    r.camera = vk::default_camera(wide.dims());
    expect_flat_matches(*ctx, wide, Palette(), r);
    expect_flat_matches(*ctx, wide, Palette(), options(96, 72, {10, 30, 12}, {140, 5, 120}, 80),
                        false);
}

TEST(SparseTrace, RandomWorldsOfAwkwardSizes) {
    REQUIRE_VULKAN(ctx);
    std::uint64_t seed = 11;
    for (const Dims d : {Dims{70, 45, 90}, Dims{65, 129, 63}, Dims{1, 100, 130}}) {
        const World world = scene_random(d, 0.02, seed++);
        const Vec3 centre{d.x / 2.0, d.y / 2.0, d.z / 2.0};
        expect_flat_matches(*ctx, world, Palette(),
                            options(80, 60, {-40.3, d.y + 30.7, -50.1}, centre, 50));
        // From inside, along a long diagonal.
        expect_flat_matches(*ctx, world, Palette(),
                            options(64, 48, {d.x * 0.3 + 0.013, d.y * 0.4 + 0.37, d.z * 0.2 + 0.21},
                                    {d.x + 10.0, d.y * 0.8, d.z + 20.0}, 75),
                            false);
        // Straight down along -y (x and z never stepped).
        expect_flat_matches(*ctx, world, Palette(),
                            options(48, 48, {d.x / 2.0 + 0.3, d.y + 40.0, d.z / 2.0 + 0.2},
                                    {d.x / 2.0 + 0.3, 0, d.z / 2.0 + 0.2}, 40),
                            false);
    }
}

// Solid tiles with empty ones between them, a one-voxel wall on a tile boundary, a floor that
// ends inside a tile cut by the world's edge.
World islands() {
    World w(Dims{300, 70, 200});
    for (std::uint32_t z = 0; z < 40; ++z) {
        for (std::uint32_t x = 0; x < 40; ++x) {
            for (std::uint32_t y = 0; y < (x + z) % 13 + 1; ++y) {
                w.set(x, y, z, static_cast<std::uint8_t>(1 + (x * 7 + z) % 200));
            }
        }
    }
    for (std::uint32_t z = 150; z < 200; ++z) {
        for (std::uint32_t x = 250; x < 300; ++x) {
            w.set(x, 0, z, 30);
        }
    }
    for (std::uint32_t z = 64; z < 128; ++z) {
        for (std::uint32_t y = 5; y < 60; ++y) {
            w.set(192, y, z, 120);  // the first voxel of the tile at x = 3
        }
    }
    w.set(299, 69, 199, 5);  // the world's last voxel
    w.set(130, 33, 100, 6);  // alone in its tile
    return w;
}

TEST(SparseTrace, EmptyTilesBetweenSolidOnes) {
    REQUIRE_VULKAN(ctx);
    const World world = islands();
    expect_flat_matches(*ctx, world, Palette(), options(128, 96, {-80, 90, -60}, {150, 20, 100}));
    expect_flat_matches(*ctx, world, Palette(), options(96, 72, {400, 80, 260}, {150, 30, 100}));
    // From an empty tile inside the world, toward the wall and the far corner.
    expect_flat_matches(*ctx, world, Palette(), options(96, 72, {100, 30, 40}, {299, 60, 199}, 90),
                        true);
    // Grazing the wall's face along it.
    expect_flat_matches(*ctx, world, Palette(),
                        options(96, 72, {192.02, 30.3, -40}, {191.9, 29, 150}, 40), true);
    // Narrow view of the lone voxel from far away.
    expect_flat_matches(*ctx, world, Palette(),
                        options(48, 36, {-2900, 2400, -3300}, {130.5, 33.5, 100.5}, 0.5));
}

TEST(SparseTrace, DirectoryBlocksApart) {
    REQUIRE_VULKAN(ctx);
    // Three blocks of 512^3 along x, two along z; solids in some of them only, at their edges.
    World world(Dims{1030, 12, 530});
    for (std::uint32_t x = 500; x < 530; ++x) {
        for (std::uint32_t z = 0; z < 20; ++z) {
            world.set(x, 0, z, 7);
        }
    }
    world.set(511, 5, 10, 40);
    world.set(512, 6, 10, 41);
    world.set(1029, 11, 529, 42);
    world.set(1024, 3, 511, 43);
    world.set(3, 2, 520, 44);
    expect_flat_matches(*ctx, world, Palette(),
                        options(96, 72, {-100, 200, -150}, {515, 3, 15}, 20));
    expect_flat_matches(*ctx, world, Palette(),
                        options(64, 48, {5.3, 8.2, 3.1}, {1029.5, 11.5, 529.5}, 1.5), true);
    expect_flat_matches(*ctx, world, Palette(), options(64, 48, {1100, 40, 600}, {515, 3, 265}));
}

TEST(SparseTrace, MengerTunnelsAndGrazingWalls) {
    REQUIRE_VULKAN(ctx);
    const World menger = scene_menger(Dims{81, 81, 81});
    expect_flat_matches(*ctx, menger, Palette(),
                        options(96, 96, {40.3, 40.6, -50}, {40.5, 40.5, 81}, 50), false);
    expect_flat_matches(*ctx, menger, Palette(),
                        options(96, 72, {-30, 95, -40}, {40.5, 40.5, 40.5}));
    World walls(Dims{130, 64, 70});
    for (std::uint32_t z = 0; z < 70; ++z) {
        for (std::uint32_t y = 0; y < 64; ++y) {
            walls.set(64, y, z, 20);
        }
        for (std::uint32_t x = 0; x < 130; ++x) {
            walls.set(x, 0, z, 100);
        }
    }
    expect_flat_matches(*ctx, walls, Palette(),
                        options(96, 72, {63.2, 1.3, -80}, {65.4, 0.8, 70}, 40));
    expect_flat_matches(*ctx, walls, Palette(), options(96, 72, {20, 30, -10}, {68, 28, 70}, 70));
}

// Rays along the diagonals x = y (z = 10) and x = y + 10 (z = 12) from cameras in the empty tile
// (0, 0, 0), in fields of view so narrow that the middle row's rays have equal x and y
// components in float: every x crossing coincides with a y crossing (the walk takes x first at a
// tie), at node edges and, on the second diagonal, where the walk leaves the empty tile at
// x = 64 while crossing y = 54 inside the next one. Cells: (64, 63, 10) and (64, 53, 12) hold
// material 33, the first cells past the tile in the walk's order; the cells beyond, 50 and 90.
// The float ray's rounding exceeds the whole image's angle, so only the dense ray marcher (same
// arithmetic) can be compared, and the ties' cell: 33.
TEST(SparseTrace, TiesAtNodeEdges) {
    REQUIRE_VULKAN(ctx);
    World world(Dims{130, 130, 20});
    world.set(64, 63, 10, 33);
    world.set(64, 53, 12, 33);
    for (std::uint32_t x = 65; x < 130; ++x) {
        world.set(x, x - 1, 10, 50);
        world.set(x - 1, x, 10, 90);
        world.set(x, x - 11, 12, 50);
        world.set(x - 1, x - 10, 12, 90);
    }
    Palette palette;
    palette[33] = Rgba{1, 2, 3, 255};
    for (const auto& r : {options(65, 65, {3.25, 3.25, 10.5}, {103.25, 103.25, 10.5}, 0.001),
                          options(65, 65, {3.25, 3.25, 10.5}, {103.25, 103.25, 10.5}, 0.00001),
                          options(65, 65, {13.25, 3.25, 12.5}, {113.25, 103.25, 12.5}, 0.0001),
                          options(65, 65, {0.7, 0.7, 10.5}, {100.7, 100.7, 10.5}, 0.001)}) {
        const vk::Image img = expect_flat_matches(*ctx, world, palette, r, false, false);
        std::size_t tie = 0;
        for (std::uint32_t i = 0; i < r.width; ++i) {
            tie += same(&img.rgba[(std::size_t{r.height / 2} * r.width + i) * 4], palette[33]);
        }
        EXPECT_EQ(tie, r.width) << "the middle row's rays must take x first at every tie";
    }
}

TEST(SparseTrace, CameraInsideASolidVoxel) {
    REQUIRE_VULKAN(ctx);
    World filled(Dims{70, 16, 16});
    filled.set(65, 6, 7, 42);
    expect_flat_matches(*ctx, filled, Palette(), options(16, 16, {65.5, 6.5, 7.5}, {9, 9, 9}),
                        false);
}

TEST(SparseTrace, CityScene) {
    REQUIRE_VULKAN(ctx);
    const World world = scene_city(Dims{200, 96, 190}, 5);
    ASSERT_GT(world.solid_count(), 0u);
    vk::RenderOptions r = options(128, 96, {}, {});
    r.camera = vk::default_camera(world.dims());
    expect_flat_matches(*ctx, world, Palette(), r);
}

// The models in data/vox, loaded dense and loaded sparse (load_sparse_world places a scene's
// instances into the tiles voxel by voxel): the same images, the dense ray marcher's.
TEST(SparseTrace, ModelsInDataVox) {
    REQUIRE_VULKAN(ctx);
    for (const char* name :
         {"chr_army1.vox", "obj_house4.vox", "scene_store8.vox", "veh_car1.vox"}) {
        SCOPED_TRACE(name);
        const fs::path path = fs::path(VOXFIELD_DATA_DIR) / "vox" / name;
        const VoxModel dense = load_world(path, InputOptions{.grid = {}, .palette_values = true});
        const SparseModel sparse =
            load_sparse_world(path, InputOptions{.grid = {}, .palette_values = true});
        ASSERT_EQ(sparse.world.dims(), dense.world.dims());
        vk::RenderOptions r = options(96, 72, {}, {});
        r.camera = vk::default_camera(dense.world, r.width, r.height);
        const vk::Image want = expect_flat_matches(*ctx, dense.world, dense.palette, r);
        vk::SparseTracer tracer(*ctx);
        tracer.upload(sparse.world, sparse.palette);
        EXPECT_EQ(differing(tracer.render(r).rgba, want.rgba), 0u);
    }
}

TEST(SparseTrace, EmptyWorldIsAllSky) {
    REQUIRE_VULKAN(ctx);
    const SparseWorld sparse(Dims{100, 50, 70});
    vk::SparseTracer tracer(*ctx);
    tracer.upload(sparse, Palette());
    const vk::RenderOptions r = options(32, 24, {-20, 30, -20}, {50, 25, 35});
    const vk::Image img = tracer.render(r);
    EXPECT_EQ(sky_pixels(img.rgba, r.sky), 32u * 24u);
    EXPECT_EQ(tracer.stats().pages, 0u);
    // The same tracer takes another world.
    const World world = islands();
    tracer.upload(SparseWorld::from_dense(world), Palette());
    const vk::RenderOptions view = options(48, 36, {-80, 90, -60}, {150, 20, 100});
    const vk::Image second = tracer.render(view);
    EXPECT_EQ(differing(second.rgba, dense_image(*ctx, world, Palette(), view).rgba), 0u);
    EXPECT_GT(tracer.stats().pages, 0u);
}

// Nodes and materials cut into several chunks give the same image; a tile over one binding is
// refused.
TEST(SparseTrace, ChunksCutAtTileBoundaries) {
    REQUIRE_VULKAN(ctx);
    const World world = scene_floor_spheres(Dims{200, 40, 190}, 9, 30);
    const SparseWorld sparse = SparseWorld::from_dense(world);
    std::uint64_t widest = 0;
    for (std::uint32_t t = 0; t < sparse.tile_count(); ++t) {
        widest = std::max<std::uint64_t>(
            {widest, std::uint64_t{sparse.node_counts()[t]} * 8, sparse.material_counts()[t]});
    }
    vk::RenderOptions r = options(96, 72, {}, {});
    r.camera = vk::default_camera(world.dims());
    vk::SparseTracer whole(*ctx);
    whole.upload(sparse, Palette());
    const vk::Image want = whole.render(r);
    EXPECT_EQ(whole.stats().node_chunks, 1u);
    EXPECT_EQ(whole.stats().material_chunks, 1u);

    vk::SparseTracer cut(*ctx, (widest + 7) / 8 * 8 * 2);
    cut.upload(sparse, Palette());
    EXPECT_GE(cut.stats().material_chunks, 3u);
    EXPECT_GE(cut.stats().node_chunks, 2u);
    EXPECT_EQ(differing(cut.render(r).rgba, want.rgba), 0u);
    EXPECT_GT(sky_pixels(want.rgba, r.sky), 0u);
    EXPECT_LT(sky_pixels(want.rgba, r.sky), std::size_t{r.width} * r.height);

    // Nodes in one chunk, materials in several (read through device addresses).
    const std::uint64_t nodes = sparse.node_masks().size() * 8;
    vk::SparseTracer mixed(*ctx, std::max(nodes, widest) + 8);
    mixed.upload(sparse, Palette());
    EXPECT_EQ(mixed.stats().node_chunks, 1u);
    EXPECT_GE(mixed.stats().material_chunks, 2u) << nodes << " node bytes, " << widest;
    EXPECT_EQ(differing(mixed.render(r).rgba, want.rgba), 0u);

    vk::SparseTracer tiny(*ctx, 64);
    EXPECT_THROW(tiny.upload(sparse, Palette()), InputError);
}

// Flat images of `tracer` (the world `sparse` uploaded, perhaps edited since) equal the dense
// ray marcher's byte for byte and the independent caster's up to ties, from three cameras.
void expect_exact(vk::Context& ctx, vk::SparseTracer& tracer, const SparseWorld& sparse,
                  const Palette& palette, const std::string& when) {
    SCOPED_TRACE(when);
    const World dense = sparse.to_dense();
    const Dims d = dense.dims();
    std::vector<vk::RenderOptions> views = {
        options(96, 72, {}, {}),
        options(96, 72, {d.x / 2.0 + 0.3, d.y * 2.5 + 40, d.z / 2.0 - 0.7},
                {d.x / 2.0, 0, d.z / 2.0 + 1}),
        options(96, 72, {-30, d.y * 0.8, d.z * 1.3}, {d.x * 0.5, d.y * 0.3, d.z * 0.3}, 70)};
    views[0].camera = vk::default_camera(d);
    for (const vk::RenderOptions& r : views) {
        const vk::Image got = tracer.render(r);
        EXPECT_EQ(differing(got.rgba, dense_image(ctx, dense, palette, r).rgba), 0u);
        EXPECT_EQ(unexplained_pixels(got.rgba, dense, palette, r), 0u);
        EXPECT_GT(sky_pixels(got.rgba, r.sky), 0u);
        EXPECT_LT(sky_pixels(got.rgba, r.sky), std::size_t{r.width} * r.height);
    }
}

// A world of random tiles (30% solid: every 4^3 node occupied, about 33 KB of node masks and
// 79 KB of materials per tile) with bindings a tenth over the widest tile: each material chunk
// holds one tile and each node chunk two, so the world's 10 tiles take 10 material and 5 node
// chunks, more than the 8 and 4 bindings the tracer once had. Its flat images equal the
// independent caster's and the dense ray marcher's, before and after edits through the arena
// (tiles made in empty space, a random tile rewritten twice: the arena grows).
TEST(SparseTrace, MoreChunksThanTheOldBindings) {
    REQUIRE_VULKAN(ctx);
    World world(Dims{384, 128, 192});
    std::mt19937_64 rng(24);
    std::uniform_int_distribution<int> percent(0, 99), material(1, 255);
    for (std::uint32_t z = 0; z < 128; ++z) {
        for (std::uint32_t y = 0; y < 64; ++y) {
            for (std::uint32_t x = 0; x < 320; ++x) {
                if (percent(rng) < 30) {
                    world.set(x, y, z, static_cast<std::uint8_t>(material(rng)));
                }
            }
        }
    }
    SparseWorld sparse = SparseWorld::from_dense(world);
    ASSERT_EQ(sparse.tile_count(), 10u);
    std::uint64_t widest = 0;
    for (std::uint32_t t = 0; t < sparse.tile_count(); ++t) {
        widest = std::max<std::uint64_t>(
            {widest, std::uint64_t{sparse.node_counts()[t]} * 8, sparse.material_counts()[t]});
    }
    const std::uint64_t binding = (widest + widest / 10) / 8 * 8;
    const Palette palette = Palette::magicavoxel_default();
    vk::SparseTracer tracer(*ctx, binding);
    tracer.upload(sparse, palette);
    const vk::SparseDeviceStats uploaded = tracer.stats();
    EXPECT_EQ(uploaded.node_chunks, 5u);
    EXPECT_EQ(uploaded.material_chunks, 10u);
    expect_exact(*ctx, tracer, sparse, palette, "uploaded");

    const auto edit = [&](const Brush& b) {
        const vk::SparseTileUpdate u = tracer.update_tiles(sparse, apply_brush(sparse, b));
        EXPECT_FALSE(u.whole);
        return u;
    };
    // New tiles above the random ones and beside them, in the arena after the upload's chunks.
    edit(brush(BrushOp::place, BrushShape::sphere, {352, 96, 32}, 6, 7));
    edit(brush(BrushOp::place, BrushShape::cube, {100, 80, 40}, 5, 200));
    EXPECT_EQ(tracer.stats().arena_node_chunk, uploaded.node_chunks);
    EXPECT_EQ(tracer.stats().arena_tiles, 2u);
    expect_exact(*ctx, tracer, sparse, palette, "two tiles made in the arena");
    // A random tile rewritten (a crater in its top), then again (painted): the arena grows.
    EXPECT_EQ(edit(brush(BrushOp::erase, BrushShape::sphere, {96, 59, 32}, 4, 1)).tiles_written,
              1u);
    EXPECT_TRUE(edit(brush(BrushOp::paint, BrushShape::cube, {110, 60, 40}, 3, 90)).arena_rebuilt);
    EXPECT_EQ(tracer.stats().arena_tiles, 3u);
    expect_exact(*ctx, tracer, sparse, palette, "a random tile rewritten twice");
}

// Any number of chunks: 40 tiles (64 scattered voxels and an 11^3 cube each: about 160 nodes,
// 1395 materials) with bindings of 2 KiB take a node chunk and a material chunk each, 120
// buffers, more than lavapipe binds storage buffers in one shader stage (32).
TEST(SparseTrace, AnyNumberOfChunks) {
    REQUIRE_VULKAN(ctx);
    const SparseWorld sparse =
        SparseWorld::from_voxels(Dims{512, 64, 320}, [](const VoxelSink& put) {
            for (std::uint32_t z = 5; z < 320; z += 16) {
                for (std::uint32_t y = 5; y < 64; y += 16) {
                    for (std::uint32_t x = 5; x < 512; x += 16) {
                        put(x, y, z, static_cast<std::uint8_t>(1 + (x + 3 * y + 7 * z) % 250));
                    }
                }
            }
            for (std::uint32_t t = 0; t < 40; ++t) {
                const std::uint32_t x0 = (t % 8) * 64 + 40, z0 = (t / 8) * 64 + 20;
                for (std::uint32_t z = z0; z < z0 + 11; ++z) {
                    for (std::uint32_t y = 20; y < 31; ++y) {
                        for (std::uint32_t x = x0; x < x0 + 11; ++x) {
                            put(x, y, z, static_cast<std::uint8_t>(1 + t * 6));
                        }
                    }
                }
            }
        });
    ASSERT_EQ(sparse.tile_count(), 40u);
    const Palette palette = Palette::magicavoxel_default();
    vk::SparseTracer tracer(*ctx, 2048);
    tracer.upload(sparse, palette);
    EXPECT_EQ(tracer.stats().node_chunks, 40u);
    EXPECT_EQ(tracer.stats().material_chunks, 40u);
    expect_exact(*ctx, tracer, sparse, palette, "80 chunks");
}

TEST(SparseTrace, RefusesSurfaceRecordsAndRenderBeforeUpload) {
    REQUIRE_VULKAN(ctx);
    vk::SparseTracer tracer(*ctx);
    const vk::RenderOptions r = options(8, 8, {-5, 5, -5}, {1, 1, 1});
    EXPECT_THROW(tracer.render(r), std::logic_error);
    tracer.upload(SparseWorld(Dims{4, 4, 4}), Palette());
    vk::RenderOptions s = r;
    s.surface = true;
    EXPECT_THROW(tracer.render(s), std::logic_error);
    vk::RenderOptions bad = r;
    bad.width = 0;
    EXPECT_THROW(tracer.render(bad), InputError);
}

TEST(SparseTrace, CountsNodeVisitsAndExits) {
    REQUIRE_VULKAN(ctx);
    const World world = islands();
    vk::SparseTracer tracer(*ctx);
    tracer.upload(SparseWorld::from_dense(world), Palette());
    vk::RenderOptions r = options(64, 48, {-80, 90, -60}, {150, 20, 100});
    const vk::Image plain = tracer.render(r);
    r.count = true;
    const vk::Image counted = tracer.render(r);
    EXPECT_EQ(differing(plain.rgba, counted.rgba), 0u);
    const std::size_t hits = std::size_t{r.width} * r.height - sky_pixels(plain.rgba, r.sky);
    // A hit visits all five levels at least.
    EXPECT_GE(counted.fetches, 5 * hits);
    EXPECT_GT(counted.steps, 0u);
    // Far fewer node exits than the voxels a plain walk would step through (at least the
    // world's 300 voxels across for each ray crossing it).
    EXPECT_LT(counted.steps, std::uint64_t{r.width} * r.height * 300);
}

// ---- Lit shading against the caster's model of it. ----

double to_linear(double c) {
    return c > 0.04045 ? std::pow((c + 0.055) / 1.055, 2.4) : c / 12.92;
}
double to_srgb(double c) {
    c = std::clamp(c, 0.0, 1.0);
    return c > 0.0031308 ? 1.055 * std::pow(c, 1.0 / 2.4) - 0.055 : c * 12.92;
}

// The shader's occlusion taps (sparse_tracer.hpp): at heights 1..4 along the face's normal n
// the cell straight out and the four k cells aside, weighted 0.4, 0.3, 0.2, 0.1.
double cpu_occlusion(const World& world, const std::array<std::int64_t, 3>& cell,
                     const std::array<int, 3>& n) {
    const std::array<int, 3> t1 =
        n[0] != 0 ? std::array<int, 3>{0, 1, 0} : std::array<int, 3>{1, 0, 0};
    const std::array<int, 3> t2 =
        n[2] != 0 ? std::array<int, 3>{0, 1, 0} : std::array<int, 3>{0, 0, 1};
    auto solid = [&](std::int64_t x, std::int64_t y, std::int64_t z) {
        return world.dims().contains(x, y, z) &&
               world.at(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y),
                        static_cast<std::uint32_t>(z)) != 0;
    };
    const double weights[4] = {0.4, 0.3, 0.2, 0.1};
    double sum = 0;
    for (int k = 1; k <= 4; ++k) {
        const std::int64_t c[3] = {cell[0] + n[0] * k, cell[1] + n[1] * k, cell[2] + n[2] * k};
        int count = solid(c[0], c[1], c[2]) ? 1 : 0;
        for (const auto& t : {t1, t2}) {
            for (const int s : {k, -k}) {
                count += solid(c[0] + t[0] * s, c[1] + t[1] * s, c[2] + t[2] * s) ? 1 : 0;
            }
        }
        sum += weights[k - 1] * count / 5.0;
    }
    return 1.0 - 0.7 * sum;
}

struct LitCheck {
    std::size_t compared = 0, sunlit = 0, shadowed = 0, wrong = 0;
};

// Every pixel whose hit face is not a tie and whose sun visibility does not change within 0.05
// voxels of the hit point: the shader's colour within 1 of the model's (float vs double pow).
LitCheck check_lit(const World& world, const Palette& palette, const vk::RenderOptions& r,
                   const vk::Image& img) {
    const Vec3 sun{1 / std::sqrt(3.0), 1 / std::sqrt(3.0), 1 / std::sqrt(3.0)};
    LitCheck c;
    for (std::uint32_t j = 0; j < r.height; ++j) {
        for (std::uint32_t i = 0; i < r.width; ++i) {
            const Vec3 d = pixel_dir(r, i + 0.5, j + 0.5);
            const CpuHit h = cpu_cast(world, r.camera.position, d);
            if (!h.hit || h.axis < 0) {
                continue;
            }
            bool tie = false;
            for (int k = 0; k < 8 && !tie; ++k) {
                const CpuHit n = cpu_cast(world, r.camera.position,
                                          pixel_dir(r, i + 0.5 + 0.01 * std::cos(k * M_PI / 4),
                                                    j + 0.5 + 0.01 * std::sin(k * M_PI / 4)));
                tie = !n.hit || n.cell != h.cell || n.axis != h.axis;
            }
            if (tie) {
                continue;
            }
            std::array<int, 3> nrm{};
            nrm[static_cast<std::size_t>(h.axis)] = -h.step[static_cast<std::size_t>(h.axis)];
            const Vec3 p{r.camera.position[0] + d[0] * h.t, r.camera.position[1] + d[1] * h.t,
                         r.camera.position[2] + d[2] * h.t};
            double diffuse = std::max(0.0, (nrm[0] + nrm[1] + nrm[2]) / std::sqrt(3.0));
            bool lit = diffuse > 0;
            if (lit) {
                auto sees_sun = [&](double du, double dv) {
                    Vec3 q = p;
                    const std::size_t a = static_cast<std::size_t>(h.axis);
                    q[a] += nrm[a] * 0.01;
                    q[(a + 1) % 3] += du;
                    q[(a + 2) % 3] += dv;
                    return !cpu_cast(world, q, sun).hit;
                };
                lit = sees_sun(0, 0);
                if (sees_sun(0.05, 0) != lit || sees_sun(-0.05, 0) != lit ||
                    sees_sun(0, 0.05) != lit || sees_sun(0, -0.05) != lit) {
                    continue;
                }
                (lit ? c.sunlit : c.shadowed) += 1;
            }
            const double ambient = (0.18 + 0.12 * nrm[1]) * cpu_occlusion(world, h.cell, nrm);
            const double light = ambient + (lit ? 0.8 * diffuse : 0.0);
            const Rgba base = palette[h.material];
            const std::uint8_t* px = &img.rgba[(std::size_t{j} * r.width + i) * 4];
            bool ok = px[3] == 255;
            for (int ch = 0; ch < 3; ++ch) {
                const double b = (ch == 0 ? base.r : (ch == 1 ? base.g : base.b)) / 255.0;
                const double want = std::round(to_srgb(to_linear(b) * light) * 255.0);
                ok = ok && std::abs(double(px[ch]) - want) <= 1.0;
            }
            ++c.compared;
            c.wrong += ok ? 0 : 1;
        }
    }
    return c;
}

// A floor, a thin roof slab across tile boundaries high above part of it and a wall, seen from
// above: the sun, normalize(1, 1, 1), casts the roof's and the wall's shadows toward -x, -z.
World shadow_world(Dims d) {
    World w(d);
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t x = 0; x < d.x; ++x) {
            w.set(x, 0, z, 1);
            for (std::uint32_t y = 1; y < 12 && x >= d.x * 2 / 3 && x < d.x * 2 / 3 + 2; ++y) {
                w.set(x, y, z, 2);
            }
            if (x >= d.x / 6 && x < d.x / 2 && z >= d.z / 6 && z < d.z / 2) {
                w.set(x, 9, z, 3);  // one voxel thick: a shadow ray must not skip it
            }
        }
    }
    return w;
}

TEST(SparseTrace, LitShadowsAndOcclusionFollowTheCasterModel) {
    REQUIRE_VULKAN(ctx);
    Palette palette;
    palette[1] = Rgba{255, 255, 255, 255};
    palette[2] = Rgba{200, 180, 160, 255};
    palette[3] = Rgba{90, 160, 220, 255};
    for (const Dims d : {Dims{48, 24, 48}, Dims{150, 30, 140}}) {
        const World world = shadow_world(d);
        vk::SparseTracer tracer(*ctx);
        tracer.upload(SparseWorld::from_dense(world), palette);
        for (const auto& r0 :
             {options(160, 160, {d.x / 2.0, 80, d.z / 2.0}, {d.x / 2.0, 0, d.z / 2.0}, 60),
              options(160, 120, {-20, 40, -30}, {d.x / 2.0, 0, d.z / 2.0}, 60)}) {
            vk::RenderOptions r = r0;
            r.shading = vk::Shading::lit;
            const vk::Image img = tracer.render(r);
            const LitCheck c = check_lit(world, palette, r, img);
            EXPECT_GT(c.compared, 2000u) << d.to_string();
            EXPECT_GT(c.shadowed, 500u) << d.to_string();
            EXPECT_GT(c.sunlit, 500u) << d.to_string();
            EXPECT_EQ(c.wrong, 0u) << "of " << c.compared << " pixels (" << c.shadowed
                                   << " in shadow, " << c.sunlit << " sunlit), " << d.to_string();
            // Hit or miss as in flat shading.
            vk::RenderOptions flat = r;
            flat.shading = vk::Shading::flat;
            const vk::Image f = tracer.render(flat);
            std::size_t mask = 0;
            for (std::size_t p = 0; p < f.rgba.size() / 4; ++p) {
                mask += same(&f.rgba[p * 4], r.sky) != same(&img.rgba[p * 4], r.sky) ? 1 : 0;
            }
            EXPECT_EQ(mask, 0u);
        }
    }
}

TEST(SparseTrace, SkyGradientAndBgra) {
    REQUIRE_VULKAN(ctx);
    const World world = scene_floor_spheres(Dims{64, 64, 64}, 3);
    vk::SparseTracer tracer(*ctx);
    tracer.upload(SparseWorld::from_dense(world), Palette());
    // Away from the world, up and down: the gradient's ends.
    vk::RenderOptions r = options(64, 48, {-100, 32, 32}, {-200, 32, 32}, 100);
    r.shading = vk::Shading::lit;
    r.sky_gradient = true;
    const vk::Image rgba = tracer.render(r);
    EXPECT_NE(std::memcmp(&rgba.rgba[0], &rgba.rgba[(std::size_t{r.height} - 1) * r.width * 4], 3),
              0);
    r = options(64, 48, {-30, 90, -40}, {32, 20, 32});
    r.shading = vk::Shading::lit;
    const vk::Image lit = tracer.render(r);
    EXPECT_LT(sky_pixels(lit.rgba, r.sky), std::size_t{r.width} * r.height);
    r.bgra = true;
    const vk::Image bgra = tracer.render(r);
    for (std::size_t p = 0; p < lit.rgba.size(); p += 4) {
        ASSERT_EQ(bgra.rgba[p], lit.rgba[p + 2]);
        ASSERT_EQ(bgra.rgba[p + 1], lit.rgba[p + 1]);
        ASSERT_EQ(bgra.rgba[p + 2], lit.rgba[p]);
        ASSERT_EQ(bgra.rgba[p + 3], 255);
    }
    // Another size from the same tracer: a new target, the flat image as a fresh tracer's.
    const vk::RenderOptions small = options(33, 17, {-30, 90, -40}, {32, 20, 32});
    const vk::Image again = tracer.render(small);
    vk::SparseTracer fresh(*ctx);
    fresh.upload(SparseWorld::from_dense(world), Palette());
    EXPECT_EQ(again.rgba, fresh.render(small).rgba);
    EXPECT_EQ(again.rgba.size(), 33u * 17u * 4u);
}

TEST(SparseTrace, DefaultCameraFramesTheSolids) {
    SparseWorld world(Dims{1000, 100, 1000});
    world.set(700, 10, 800, 3);
    world.set(720, 30, 840, 3);
    const vk::Camera c = vk::default_camera(world, 800, 600);
    EXPECT_DOUBLE_EQ(c.target[0], 710.5);
    EXPECT_DOUBLE_EQ(c.target[1], 20.5);
    EXPECT_DOUBLE_EQ(c.target[2], 820.5);
    // In front (-z) of the solids, above them, within a few boxes' extents.
    EXPECT_LT(c.position[2], 800);
    EXPECT_GT(c.position[1], 31);
    EXPECT_LT(std::abs(c.position[0] - 710.5), 200);
}

// ---- `voxfield render` of sparse inputs. ----

const fs::path kVox = fs::path(VOXFIELD_DATA_DIR) / "vox";

class SparseRenderCli : public ::testing::Test {
  protected:
    void SetUp() override {
        try {
            vk::select_device("");
        } catch (const vk::DeviceSelectionError&) {
            GTEST_SKIP() << "no Vulkan device";
        }
        dir_ = make_temp_dir("voxfield_sparse_render");
        io_ = make_temp_dir("voxfield_sparse_render_io");
        ::setenv("VOXFIELD_VALIDATE", "1", 1);  // any validation message exits 1
    }
    void TearDown() override {
        if (!dir_.empty()) {
            fs::remove_all(dir_);
            fs::remove_all(io_);
        }
    }
    fs::path dir_, io_;
};

TEST_F(SparseRenderCli, SparseImageEqualsTheDenseOne) {
    for (const char* model : {"chr_army1.vox", "scene_store8.vox"}) {
        const std::string in = (kVox / model).string();
        const fs::path dense = dir_ / "dense.png", sparse = dir_ / "sparse.png";
        const std::vector<std::string> view = {
            "--camera", "-40.3,110.2,-60.7", "--target", "40,20,45", "--width",
            "160",      "--height",          "120"};
        std::vector<std::string> a = {"render", in, "-o", dense.string()};
        a.insert(a.end(), view.begin(), view.end());
        std::vector<std::string> b = {"render", in, "-o", sparse.string(), "--sparse", "--stats"};
        b.insert(b.end(), view.begin(), view.end());
        const RunResult ra = run_voxfield(a, io_);
        const RunResult rb = run_voxfield(b, io_);
        ASSERT_EQ(ra.code, 0) << describe(ra);
        ASSERT_EQ(rb.code, 0) << describe(rb);
        EXPECT_NE(rb.out.find("traced through the 64-trees"), std::string::npos) << rb.out;
        EXPECT_NE(rb.out.find("node visits"), std::string::npos) << rb.out;
        const std::string pa = read_text(dense), pb = read_text(sparse);
        EXPECT_EQ(pb.substr(1, 3), "PNG");
        EXPECT_EQ(pa, pb) << model << ": the sparse PNG differs from the dense one";
        fs::remove(dense);
        fs::remove(sparse);
    }
}

TEST_F(SparseRenderCli, DefaultCameraAndLitShading) {
    const fs::path out = dir_ / "lit.png";
    const RunResult r =
        run_voxfield({"render", (kVox / "scene_store8.vox").string(), "-o", out.string(),
                      "--sparse", "--shading", "lit", "--width", "96", "--height", "64"},
                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(read_text(out).substr(1, 3), "PNG");
    EXPECT_EQ(list_dir(dir_), std::set<std::string>{"lit.png"});
}

// A .vdb grid of two 4^3 cubes 600000 voxels apart: 1.2e12 voxels, sparse without --sparse.
TEST_F(SparseRenderCli, HugeVdbGridIsRenderedSparse) {
    const fs::path grid = io_ / "far.vdb";
    write_far_cubes_vdb(grid);
    const fs::path out = dir_ / "far.png";
    const RunResult r =
        run_voxfield({"render", grid.string(), "-o", out.string(), "--camera", "600010,9,499990",
                      "--target", "600002,2,500002", "--width", "64", "--height", "48"},
                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.out.find("600004x4x500004"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("128 solid in 2 tiles"), std::string::npos) << r.out;
    EXPECT_EQ(read_text(out).substr(1, 3), "PNG");
}

// `bench --suite sparse` traces each row's world at 1920x1080 (flat and lit, GPU timestamps).
TEST_F(SparseRenderCli, SparseBenchTimesTheTrace) {
    const fs::path js = dir_ / "sparse.json";
    const RunResult r =
        run_voxfield({"bench", "--suite", "sparse", "--sizes", "130x40x64", "--max-distance", "4",
                      "--edits", "1", "--warmup", "0", "--device", "cpu", "--json", js.string()},
                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.err.find("traced 1920x1080"), std::string::npos) << r.err;
    const std::string text = read_text(js);
    for (const char* key :
         {"\"trace_flat_ms\"", "\"trace_lit_ms\"", "\"trace_lit_ms_samples\"",
          "\"trace_node_visits_per_ray\"", "\"trace_width\": 1920", "\"trace_height\": 1080"}) {
        EXPECT_NE(text.find(key), std::string::npos) << key << " missing in " << text;
    }
    EXPECT_EQ(text.find("trace_skipped"), std::string::npos) << text;
}

TEST_F(SparseRenderCli, BadInputExitsTwoWithOneLineAndNoFile) {
    write_file(dir_ / "world.txt", "not a world");
    write_file(dir_ / "part.sdf.json", "{}");
    const std::string model = (kVox / "chr_army1.vox").string();
    const std::string out = (dir_ / "out.png").string();
    const std::vector<std::vector<std::string>> cases = {
        {model, "-o", out, "--sparse", "--metric", "euclidean"},
        {model, "-o", out, "--sparse", "--field", "packed32"},
        {model, "-o", out, "--sparse", "--spacing", "1,2,1"},
        {model, "-o", out, "--sparse", "--device", "cpu"},
        {model, "-o", out, "--sparse", "--width", "0"},
        {model, "-o", out, "--sparse", "--camera", "1,2,3", "--target", "1,2,3"},
        {(dir_ / "part.sdf.json").string(), "-o", out, "--sparse"},
        {(dir_ / "world.txt").string(), "-o", out, "--sparse"},
        {(dir_ / "absent.vox").string(), "-o", out, "--sparse"},
    };
    for (const auto& args : cases) {
        std::vector<std::string> full = {"render"};
        full.insert(full.end(), args.begin(), args.end());
        const RunResult r = run_voxfield(full, io_);
        std::string cmd;
        for (const auto& a : args) {
            cmd += a + " ";
        }
        EXPECT_EQ(r.code, 2) << cmd << describe(r);
        EXPECT_EQ(split_lines(r.err).size(), 1u) << cmd << describe(r);
        EXPECT_EQ(list_dir(dir_), (std::set<std::string>{"part.sdf.json", "world.txt"})) << cmd;
    }
}

}  // namespace
}  // namespace voxfield::test
