// `exact` on PoCL, both kernel layouts, against the CPU reference (core/reference).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <initializer_list>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "cl_test_util.hpp"
#include "voxfield/cl/exact.hpp"
#include "voxfield/cl/separable.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield {
namespace {

using ocl::Layout;

const Format kFormats[] = {Format::u8, Format::u16, Format::u32, Format::packed32};
const Layout kLayouts[] = {Layout::cpu, Layout::gpu};

using test::pocl;

ocl::GeneratorOptions exact_options(Format f, Layout layout = Layout::automatic) {
    ocl::GeneratorOptions o;
    o.format = f;
    o.layout = layout;
    return o;
}

const char* name(Layout l) {
    return l == Layout::cpu ? "cpu" : "gpu";
}

// Checks every format and layout against the reference, voxel by voxel.
void expect_exact(const World& world, const Palette& palette, const std::string& what) {
    const auto exact = reference_manhattan(world);
    for (Format f : kFormats) {
        const auto want = encode_field(exact, world, palette, f);
        for (Layout layout : kLayouts) {
            const auto got = ocl::generate(pocl(), world, palette, exact_options(f, layout)).bytes;
            const std::string diff = test::first_difference(got, want, f, world.dims());
            if (!diff.empty()) {
                FAIL() << what << " " << world.dims().to_string() << " format " << to_string(f)
                       << " layout " << name(layout) << ": " << diff;
            }
        }
    }
}

TEST(ExactManhattan, MatchesReferenceOnRandomGrids) {
    std::mt19937_64 rng(20261122);
    const double densities[] = {0.0001, 0.001, 0.01, 0.05, 0.2, 0.5};
    auto axis = [&] {
        const std::uint32_t choices[] = {1, 2, 3, 7, 8, 13, 31, 32, 33, 64, 67, 97};
        return choices[rng() % std::size(choices)];
    };
    for (int i = 0; i < 60; ++i) {
        const Dims dims{axis(), axis(), axis()};
        const double density = densities[static_cast<std::size_t>(i) % std::size(densities)];
        expect_exact(scene_random(dims, density, rng()), Palette(),
                     "random #" + std::to_string(i) + " density " + std::to_string(density));
    }
}

TEST(ExactManhattan, EmptyFullAndSingleVoxels) {
    for (const Dims dims : {Dims{1, 1, 1}, Dims{5, 1, 3}, Dims{17, 9, 4}, Dims{40, 3, 29}}) {
        expect_exact(scene_empty(dims), Palette(), "empty");
        World full(dims);
        std::fill(full.voxels().begin(), full.voxels().end(), std::uint8_t{7});
        expect_exact(full, Palette(), "full");
        for (int corner = 0; corner < 8; ++corner) {
            World w(dims);
            w.set(corner & 1 ? dims.x - 1 : 0, corner & 2 ? dims.y - 1 : 0,
                  corner & 4 ? dims.z - 1 : 0, 3);
            expect_exact(w, Palette::dissertation(), "corner " + std::to_string(corner));
        }
    }
}

TEST(ExactManhattan, LongDistancesSaturate) {
    // Distances up to 300+ exceed u8 and the packed byte: they must saturate, never wrap.
    World w(Dims{300, 40, 3});
    w.set(0, 0, 0, 1);
    expect_exact(w, Palette(), "far single voxel");
}

TEST(ExactManhattan, ByteSweepsWidenFrom255) {
    // The CPU layout's byte sweeps hold min(distance, 255); a field whose largest distance is
    // 255 or more takes the wide sweeps (u16, u32), one of 254 stays on bytes. Along each
    // axis, and across all three.
    for (const std::uint32_t n : {254u, 255u, 256u, 257u, 300u}) {
        World x(Dims{n, 1, 1});
        x.set(0, 0, 0, 1);
        expect_exact(x, Palette(), "far along x");
        World y(Dims{2, n, 3});
        y.set(1, n - 1, 2, 1);
        expect_exact(y, Palette(), "far along y");
        World z(Dims{3, 2, n});
        z.set(2, 0, 0, 1);
        expect_exact(z, Palette(), "far along z");
    }
    World xyz(Dims{90, 90, 90});
    xyz.set(0, 0, 0, 1);
    xyz.set(89, 89, 89, 1);
    expect_exact(xyz, Palette(), "corners 267 apart");
    // Rows of 1024 voxels or more with few solids: the byte sweeps' scans carry distances
    // across 64-byte steps, every distance below 255, so that no format falls back to the
    // wide sweeps.
    World ramps(Dims{1030, 4, 2});
    for (std::uint32_t z = 0; z < 2; ++z) {
        for (std::uint32_t y = 0; y < 4; ++y) {
            for (std::uint32_t x = y; x < 1030; x += 100 + 7 * z) {
                ramps.set(x, y, z, 1);
            }
            ramps.set(1029 - y, y, z, 1);
        }
    }
    expect_exact(ramps, Palette(), "long rows of few solids");
}

// The kernels a generator of `world` launches in `layout` (ExactManhattan::kernel_path), and
// a check that its run() launched those (stage names in order).
std::vector<std::string> kernel_path(const World& world, Format f, Layout layout) {
    auto job = ocl::make_generator(pocl(), world, Palette(), exact_options(f, layout));
    const auto* exact = dynamic_cast<const ocl::ExactManhattan*>(job.get());
    if (exact == nullptr) {
        ADD_FAILURE() << "not an ExactManhattan";
        return {};
    }
    job->run();
    std::vector<std::string> ran;
    for (const auto& [name, ms] : job->stage_ms()) {
        ran.push_back(name);
    }
    std::vector<std::string> names;
    for (const std::string& step : exact->kernel_path()) {
        const std::string name = step.substr(0, step.find('/'));
        if (names.empty() || names.back() != name) {
            names.push_back(name);
        }
    }
    // The byte sweeps' wide fallback runs only where a distance reaches 255.
    if (ran.size() == 2 && names.size() == 4 && names[0] == "xy_bytes") {
        names.resize(2);
    }
    EXPECT_EQ(ran, names) << "stage_ms names a kernel of each launch, repeats summed";
    return exact->kernel_path();
}

TEST(ExactManhattan, LongColumnsUseEveryKernelPath) {
    // Columns up to 512 voxels take cols_seg with segments of 16, longer ones segments of 32
    // (u16's y columns 16 up to 1024), as many as a work-group holds (PoCL: 4096), and longer
    // ones in chunks of a work-group (cols_chunk_ends, cols_chunks); z-slices of at most 16 KiB
    // take x and y in one launch (xy_slice_local; xy_slice_segments where they are as few as the
    // compute units), larger ones, and those of worlds over 2^22 voxels, the row kernels and a y
    // column pass.
    // The CPU layout sweeps xy slices and strips of columns (on bytes where it can).
    using Path = std::vector<std::string>;
    const World tall = scene_random(Dims{17, 1100, 2}, 0.002, 5);
    const World mid = scene_random(Dims{33, 600, 2}, 0.003, 9);
    const World deep = scene_random(Dims{2, 2, 2100}, 0.001, 6);
    const World deeper = scene_random(Dims{2, 2, 32 * 4096 + 1}, 0.00002, 10);
    const World wide = scene_random(Dims{144, 120, 20}, 0.01, 7);
    const World small = scene_random(Dims{20, 30, 400}, 0.002, 8);
    const World one_slice = scene_random(Dims{20, 30, 1}, 0.01, 11);
    // Slices of 16 voxels: a world of exactly 2^22 voxels takes them, one slice more does not.
    const World at_bound = scene_random(Dims{4, 4, 1u << 18}, 0.00002, 12);
    const World over_bound = scene_random(Dims{4, 4, (1u << 18) + 1}, 0.00002, 12);
    for (Format f : kFormats) {
        EXPECT_EQ(kernel_path(tall, f, Layout::gpu),
                  (Path{"x_rows_local", "cols_seg/32", "cols_seg/16"}))
            << to_string(f);
        EXPECT_EQ(
            kernel_path(mid, f, Layout::gpu),
            (Path{"x_rows_local", f == Format::u16 ? "cols_seg/16" : "cols_seg/32", "cols_seg/16"}))
            << to_string(f);
        EXPECT_EQ(kernel_path(deep, f, Layout::gpu), (Path{"xy_slice_local", "cols_seg/32"}))
            << to_string(f);
        EXPECT_EQ(kernel_path(deeper, f, Layout::gpu),
                  (Path{"xy_slice_local", "cols_chunk_ends", "cols_chunks"}))
            << to_string(f);
        const Path wide_gpu = f == Format::u32 ? Path{"x_words", "cols_bits/16", "cols_seg/16"}
                                               : Path{"x_rows_map", "cols_seg/16", "cols_seg/16"};
        EXPECT_EQ(kernel_path(wide, f, Layout::gpu), wide_gpu) << to_string(f);
        EXPECT_EQ(kernel_path(small, f, Layout::gpu), (Path{"xy_slice_local", "cols_seg/16"}))
            << to_string(f);
        EXPECT_EQ(kernel_path(one_slice, f, Layout::gpu).front(), "xy_slice_segments")
            << to_string(f);
        EXPECT_EQ(kernel_path(at_bound, f, Layout::gpu),
                  (Path{"xy_slice_local", "cols_chunk_ends", "cols_chunks"}))
            << to_string(f);
        EXPECT_EQ(kernel_path(over_bound, f, Layout::gpu),
                  (Path{"x_rows_local", "cols_seg/16", "cols_chunk_ends", "cols_chunks"}))
            << to_string(f);
        // Bytes first where the format is unsigned and holds no colours, then (u16, u32) the
        // wide sweeps where a distance reaches 255.
        const Path cpu = f == Format::packed32 ? Path{"xy_slices_seq", "cols_strip_final"}
                         : f == Format::u8
                             ? Path{"xy_bytes", "z_bytes"}
                             : Path{"xy_bytes", "z_bytes", "xy_slices_seq", "cols_strip_final"};
        for (const World* w : {&tall, &mid, &deep, &deeper, &wide, &small}) {
            EXPECT_EQ(kernel_path(*w, f, Layout::cpu), cpu) << to_string(f);
        }
    }
    expect_exact(tall, Palette(), "tall");
    expect_exact(mid, Palette(), "mid");
    expect_exact(deep, Palette(), "deep");
    expect_exact(deeper, Palette(), "deeper");
    expect_exact(wide, Palette(), "wide");
    expect_exact(small, Palette(), "small");
    expect_exact(one_slice, Palette(), "one slice");
    expect_exact(over_bound, Palette(), "slices of a world over 2^22 voxels");
}

TEST(ExactManhattan, LongColumnsSaturatePerLane) {
    // cols_seg holds 4 columns of 1- or 2-byte work per work-item where X allows it (2 of u16
    // work for X = 6): every lane of a word saturates on its own, along y and along z; X = 7
    // keeps one column per item.
    for (const std::uint32_t x : {8u, 6u, 7u}) {
        World tall(Dims{x, 600, 3});
        tall.set(1, 0, 0, 1);
        expect_exact(tall, Palette(), "far along y");
        World deep(Dims{x, 3, 600});
        deep.set(x - 1, 2, 599, 1);
        deep.set(0, 0, 300, 2);
        expect_exact(deep, Palette(), "far along z");
    }
}

// A world of `dims` whose only solids are `solids`, each {x, y, z, material}.
World with_solids(Dims dims, std::initializer_list<std::array<std::uint32_t, 4>> solids) {
    World w(dims);
    for (const auto& [x, y, z, material] : solids) {
        w.set(x, y, z, static_cast<std::uint8_t>(material));
    }
    return w;
}

TEST(ExactManhattan, LongColumnsCarryAcrossHundredsOfSegments) {
    // Lines whose only solids are at one end, both or the middle, so that a voxel's nearest
    // solid lies thousands of segments away (u8 saturates, u16 and u32 do not): columns of
    // hundreds of cols_seg segments (more than 64: the scan of segment ends takes more steps);
    // columns longer than a work-group's segments (PoCL: 4096 of 32), in chunks of a work-group
    // (nine here, each 512 segments);
    // rows longer than a GPU's work-group (1024 segments of 16 voxels) in x_rows_map's chunks
    // of 128 segments (the last one partial in the second); ragged rows too long for
    // x_rows_local's local memory (PoCL: about 51000 voxels), a work-item per row.
    const std::pair<World, const char*> worlds[] = {
        {with_solids({2, 2, 20000}, {{0, 0, 0, 1}}), "cols_seg/32"},
        {with_solids({3, 2, 20000}, {{0, 0, 0, 1}, {2, 1, 19999, 2}}), "cols_seg/32"},
        {with_solids({4, 9001, 3}, {{0, 0, 0, 1}, {3, 9000, 2, 1}}), "cols_seg/32"},
        {with_solids({8, 2, 12000}, {{5, 1, 6007, 1}}), "cols_seg/32"},
        {with_solids({3, 2, 140001}, {{0, 0, 0, 1}, {1, 0, 70001, 1}, {2, 1, 140000, 1}}),
         "cols_chunks"},
        {with_solids({4, 140001, 2}, {{0, 0, 0, 1}, {3, 140000, 1, 1}}), "cols_chunks"},
        {with_solids({60000, 3, 2}, {{0, 0, 0, 1}, {30011, 1, 0, 1}, {59999, 2, 1, 1}}),
         "x_rows_chunks"},
        {with_solids({65552, 2, 2}, {{0, 0, 0, 1}, {30011, 1, 0, 1}, {65551, 1, 1, 1}}),
         "x_rows_chunks"},
        {with_solids({60001, 2, 2}, {{60000, 1, 1, 1}}), "x_rows_long"}};
    for (const auto& [w, kernel] : worlds) {
        const auto path = kernel_path(w, Format::u16, Layout::gpu);
        EXPECT_NE(std::find(path.begin(), path.end(), kernel), path.end())
            << w.dims().to_string() << " " << kernel;
        expect_exact(w, Palette(), "far ends");
    }
}

TEST(ExactManhattan, SliceSegmentsCarryAlongLines) {
    // xy_slice_segments sweeps a slice's rows and columns in segments of 16 values: lines of
    // one segment, of a segment and one value, of whole and ragged segments; sparse worlds
    // (carries across many empty segments, T_MAX runs) and dense ones (carries that a segment's
    // own values beat); a solid voxel at each end of the longest row and column. Worlds of as
    // many slices as the device has compute units take it, more take xy_slice_local.
    const std::uint32_t units = pocl().info().compute_units;
    const std::uint32_t sizes[] = {1, 15, 16, 17, 33, 52, 64, 100};
    std::uint64_t seed = 1;
    for (const std::uint32_t x : sizes) {
        for (const std::uint32_t y : sizes) {
            for (const double density : {0.002, 0.05, 0.4}) {
                const std::uint32_t z = density > 0.01 ? std::min(units, 3u) : units + 1;
                World w = scene_random(Dims{x, y, z}, density, seed++);
                w.set(0, 0, z - 1, 1);
                w.set(x - 1, y - 1, 0, 1);
                const auto exact = reference_manhattan(w);
                for (Format f : kFormats) {
                    // Slices above 16 KiB (u32 from 4096 voxels, rows padded) take the row
                    // kernels.
                    const std::string first = kernel_path(w, f, Layout::gpu).front();
                    if (first != "xy_slice_local" && first != "xy_slice_segments") {
                        EXPECT_GE(x * y, 4096u) << w.dims().to_string() << " " << to_string(f);
                        continue;
                    }
                    EXPECT_EQ(first, z <= units ? "xy_slice_segments" : "xy_slice_local");
                    const auto want = encode_field(exact, w, Palette(), f);
                    const auto got =
                        ocl::generate(pocl(), w, Palette(), exact_options(f, Layout::gpu)).bytes;
                    const std::string diff = test::first_difference(got, want, f, w.dims());
                    if (!diff.empty()) {
                        FAIL() << w.dims().to_string() << " density " << density << " format "
                               << to_string(f) << ": " << diff;
                    }
                }
            }
        }
    }
}

TEST(ExactManhattan, GpuLayoutOddShapes) {
    // Rows of 16-voxel words and ragged rows, columns of every cols_seg width and of
    // hundreds of segments along y and z, words of 1, 2 and 4 columns; slices in local memory
    // whose rows xy_slice_local pads (64 and 32 voxels: many rows of a warp in one bank) or not;
    // short u16 columns in groups of 16 to 64 work-items along x (seg_group_columns), the
    // rows' last group ragged (1000 and 2052 voxels: 250 and 513 words of 4 columns).
    const Dims shapes[] = {Dims{1, 1, 1},      Dims{3, 2049, 5},  Dims{300, 200, 700},
                           Dims{1024, 64, 96}, Dims{1040, 3, 2},  Dims{4, 9001, 3},
                           Dims{5, 3, 20011},  Dims{8, 2, 12000}, Dims{64, 40, 9},
                           Dims{32, 48, 5},    Dims{49, 49, 7},   Dims{1000, 70, 3},
                           Dims{2052, 64, 9}};
    for (const Dims dims : shapes) {
        const World w = scene_random(dims, 0.0002, dims.x + dims.y + dims.z);
        const auto exact = reference_manhattan(w);
        for (Format f : kFormats) {
            const auto want = encode_field(exact, w, Palette(), f);
            const auto got =
                ocl::generate(pocl(), w, Palette(), exact_options(f, Layout::gpu)).bytes;
            const std::string diff = test::first_difference(got, want, f, dims);
            if (!diff.empty()) {
                FAIL() << dims.to_string() << " format " << to_string(f) << ": " << diff;
            }
        }
    }
}

TEST(ExactManhattan, GpuBitRowsEveryWordCase) {
    // x_words and the y pass's expansion: rows of 16 voxels (half a word), 16 mod 32 (a half
    // word at the end), whole words and many words; solids only in far words, at a row's ends,
    // none in a row, a word's every bit; both directions of the nearest solid from the
    // neighbouring words' summaries.
    for (const std::uint32_t x : {16u, 48u, 96u, 512u}) {
        // Rows past the fifth stay empty: u32 slices above 16 KiB, which xy_slice_local leaves
        // to the row kernels.
        World edges = with_solids(
            Dims{x, std::max(5u, 4096u / x + 1), 4},
            {{0, 0, 0, 1}, {x - 1, 1, 0, 2}, {0, 2, 1, 3}, {x - 1, 2, 1, 4}, {x / 2, 3, 2, 5}});
        for (std::uint32_t i = 0; i < std::min(x, 32u); ++i) {
            edges.set(i, 4, 3, 6);
        }
        EXPECT_EQ(kernel_path(edges, Format::u32, Layout::gpu).front(), "x_words");
        expect_exact(edges, Palette(), "word edges");
        for (const double density : {0.002, 0.05, 0.6}) {
            const World w =
                scene_random(Dims{x, 9, 7}, density, x + static_cast<unsigned>(density * 1000));
            expect_exact(w, Palette(), "random rows");
        }
    }
}

// The GPU layout's field of `world` bounded at `bound` in each of `formats`: min(exact, bound).
void expect_bounded_gpu(const World& world, double bound, std::initializer_list<Format> formats,
                        const std::string& what) {
    auto capped = reference_distance(world, Metric::manhattan, Spacing{});
    for (double& v : capped) {
        v = std::min(v, bound);
    }
    for (Format f : formats) {
        ocl::ExactManhattan job(pocl(), world, Palette(), f, Layout::gpu, Metric::manhattan, bound);
        job.run();
        const std::string diff = test::first_difference(
            job.read(), encode_real_field(capped, world, Palette(), f), f, world.dims());
        EXPECT_TRUE(diff.empty()) << what << " bounded " << to_string(f) << ": " << diff;
    }
}

TEST(ExactManhattan, GpuRowsInChunksEveryCarry) {
    // x_rows_map's chunks (rows of more than 1024 segments, chunks of 128 = 2048 voxels): a row's
    // nearest target in its own chunk, in the next chunk or many chunks away on either side, at
    // the row's first or last voxel, in a partial last chunk, none at all; both rows of a
    // work-item; u8 (saturating) and u16, bounded fields, random rows.
    for (const std::uint32_t x : {16400u, 32768u, 36880u}) {
        World w = with_solids(Dims{x, 9, 3}, {{0, 0, 0, 1},
                                              {x - 1, 1, 0, 2},
                                              {0, 2, 1, 3},
                                              {x - 1, 2, 1, 4},
                                              {x / 2, 3, 2, 5},
                                              {2047, 4, 1, 6},
                                              {2048, 5, 0, 7},
                                              {x - 3, 6, 2, 8},
                                              {5 * 2048 + 100, 7, 0, 1}});
        for (std::uint32_t i = 0; i < x; i += 4093) {
            w.set(i, 8, 1, 9);
        }
        // (u32 rows of whole words below 65535 voxels take x_words.)
        for (Format f : {Format::u8, Format::u16}) {
            const auto path = kernel_path(w, f, Layout::gpu);
            EXPECT_NE(std::find(path.begin(), path.end(), "x_rows_chunks"), path.end()) << x;
        }
        expect_exact(w, Palette(), "row chunk cases");
        const World r = scene_random(w.dims(), 0.0004, x);
        expect_exact(r, Palette(), "random long rows");
        expect_bounded_gpu(w, 300.5, {Format::u16, Format::u32}, std::to_string(x));
    }
}

TEST(ExactManhattan, GpuRowMapEveryWordCase) {
    // x_rows_map: rows of 1 to 256 segments of 16 voxels (maps of one to four 64-bit words); the
    // nearest target in the same segment, the next one, the next word of the map or several
    // words away, only at a row's start or end, none; both rows of a work-item; bounded fields,
    // which saturate below the work type's maximum.
    for (const std::uint32_t x : {16u, 48u, 512u, 1040u, 4096u}) {
        // Slices above 16 KiB even for u8, which xy_slice_local leaves to the row kernels.
        World w = with_solids(Dims{x, std::max(9u, 16384u / x + 1), 3},
                              {{0, 0, 0, 1},
                               {x - 1, 1, 0, 2},
                               {0, 2, 1, 3},
                               {x - 1, 2, 1, 4},
                               {x / 2, 3, 2, 5},
                               {std::min(x - 1, 64u * 16u + 5), 4, 1, 6},
                               {std::min(x - 1, 3u * 64u * 16u + 9), 5, 0, 7}});
        for (std::uint32_t i = 0; i < std::min(x, 32u); ++i) {
            w.set(i, 6, 2, 8);
        }
        for (std::uint32_t i = 0; i < x; i += 17) {
            w.set(i, 7, 1, 9);
        }
        for (Format f : {Format::u8, Format::u16}) {
            EXPECT_EQ(kernel_path(w, f, Layout::gpu).front(), "x_rows_map") << x;
        }
        expect_exact(w, Palette(), "row map cases");
        const World r = scene_random(w.dims(), 0.003, x);
        expect_exact(r, Palette(), "random rows");
        expect_bounded_gpu(r, 6.5, {Format::u8, Format::u16}, std::to_string(x));
    }
}

TEST(ExactManhattan, BundledModels) {
    const std::filesystem::path dir = std::filesystem::path(VOXFIELD_DATA_DIR) / "vox";
    int models = 0;
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
        if (entry.path().extension() == ".vox") {
            const VoxModel m = read_vox(entry.path());
            expect_exact(m.world, m.palette, entry.path().filename().string());
            ++models;
        }
    }
    EXPECT_GE(models, 2);
}

TEST(ExactManhattan, Handles512Cubed) {
    const World w = scene_floor_spheres(Dims{512, 512, 512}, 6683787);
    const auto want = encode_field(reference_manhattan(w), w, Palette(), Format::u8);
    const auto got = ocl::generate(pocl(), w, Palette(), exact_options(Format::u8)).bytes;
    EXPECT_TRUE(got == want);
}

// Bounded fields from the same sweeps saturating at floor(D): min(exact, D) in every format
// and layout (packed32 and u8 also saturate at 255 where D is larger), L-inf in the CPU layout.
TEST(ExactManhattan, BoundedFieldsSaturateAtD) {
    const World w = scene_random(Dims{48, 37, 29}, 0.003, 17);
    for (Metric m : {Metric::manhattan, Metric::chebyshev}) {
        const auto exact = reference_distance(w, m, Spacing{});
        for (double bound : {1.0, 6.5, 300.0}) {
            std::vector<double> capped = exact;
            for (double& v : capped) {
                v = std::min(v, bound);
            }
            for (Format f : kFormats) {
                const auto want = encode_real_field(capped, w, Palette(), f);
                for (Layout layout : kLayouts) {
                    if (m == Metric::chebyshev && layout == Layout::gpu) {
                        continue;
                    }
                    auto o = exact_options(f, layout);
                    o.metric = m;
                    o.max_distance = bound;
                    ASSERT_TRUE(ocl::ExactManhattan::handles(pocl(), o, w.dims()));
                    ocl::ExactManhattan job(pocl(), w, Palette(), f, layout, m, bound);
                    job.run();
                    const std::string diff = test::first_difference(job.read(), want, f, w.dims());
                    if (!diff.empty()) {
                        FAIL() << to_string(m) << " D " << bound << " format " << to_string(f)
                               << " layout " << name(layout) << ": " << diff;
                    }
                }
            }
        }
    }
}

// Columns in chunks (cols_chunk_ends, cols_chunks) with bounds: the carries from other chunks
// saturate at floor(D) as within a chunk, where D is below a chunk's length and beyond it.
TEST(ExactManhattan, LongColumnsInChunksSaturateAtD) {
    const World w =
        with_solids({3, 2, 140001}, {{0, 0, 0, 1}, {1, 0, 70001, 1}, {2, 1, 140000, 1}});
    const auto exact = reference_distance(w, Metric::manhattan, Spacing{});
    const std::pair<Format, double> cases[] = {{Format::packed32, 1.0},
                                               {Format::u16, 300.0},
                                               {Format::u16, 20000.5},
                                               {Format::u32, 100000.0}};
    for (const auto& [f, bound] : cases) {
        std::vector<double> capped = exact;
        for (double& v : capped) {
            v = std::min(v, bound);
        }
        ocl::ExactManhattan job(pocl(), w, Palette(), f, Layout::gpu, Metric::manhattan, bound);
        job.run();
        const std::string diff = test::first_difference(
            job.read(), encode_real_field(capped, w, Palette(), f), f, w.dims());
        ASSERT_TRUE(diff.empty()) << "D " << bound << " format " << to_string(f) << ": " << diff;
    }
}

TEST(ExactManhattan, RepeatedRunsAreBitIdentical) {
    const World w = scene_terrain(Dims{96, 64, 80}, 3);
    for (Layout layout : kLayouts) {
        ocl::ExactManhattan job(pocl(), w, Palette(), Format::packed32, layout);
        job.run();
        const auto first = job.read();
        for (int i = 0; i < 3; ++i) {
            job.run();
            EXPECT_TRUE(job.read() == first) << name(layout);
        }
    }
}

// L-inf by exact_manhattan.cl's sweeps (the CPU layout's path for unsigned unit-spacing
// fields): every format against core's reference, whose line search shares nothing with them.
void expect_chebyshev(const World& world, const Palette& palette, const std::string& what) {
    const auto exact = reference_distance(world, Metric::chebyshev, Spacing{});
    for (Format f : kFormats) {
        auto o = exact_options(f, Layout::cpu);
        o.metric = Metric::chebyshev;
        ASSERT_TRUE(ocl::ExactManhattan::handles(pocl(), o, world.dims()));
        const auto want = encode_real_field(exact, world, palette, f);
        ocl::ExactManhattan job(pocl(), world, palette, f, Layout::cpu, Metric::chebyshev);
        job.run();
        const std::string diff = test::first_difference(job.read(), want, f, world.dims());
        if (!diff.empty()) {
            FAIL() << what << " " << world.dims().to_string() << " format " << to_string(f) << ": "
                   << diff;
        }
    }
}

TEST(ExactChebyshevSweeps, MatchReferenceOnRandomGrids) {
    std::mt19937_64 rng(20261203);
    const double densities[] = {0.0, 0.0002, 0.002, 0.01, 0.05, 0.2, 0.5, 0.9, 1.0};
    auto axis = [&] {
        const std::uint32_t choices[] = {1, 2, 3, 7, 8, 13, 31, 32, 33, 64, 70};
        return choices[rng() % std::size(choices)];
    };
    for (int i = 0; i < 60; ++i) {
        const Dims dims{axis(), axis(), axis()};
        const double density = densities[static_cast<std::size_t>(i) % std::size(densities)];
        expect_chebyshev(scene_random(dims, density, rng()), Palette(),
                         "random #" + std::to_string(i) + " density " + std::to_string(density));
    }
}

TEST(ExactChebyshevSweeps, SingleVoxelsDiagonalsAndSaturation) {
    // One solid per corner: the field is a cube's shells, reached by every king move.
    for (const Dims dims : {Dims{1, 1, 1}, Dims{5, 1, 3}, Dims{17, 9, 4}, Dims{3, 40, 29}}) {
        for (int corner = 0; corner < 8; ++corner) {
            World w(dims);
            w.set(corner & 1 ? dims.x - 1 : 0, corner & 2 ? dims.y - 1 : 0,
                  corner & 4 ? dims.z - 1 : 0, 3);
            expect_chebyshev(w, Palette::dissertation(), "corner " + std::to_string(corner));
        }
    }
    // Distances past 255 saturate u8 and the packed byte.
    World far(Dims{300, 40, 3});
    far.set(0, 0, 0, 1);
    expect_chebyshev(far, Palette(), "far single voxel");
}

TEST(ExactChebyshevSweeps, WideAndLongWorlds) {
    // Wide planes and long axes: z_king walks every plane of each in turn.
    expect_chebyshev(scene_random(Dims{700, 3, 400}, 0.0005, 8), Palette(), "wide");
    expect_chebyshev(scene_random(Dims{5, 4, 900}, 0.002, 9), Palette(), "long z");
    expect_chebyshev(scene_random(Dims{6, 900, 3}, 0.002, 10), Palette(), "long y");
    expect_chebyshev(scene_random(Dims{900, 2, 5}, 0.002, 11), Palette(), "long x");
}

TEST(ExactChebyshevSweeps, BytesWidenFrom255) {
    // As ExactManhattan.ByteSweepsWidenFrom255, for L-inf's byte sweeps.
    for (const std::uint32_t n : {254u, 255u, 256u, 300u}) {
        World x(Dims{n, 1, 1});
        x.set(0, 0, 0, 1);
        expect_chebyshev(x, Palette(), "far along x");
        World y(Dims{2, n, 3});
        y.set(1, n - 1, 2, 1);
        expect_chebyshev(y, Palette(), "far along y");
        World z(Dims{3, 2, n});
        z.set(2, 0, 0, 1);
        expect_chebyshev(z, Palette(), "far along z");
    }
}

TEST(ExactChebyshevSweeps, RoutedByLayout) {
    const Dims small{9, 9, 9};
    auto o = exact_options(Format::u16, Layout::cpu);
    o.metric = Metric::chebyshev;
    EXPECT_TRUE(ocl::ExactManhattan::handles(pocl(), o, small));
    o.layout = Layout::gpu;
    EXPECT_FALSE(ocl::ExactManhattan::handles(pocl(), o, small));
    o.layout = Layout::cpu;
    o.format = Format::f32;
    EXPECT_FALSE(ocl::ExactManhattan::handles(pocl(), o, small));
    o.format = Format::u16;
    o.max_distance = 4.0;  // bounded: the same sweeps, saturating at floor(D)
    EXPECT_TRUE(ocl::ExactManhattan::handles(pocl(), o, small));
    o.signed_field = true;
    EXPECT_FALSE(ocl::ExactManhattan::handles(pocl(), o, small));
    const World w = scene_random(Dims{9, 9, 9}, 0.1, 1);
    EXPECT_THROW(
        ocl::ExactManhattan(pocl(), w, Palette(), Format::u16, Layout::gpu, Metric::chebyshev),
        std::invalid_argument);
    EXPECT_THROW(
        ocl::ExactManhattan(pocl(), w, Palette(), Format::u16, Layout::cpu, Metric::euclidean),
        std::invalid_argument);
}

// The CPU layout's x pass: rows with no solid, with up to 16 solids (the wide sweeps'
// row_ramps: runs of solids, solids at the row's ends), with 8 and 16 solids per 64 bytes of
// the row rounded up to 64 and with more (doubling steps that stop early: runs of 5 solids 5
// apart), a row of solids on both sides of every 64-byte step's edge (the byte sweeps' scans
// carry across it), in rows of lengths around the 16-voxel blocks, for L1 (unsigned and
// signed) and L-inf.
World rows_world(std::uint32_t X, std::uint32_t seed) {
    std::mt19937_64 rng(seed);
    const std::uint32_t eight_per_step = (X + 63) / 64 * 8;
    const std::uint32_t counts[] = {
        0, 1, 2, 15, 16, 17, eight_per_step, eight_per_step + 1, 40, eight_per_step * 2, X / 2, X};
    World w(Dims{X, static_cast<std::uint32_t>(std::size(counts)) + 3, 3});
    for (std::uint32_t z = 0; z < 3; ++z) {
        for (std::uint32_t r = 0; r < std::size(counts); ++r) {
            for (std::uint32_t i = 0; i < std::min(counts[r], X); ++i) {
                w.set(static_cast<std::uint32_t>(rng() % X), r, z, 1);
            }
        }
        // A row of runs: both ends and a run in the middle.
        const std::uint32_t y = static_cast<std::uint32_t>(std::size(counts));
        for (std::uint32_t x : {0u, 1u, X / 2, X / 2 + 1, X / 2 + 2, X - 1}) {
            w.set(std::min(x, X - 1), y, z, 2);
        }
        // Runs of 5 solids 5 apart (up to 30 runs), the first from x = z.
        for (std::uint32_t x = z; x < X; ++x) {
            if ((x - z) % 10 < 5) {
                w.set(x, y + 1, z, 3);
            }
        }
        // The last voxel of one 64-byte step and the first of the next, every 64 * (z + 1).
        for (std::uint32_t x = 64 * (z + 1); x < X; x += 64 * (z + 1)) {
            w.set(x - 1, y + 2, z, 4);
            w.set(x, y + 2, z, 4);
        }
    }
    return w;
}

// A signed L1 field (i8, i16, i32) on the CPU layout's SIGNED sweeps against core's
// reference_signed, voxel by voxel.
void expect_signed(const World& world, const std::string& what) {
    const auto exact = reference_signed(world, Metric::manhattan, Spacing{});
    for (Format f : {Format::i8, Format::i16, Format::i32}) {
        auto o = exact_options(f, Layout::cpu);
        o.signed_field = true;
        auto job = ocl::make_generator(pocl(), world, Palette(), o);
        ASSERT_NE(dynamic_cast<const ocl::ExactManhattan*>(job.get()), nullptr) << what;
        job->run();
        const auto want = encode_real_field(exact, world, Palette(), f);
        const std::string diff = test::first_difference(job->read(), want, f, world.dims());
        if (!diff.empty()) {
            FAIL() << what << " " << world.dims().to_string() << " format " << to_string(f) << ": "
                   << diff;
        }
    }
}

TEST(ExactManhattanRows, SparseAndDenseRows) {
    for (std::uint32_t X : {1u, 2u, 15u, 16u, 17u, 33u, 64u, 300u, 1024u, 1030u, 2100u}) {
        const World w = rows_world(X, X);
        expect_exact(w, Palette(), "rows");
        expect_chebyshev(w, Palette(), "rows");
        expect_signed(w, "rows");
    }
}

TEST(ExactSignedSweeps, MatchReferenceOnRandomGrids) {
    std::mt19937_64 rng(20261203);
    const double densities[] = {0.0001, 0.001, 0.01, 0.05, 0.2, 0.5, 0.9, 1.0};
    auto axis = [&] {
        const std::uint32_t choices[] = {1, 2, 3, 7, 16, 17, 31, 33, 64, 67, 97};
        return choices[rng() % std::size(choices)];
    };
    for (int i = 0; i < 60; ++i) {
        const Dims dims{axis(), axis(), axis()};
        const double density = densities[static_cast<std::size_t>(i) % std::size(densities)];
        expect_signed(scene_random(dims, density, rng()),
                      "random #" + std::to_string(i) + " density " + std::to_string(density));
    }
}

TEST(ExactSignedSweeps, EmptyFullLongAxesAndSaturation) {
    for (const Dims dims : {Dims{1, 1, 1}, Dims{5, 1, 3}, Dims{17, 9, 4}}) {
        expect_signed(scene_empty(dims), "empty");
        World full(dims);
        std::fill(full.voxels().begin(), full.voxels().end(), std::uint8_t{7});
        expect_signed(full, "full");
    }
    // Long thin axes; a full slab 300 deep (solid distances past i8's 127) and a lone voxel
    // 300 away (empty distances past 127).
    expect_signed(scene_random(Dims{700, 3, 2}, 0.004, 3), "long x");
    expect_signed(scene_random(Dims{2, 700, 3}, 0.004, 4), "long y");
    expect_signed(scene_random(Dims{3, 2, 700}, 0.004, 5), "long z");
    World slab(Dims{3, 300, 2});
    std::fill(slab.voxels().begin(), slab.voxels().end(), std::uint8_t{1});
    expect_signed(slab, "full long y");
    World lone(Dims{300, 2, 3});
    lone.set(0, 1, 1, 1);
    expect_signed(lone, "far single voxel");
}

TEST(ExactSignedSweeps, BundledModels) {
    const std::filesystem::path dir = std::filesystem::path(VOXFIELD_DATA_DIR) / "vox";
    int models = 0;
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
        if (entry.path().extension() == ".vox") {
            expect_signed(read_vox(entry.path()).world, entry.path().filename().string());
            ++models;
        }
    }
    EXPECT_GE(models, 2);
}

// Signed L1 takes the sweeps only unbounded, in the CPU layout and a signed integer format;
// ExactSeparable computes the rest.
TEST(ExactSignedSweeps, RoutedByLayoutFormatAndBound) {
    const Dims small{9, 9, 9};
    auto o = exact_options(Format::i16, Layout::cpu);
    o.signed_field = true;
    EXPECT_TRUE(ocl::ExactManhattan::handles(pocl(), o, small));
    o.layout = Layout::gpu;
    EXPECT_FALSE(ocl::ExactManhattan::handles(pocl(), o, small));
    o.layout = Layout::cpu;
    o.format = Format::f32;
    EXPECT_FALSE(ocl::ExactManhattan::handles(pocl(), o, small));
    o.format = Format::i32;
    o.max_distance = 4.0;
    EXPECT_FALSE(ocl::ExactManhattan::handles(pocl(), o, small));
    o.max_distance.reset();
    o.metric = Metric::chebyshev;
    EXPECT_FALSE(ocl::ExactManhattan::handles(pocl(), o, small));
    o.metric = Metric::manhattan;
    o.signed_field = false;  // an unsigned field in a signed format: ExactSeparable
    EXPECT_FALSE(ocl::ExactManhattan::handles(pocl(), o, small));
    const World w = scene_random(Dims{9, 9, 9}, 0.1, 1);
    EXPECT_THROW(ocl::ExactManhattan(pocl(), w, Palette(), Format::i16, Layout::gpu),
                 std::invalid_argument);
    EXPECT_THROW(
        ocl::ExactManhattan(pocl(), w, Palette(), Format::i16, Layout::cpu, Metric::manhattan, 5.0),
        std::invalid_argument);
}

// The CPU layout's signed and L-inf sweeps hold a row (with its padding) and a z column in
// local memory: a world whose lines are longer takes ExactSeparable, exact as ever, instead of
// failing with CL_OUT_OF_RESOURCES (1 MiB on PoCL here: signed i32 rows of 70001 voxels, L-inf
// u16 rows of 2^20). Lines a little longer than this device's local memory holds.
TEST(ExactSweeps, LinesLongerThanLocalMemoryTakeTheSeparableTransform) {
    const auto longest = static_cast<std::uint32_t>(pocl().info().local_mem / 2 + 1);
    struct Case {
        Dims dims;
        Metric metric;
        bool sgn;
        Format format;
    };
    const Case cases[] = {{{longest, 2, 1}, Metric::manhattan, true, Format::i32},
                          {{1, 2, longest / 2 + 1}, Metric::manhattan, true, Format::i32},
                          {{longest, 1, 2}, Metric::chebyshev, false, Format::u16},
                          {{2, 1, longest + 1}, Metric::chebyshev, false, Format::u16}};
    std::uint64_t seed = 9;
    for (const Case& c : cases) {
        const World w = scene_random(c.dims, 0.0005, ++seed);
        auto o = exact_options(c.format, Layout::cpu);
        o.metric = c.metric;
        o.signed_field = c.sgn;
        const std::string what =
            c.dims.to_string() + " " + to_string(c.metric) + (c.sgn ? " signed" : "");
        EXPECT_FALSE(ocl::ExactManhattan::handles(pocl(), o, c.dims)) << what;
        auto job = ocl::make_generator(pocl(), w, Palette(), o);
        ASSERT_NE(dynamic_cast<const ocl::ExactSeparable*>(job.get()), nullptr) << what;
        job->run();
        const auto exact = c.sgn ? reference_signed(w, c.metric, Spacing{})
                                 : reference_distance(w, c.metric, Spacing{});
        const std::string diff = test::first_difference(
            job->read(), encode_real_field(exact, w, Palette(), c.format), c.format, c.dims);
        EXPECT_TRUE(diff.empty()) << what << ": " << diff;
    }
    // Lines that fit keep the sweeps.
    auto o = exact_options(Format::i32, Layout::cpu);
    o.signed_field = true;
    EXPECT_TRUE(ocl::ExactManhattan::handles(pocl(), o, Dims{64, 2, 3}));
}

TEST(DeviceSelection, ExplainsRejections) {
    try {
        ocl::select_device("9999");
        FAIL() << "index 9999 was accepted";
    } catch (const ocl::DeviceSelectionError& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find("not index 9999"), std::string::npos) << msg;
        EXPECT_NE(msg.find("#0 "), std::string::npos) << msg;
    }
    EXPECT_THROW(ocl::select_device("fastest"), ocl::DeviceSelectionError);
    EXPECT_EQ(ocl::select_device("cpu").type, "cpu");
}

}  // namespace
}  // namespace voxfield
