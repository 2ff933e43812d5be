// Incremental updates on PoCL: after every batch of random edits the field equals a full
// regeneration (the CPU reference), and nothing outside the reported regions is written.
#include <gtest/gtest.h>

#include <algorithm>
#include <optional>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "cl_test_util.hpp"
#include "voxfield/cl/incremental.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/undo.hpp"

namespace voxfield {
namespace {

using test::pocl;

ocl::GeneratorOptions exact_options(Format f) {
    ocl::GeneratorOptions o;
    o.format = f;
    return o;
}

Brush random_brush(std::mt19937_64& rng, Dims d, std::int64_t max_radius) {
    Brush b;
    const auto op = rng() % 10;
    b.op = op < 5 ? BrushOp::place : op < 9 ? BrushOp::erase : BrushOp::paint;
    b.shape = rng() % 2 == 0 ? BrushShape::sphere : BrushShape::cube;
    // Centres up to max_radius outside the world, so edits touch and cross every border.
    auto coord = [&](std::uint32_t n) {
        return static_cast<std::int64_t>(rng() % (n + 2 * static_cast<std::uint64_t>(max_radius))) -
               max_radius;
    };
    b.centre = {coord(d.x), coord(d.y), coord(d.z)};
    b.radius = static_cast<std::int64_t>(rng() % static_cast<std::uint64_t>(max_radius + 1));
    b.material = static_cast<std::uint8_t>(1 + rng() % 255);
    return b;
}

void expect_exact(ocl::IncrementalField& field, Format f, const std::string& what) {
    const World& w = field.world();
    const auto want = encode_field(reference_manhattan(w), w, Palette(), f);
    const std::string diff = test::first_difference(field.read(), want, f, w.dims());
    ASSERT_TRUE(diff.empty()) << what << ": " << diff;
}

TEST(Incremental, ThousandsOfRandomEditsStayExact) {
    // Both sweep layouts (CPU: inner loops along x; GPU: a column per work-item) on PoCL.
    for (const ocl::Layout layout : {ocl::Layout::cpu, ocl::Layout::gpu}) {
        std::mt19937_64 rng(1234);
        const World start = scene_floor_spheres(Dims{48, 40, 36}, 17, 10);
        auto o = exact_options(Format::u16);
        o.layout = layout;
        ocl::IncrementalField field(pocl(), start, Palette(), o);
        int edits = 0;
        for (int batch = 0; batch < 500; ++batch) {
            std::vector<Brush> brushes;
            const int n = batch % 3 == 0 ? 4 : 1;  // some frames carry several edits
            for (int i = 0; i < n; ++i) {
                brushes.push_back(random_brush(rng, start.dims(), batch % 7 == 0 ? 20 : 8));
            }
            const auto stats = field.apply(brushes);
            edits += n;
            ASSERT_EQ(stats.edits.size(), brushes.size());
            expect_exact(field, Format::u16,
                         std::string(layout == ocl::Layout::cpu ? "cpu" : "gpu") +
                             " layout, after batch " + std::to_string(batch));
        }
        EXPECT_GE(edits, 1000);
    }
}

// A cap box of more than 2^15 blocks (an unbounded field in a world of 33 792 blocks) makes
// the GPU layout's inc_place and inc_bounds take eight blocks per work-group instead of one:
// edits there, placing and erasing, stay exact.
TEST(Incremental, WideCapBoxesTakeSeveralBlocksPerGroup) {
    const World start = scene_floor_spheres(Dims{528, 256, 128}, 7, 12);
    auto o = exact_options(Format::u16);
    o.layout = ocl::Layout::gpu;
    ocl::IncrementalField field(pocl(), start, Palette(), o);
    std::mt19937_64 rng(99);
    for (int i = 0; i < 6; ++i) {
        Brush b = random_brush(rng, start.dims(), 6);
        b.op = i % 3 == 2 ? BrushOp::erase : BrushOp::place;
        b.radius = std::max<std::int64_t>(b.radius, 2);
        const auto stats = field.apply({b});
        ASSERT_EQ(stats.edits.size(), 1u);
        EXPECT_FALSE(stats.full_regeneration) << "edit " << i;
        expect_exact(field, Format::u16, "edit " + std::to_string(i));
    }
}

// Chebyshev, Euclidean, spacing and signed fields (ExactSeparable's incremental passes):
// after every batch the field is byte-identical to a fresh full transform of the edited
// world, in both layouts.
TEST(Incremental, EveryMetricStaysExact) {
    struct Case {
        Metric metric;
        Spacing spacing;
        bool signed_field;
        Format format;
        std::optional<double> max_distance = std::nullopt;
    };
    const Case cases[] = {{Metric::chebyshev, {}, false, Format::u16},
                          {Metric::euclidean, {}, false, Format::f32},
                          {Metric::euclidean, {0.5, 1.5, 1.0}, false, Format::f64},
                          {Metric::chebyshev, {}, true, Format::i16},
                          {Metric::euclidean, {}, true, Format::f32},
                          {Metric::manhattan, {}, true, Format::i8},
                          {Metric::manhattan, {2.0, 1.0, 0.5}, false, Format::packed32},
                          {Metric::manhattan, {}, false, Format::u16, 4.0},
                          {Metric::euclidean, {}, false, Format::f32, 6.5},
                          {Metric::chebyshev, {1.0, 2.0, 0.5}, true, Format::f32, 3.0}};
    for (const Case& c : cases) {
        for (const ocl::Layout layout : {ocl::Layout::cpu, ocl::Layout::gpu}) {
            std::mt19937_64 rng(4321);
            const World start = scene_floor_spheres(Dims{37, 30, 26}, 11, 6);
            ocl::GeneratorOptions o = exact_options(c.format);
            o.metric = c.metric;
            o.spacing = c.spacing;
            o.signed_field = c.signed_field;
            o.max_distance = c.max_distance;
            o.layout = layout;
            ocl::IncrementalField field(pocl(), start, Palette(), o);
            const std::string what =
                to_string(c.metric) + " " + c.spacing.to_string() +
                (c.signed_field ? " signed " : " ") + to_string(c.format) +
                (c.max_distance ? " max " + std::to_string(*c.max_distance) : "") +
                (layout == ocl::Layout::cpu ? " cpu" : " gpu");
            int local = 0;  // batches updated incrementally
            for (int batch = 0; batch < 40; ++batch) {
                std::vector<Brush> brushes;
                for (int i = 0; i < (batch % 4 == 0 ? 3 : 1); ++i) {
                    brushes.push_back(random_brush(rng, start.dims(), batch % 5 == 0 ? 14 : 5));
                }
                const auto stats = field.apply(brushes);
                const auto want = ocl::generate(pocl(), field.world(), Palette(), o).bytes;
                ASSERT_TRUE(field.read() == want) << what << ", after batch " << batch;
                if (stats.edits.front().occupancy_changed()) {
                    EXPECT_GT(stats.voxels_recomputed, 0u) << what;
                }
                // Bounded: every changed voxel lies within D (in voxels of the finest
                // spacing) of an edited one, plus the one-voxel slack of rounding up (unless
                // the batch spanned so much of the world that it was regenerated whole).
                local += stats.full_regeneration ? 0 : 1;
                for (const Box& r : stats.regions) {
                    if (!c.max_distance || stats.full_regeneration) {
                        break;
                    }
                    const double finest = std::min({c.spacing.x, c.spacing.y, c.spacing.z});
                    const auto reach = static_cast<std::int64_t>(*c.max_distance / finest) + 2;
                    Box edited;
                    for (const EditResult& e : stats.edits) {
                        if (e.changed()) {
                            edited = hull(edited, e.bounds);
                        }
                    }
                    EXPECT_GE(r.min.x, edited.min.x - reach) << what;
                    EXPECT_LE(r.max.x, edited.max.x + reach) << what;
                    EXPECT_GE(r.min.y, edited.min.y - reach) << what;
                    EXPECT_LE(r.max.y, edited.max.y + reach) << what;
                    EXPECT_GE(r.min.z, edited.min.z - reach) << what;
                    EXPECT_LE(r.max.z, edited.max.z + reach) << what;
                }
            }
            EXPECT_GE(local, 30) << what;
        }
    }
}

TEST(Incremental, BoundedL1IsMinOfExactAndTheBound) {
    // Bounded unit-spacing L1 fields take the capped sweeps (place pass, exact R, capped z
    // sweep): after every batch the field equals min(exact, floor(D)) voxel by voxel, in both
    // layouts, for integer and fractional bounds and saturating formats; every changed voxel
    // lies within D of the edit's changed box.
    struct Case {
        double bound;
        Format format;
    };
    const Case cases[] = {{1.0, Format::u16},
                          {3.5, Format::u8},
                          {7.0, Format::packed32},
                          {300.0, Format::u8},
                          {12.0, Format::u32}};
    for (const Case& c : cases) {
        for (const ocl::Layout layout : {ocl::Layout::cpu, ocl::Layout::gpu}) {
            std::mt19937_64 rng(1618);
            const World start = scene_floor_spheres(Dims{41, 35, 30}, 9, 6);
            ocl::GeneratorOptions o = exact_options(c.format);
            o.max_distance = c.bound;
            o.layout = layout;
            ocl::IncrementalField field(pocl(), start, Palette(), o);
            const auto cap = static_cast<std::uint32_t>(c.bound);
            const std::string what = "max " + std::to_string(c.bound) + " " + to_string(c.format) +
                                     (layout == ocl::Layout::cpu ? " cpu" : " gpu");
            int local = 0;  // batches updated incrementally
            for (int batch = 0; batch < 50; ++batch) {
                std::vector<Brush> brushes = {random_brush(rng, start.dims(), 7)};
                if (batch % 3 == 0) {
                    brushes.push_back(random_brush(rng, start.dims(), 4));
                }
                const std::vector<std::uint8_t> before = field.read();
                const auto stats = field.apply(brushes);
                std::vector<std::uint32_t> want = reference_manhattan(field.world());
                for (std::uint32_t& v : want) {
                    v = std::min(v, cap);
                }
                const std::vector<std::uint8_t> got = field.read();
                const std::string diff = test::first_difference(
                    got, encode_field(want, field.world(), Palette(), c.format), c.format,
                    start.dims());
                ASSERT_TRUE(diff.empty()) << what << ", batch " << batch << ": " << diff;
                if (stats.full_regeneration) {
                    continue;
                }
                ++local;
                Box changed;
                for (const EditResult& e : stats.edits) {
                    changed = hull(changed, e.bounds);
                }
                const Dims d = start.dims();
                const auto reach = static_cast<std::int64_t>(c.bound);
                for (std::size_t i = 0; i < start.size(); ++i) {
                    if (decode_distance(got, c.format, i) == decode_distance(before, c.format, i)) {
                        continue;
                    }
                    const Int3 p{static_cast<std::int64_t>(i % d.x),
                                 static_cast<std::int64_t>(i / d.x % d.y),
                                 static_cast<std::int64_t>(i / d.x / d.y)};
                    const std::int64_t gap =
                        std::max<std::int64_t>({changed.min.x - p.x, p.x - changed.max.x + 1, 0}) +
                        std::max<std::int64_t>({changed.min.y - p.y, p.y - changed.max.y + 1, 0}) +
                        std::max<std::int64_t>({changed.min.z - p.z, p.z - changed.max.z + 1, 0});
                    ASSERT_LE(gap, reach) << what << ": a voxel changed " << gap
                                          << " voxels from the edits, batch " << batch;
                }
            }
            // Only batches spanning an eighth of the world regenerate: the region, within D
            // of the edits, never overflows the cap box.
            EXPECT_GE(local, 40) << what;
        }
    }
}

TEST(Incremental, EveryFormatAndSmallMargins) {
    // Both layouts: small margins cut the cap box, so the block passes' overflow flags (the
    // GPU kernels' and the CPU _seq kernels') must send updates to a full regeneration.
    for (const ocl::Layout layout : {ocl::Layout::cpu, ocl::Layout::gpu}) {
        std::mt19937_64 rng(77);
        for (Format f : {Format::u8, Format::u32, Format::packed32}) {
            for (std::uint32_t margin : {1u, 3u, 64u}) {
                const World start = scene_terrain(Dims{33, 21, 27}, 5);
                auto o = exact_options(f);
                o.layout = layout;
                ocl::IncrementalField field(pocl(), start, Palette(), o, margin);
                bool fell_back = false;
                const std::string what = std::string(layout == ocl::Layout::cpu ? "cpu" : "gpu") +
                                         " layout, " + to_string(f) + " margin " +
                                         std::to_string(margin);
                for (int batch = 0; batch < 60; ++batch) {
                    fell_back |=
                        field.apply({random_brush(rng, start.dims(), 6)}).full_regeneration;
                    expect_exact(field, f, what + " batch " + std::to_string(batch));
                }
                if (margin == 1) {
                    EXPECT_TRUE(fell_back) << what << ": a margin of 1 never overflowed";
                }
            }
        }
    }
}

// An edit with more voxel changes than the block passes have work-items (a 24^3 cube, 13 824
// changes, over a cap box of 5^3 blocks: 8 000 work-items on the GPU layout, 1 600 on the
// CPU's) must still write every change, placing and erasing, in both layouts and for packed32
// (whose place edits scatter before inc_place).
TEST(Incremental, EditsWithMoreChangesThanWorkItems) {
    for (const ocl::Layout layout : {ocl::Layout::cpu, ocl::Layout::gpu}) {
        for (Format f : {Format::u16, Format::packed32}) {
            const World start = scene_floor_spheres(Dims{64, 64, 64}, 4, 3);
            auto o = exact_options(f);
            o.layout = layout;
            ocl::IncrementalField field(pocl(), start, Palette(), o, 1);
            Brush cube;
            cube.shape = BrushShape::cube;
            cube.centre = {20, 20, 20};  // voxels 8..32: three blocks per axis
            cube.radius = 12;
            cube.material = 77;
            const std::string what = std::string(layout == ocl::Layout::cpu ? "cpu" : "gpu") +
                                     " layout, " + to_string(f);
            for (const BrushOp op : {BrushOp::place, BrushOp::erase}) {
                cube.op = op;
                const auto stats = field.apply({cube});
                ASSERT_EQ(stats.edits.size(), 1u);
                EXPECT_GE(stats.edits[0].changes.size(), 10000u) << what;
                std::vector<std::uint8_t> got(start.size());
                pocl().queue().enqueueReadBuffer(field.voxels_buffer(), CL_TRUE, 0, got.size(),
                                                 got.data());
                ASSERT_EQ(got, field.world().voxels()) << what;
                expect_exact(field, f, what + (op == BrushOp::place ? " placed" : " erased"));
            }
        }
    }
}

TEST(Incremental, EraseEverythingThenFillEverything) {
    const World start = scene_floor_spheres(Dims{24, 20, 16}, 3, 4);
    ocl::IncrementalField field(pocl(), start, Palette(), exact_options(Format::u32));
    Brush all;
    all.shape = BrushShape::cube;
    all.centre = {12, 10, 8};
    all.radius = 40;
    all.op = BrushOp::erase;
    field.apply({all});
    expect_exact(field, Format::u32, "erased everything");
    Brush one;
    one.centre = {3, 4, 5};
    one.radius = 0;
    field.apply({one});
    expect_exact(field, Format::u32, "one voxel in an empty world");
    all.op = BrushOp::place;
    field.apply({all});
    expect_exact(field, Format::u32, "filled everything");
    all.op = BrushOp::erase;
    all.radius = 3;
    field.apply({all});
    expect_exact(field, Format::u32, "a hole in a full world");
}

TEST(Incremental, BatchesSpanningTheWorldRegenerateAndStayExact) {
    // Changes scattered over the whole world (as a step of falling sand makes) take one full
    // regeneration; a small edit after it is incremental again. Unbounded L1 (the global sweeps),
    // bounded L1 and L2 (the separable engine).
    for (const auto& [metric, bound] : {std::pair{Metric::manhattan, std::optional<double>()},
                                        std::pair{Metric::manhattan, std::optional<double>(6)},
                                        std::pair{Metric::euclidean, std::optional<double>()}}) {
        ocl::GeneratorOptions o;
        o.metric = metric;
        o.max_distance = bound;
        o.format = metric == Metric::euclidean ? Format::f32 : Format::u16;
        const World start = scene_floor_spheres(Dims{36, 28, 32}, 5, 6);
        ocl::IncrementalField field(pocl(), start, Palette(), o);
        std::mt19937_64 rng(17);
        VoxelChanges scattered;
        std::vector<bool> taken(start.size());
        for (int i = 0; i < 400; ++i) {
            const std::size_t v = rng() % start.size();
            if (taken[v]) {
                continue;
            }
            taken[v] = true;
            const std::uint8_t was = start.voxels()[v];
            scattered.push_back({v, was, static_cast<std::uint8_t>(was != 0 ? 0 : 1 + rng() % 9)});
        }
        const std::string what = to_string(metric) + (bound ? " bounded" : "");
        // Against the CPU reference (a regeneration by the same kernels would share their
        // mistakes): L1 capped at floor(D), or the exact L2 distance.
        auto expect_fresh = [&](const std::string& when) {
            const World& w = field.world();
            std::vector<std::uint8_t> want;
            if (metric == Metric::manhattan) {
                std::vector<std::uint32_t> d = reference_manhattan(w);
                for (std::uint32_t& v : d) {
                    v = bound ? std::min<std::uint32_t>(v, static_cast<std::uint32_t>(*bound)) : v;
                }
                want = encode_field(d, w, Palette(), o.format);
            } else {
                want = encode_real_field(reference_distance(w, metric, Spacing{}), w, Palette(),
                                         o.format);
            }
            const std::string diff =
                test::first_difference(field.read(), want, o.format, start.dims());
            EXPECT_TRUE(diff.empty()) << what << " " << when << ": " << diff;
        };
        const ocl::UpdateStats big = field.apply_changes(scattered);
        EXPECT_TRUE(big.full_regeneration) << what;
        expect_fresh("after the scattered batch");
        Brush small;
        small.centre = {10, 12, 9};
        small.radius = 2;
        const ocl::UpdateStats next = field.apply({small});
        EXPECT_FALSE(next.full_regeneration) << what;
        expect_fresh("after a small edit");
    }
}

TEST(Incremental, OverlappingPlacesInOneBatchStayExact) {
    // Batches of place-only edits (inc_place: each edit's box field is the world as that edit
    // left it, later edits of the batch undone) that overlap each other, in both layouts and
    // in u8 (saturating) and packed32 (colours): exact after every batch, and every voxel
    // whose distance changed lies in a reported region.
    for (const ocl::Layout layout : {ocl::Layout::cpu, ocl::Layout::gpu}) {
        for (const Format f : {Format::u8, Format::packed32}) {
            std::mt19937_64 rng(2718);
            const World start = scene_floor_spheres(Dims{45, 38, 33}, 3, 5);
            auto o = exact_options(f);
            o.layout = layout;
            ocl::IncrementalField field(pocl(), start, Palette(), o);
            for (int batch = 0; batch < 40; ++batch) {
                const std::vector<std::uint8_t> before = field.read();
                std::vector<Brush> brushes;
                const Brush first = random_brush(rng, start.dims(), 7);
                for (int i = 0; i < 1 + batch % 4; ++i) {
                    Brush b = first;
                    b.op = BrushOp::place;
                    b.centre = {first.centre.x + static_cast<std::int64_t>(rng() % 7) - 3,
                                first.centre.y + static_cast<std::int64_t>(rng() % 7) - 3,
                                first.centre.z + static_cast<std::int64_t>(rng() % 7) - 3};
                    b.material = static_cast<std::uint8_t>(1 + rng() % 255);
                    brushes.push_back(b);
                }
                const auto stats = field.apply(brushes);
                const std::string what = std::string(layout == ocl::Layout::cpu ? "cpu" : "gpu") +
                                         " " + to_string(f) + " batch " + std::to_string(batch);
                expect_exact(field, f, what);
                const std::vector<std::uint8_t> after = field.read();
                const Dims d = start.dims();
                for (std::size_t i = 0; i < start.size(); ++i) {
                    if (decode_distance(after, f, i) == decode_distance(before, f, i)) {
                        continue;
                    }
                    const Int3 p{static_cast<std::int64_t>(i % d.x),
                                 static_cast<std::int64_t>(i / d.x % d.y),
                                 static_cast<std::int64_t>(i / d.x / d.y)};
                    bool inside = stats.full_regeneration;
                    for (const Box& r : stats.regions) {
                        inside |= p.x >= r.min.x && p.x < r.max.x && p.y >= r.min.y &&
                                  p.y < r.max.y && p.z >= r.min.z && p.z < r.max.z;
                    }
                    ASSERT_TRUE(inside) << what << ": changed outside the regions at " << p.x << ","
                                        << p.y << "," << p.z;
                }
            }
        }
    }
}

TEST(Incremental, WritesNothingOutsideItsRegions) {
    std::mt19937_64 rng(5);
    const World start = scene_floor_spheres(Dims{40, 32, 40}, 9, 8);
    ocl::IncrementalField field(pocl(), start, Palette(), exact_options(Format::u16));
    const std::uint16_t poison = 0xBEEF;
    int checked = 0;
    for (int batch = 0; batch < 40; ++batch) {
        const auto before = field.read();
        pocl().queue().enqueueFillBuffer(field.field_buffer(), poison, 0, before.size());
        const auto stats = field.apply({random_brush(rng, start.dims(), 5)});
        const auto after = field.read();
        const auto want =
            encode_field(reference_manhattan(field.world()), field.world(), Palette(), Format::u16);
        const Dims d = start.dims();
        for (std::uint32_t z = 0; z < d.z; ++z) {
            for (std::uint32_t y = 0; y < d.y; ++y) {
                for (std::uint32_t x = 0; x < d.x; ++x) {
                    const std::size_t i = d.index(x, y, z);
                    const auto got = decode_distance(after, Format::u16, i);
                    bool inside = stats.full_regeneration;
                    for (const Box& b : stats.regions) {
                        inside |= x >= b.min.x && x < b.max.x && y >= b.min.y && y < b.max.y &&
                                  z >= b.min.z && z < b.max.z;
                    }
                    if (!inside) {
                        ASSERT_EQ(got, poison) << "written outside the regions at " << x << "," << y
                                               << "," << z << " batch " << batch;
                    } else if (got != poison) {
                        ASSERT_EQ(got, decode_distance(want, Format::u16, i));
                    }
                }
            }
        }
        // Restore the real field for the next batch.
        pocl().queue().enqueueWriteBuffer(field.field_buffer(), CL_TRUE, 0, want.size(),
                                          want.data());
        checked += stats.regions.empty() ? 0 : 1;
    }
    EXPECT_GE(checked, 10);
}

TEST(Incremental, FarApartEditsOfOneBatchStayLocalInTheSeparableEngine) {
    // Two small strokes at opposite corners of the world in one batch: each is updated by
    // itself, not their hull (the whole world) and not a full regeneration.
    for (const Metric metric : {Metric::euclidean, Metric::chebyshev}) {
        ocl::GeneratorOptions o;
        o.metric = metric;
        o.format = metric == Metric::euclidean ? Format::f32 : Format::u16;
        o.layout = ocl::Layout::gpu;  // chebyshev takes the separable engine in this layout
        const World start = scene_floor_spheres(Dims{48, 40, 44}, 3, 4);
        ocl::IncrementalField field(pocl(), start, Palette(), o);
        const std::vector<Brush> batch = {{BrushOp::place, BrushShape::sphere, {4, 30, 4}, 2, 3},
                                          {BrushOp::place, BrushShape::cube, {43, 34, 39}, 2, 5},
                                          {BrushOp::erase, BrushShape::sphere, {5, 31, 5}, 1, 0}};
        const ocl::UpdateStats u = field.apply(batch);
        // Their hull spans more than an eighth of the world: merged, they were regenerated.
        EXPECT_FALSE(u.full_regeneration) << to_string(metric);
        EXPECT_EQ(u.regions.size(), 3u) << to_string(metric);  // one update per run of edits
        World want = start;
        for (const Brush& b : batch) {
            apply_brush(want, b);
        }
        ASSERT_EQ(field.world().voxels(), want.voxels());
        const auto ref = encode_real_field(reference_distance(want, metric, Spacing{}), want,
                                           Palette(), o.format);
        EXPECT_EQ(test::first_difference(field.read(), ref, o.format, want.dims()), "")
            << to_string(metric);
    }
}

TEST(Incremental, ChunkLocalRecomputesExactlyTheChunksHoldingAChange) {
    // A sphere of radius 3 at (5, 5, 5) in chunks of 8: its box [2, 9)^3 overlaps 8 chunks, its
    // voxels lie in 4 ((8, 5, 5), (5, 8, 5) and (5, 5, 8) cross into the next chunk along one
    // axis each; no voxel reaches two). Then two cubes whose boxes a 25% slack would merge
    // into a hull over a chunk neither touches.
    ocl::GeneratorOptions o;
    o.algorithm = ocl::Algorithm::fim;
    o.format = Format::u16;
    o.chunk = 8;
    const World start(Dims{24, 24, 24});
    o = ocl::resolve_options(o, start.dims());
    ocl::IncrementalField field(pocl(), start, Palette(), o);
    auto chunks_of = [](const ocl::UpdateStats& u) {
        std::vector<Int3> c;
        for (const Box& b : u.regions) {
            c.push_back({b.min.x / 8, b.min.y / 8, b.min.z / 8});
        }
        return c;
    };
    const ocl::UpdateStats sphere =
        field.apply({{BrushOp::place, BrushShape::sphere, {5, 5, 5}, 3, 2}});
    EXPECT_EQ(chunks_of(sphere), (std::vector<Int3>{{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}}));
    EXPECT_EQ(sphere.voxels_recomputed, 4u * 512u);
    const ocl::UpdateStats cubes =
        field.apply({{BrushOp::place, BrushShape::cube, {5, 6, 5 + 8}, 2, 3},
                     {BrushOp::place, BrushShape::cube, {10, 5, 5 + 8}, 2, 4}});
    EXPECT_EQ(chunks_of(cubes), (std::vector<Int3>{{0, 0, 1}, {1, 0, 1}, {0, 1, 1}}));
    const auto want = ocl::generate(pocl(), field.world(), Palette(), o).bytes;
    EXPECT_EQ(test::first_difference(field.read(), want, o.format, start.dims()), "");
}

TEST(Incremental, ChunkLocalWritesOnlyDirtyChunks) {
    std::mt19937_64 rng(8);
    const World start = scene_floor_spheres(Dims{32, 24, 40}, 4, 6);
    ocl::GeneratorOptions o;
    o.algorithm = ocl::Algorithm::fim;
    o.format = Format::u16;
    o.chunk = 8;
    o = ocl::resolve_options(o, start.dims());
    ocl::IncrementalField field(pocl(), start, Palette(), o);
    const std::uint16_t poison = 0xBEEF;
    const Dims d = start.dims();
    for (int batch = 0; batch < 20; ++batch) {
        const auto bytes = 2 * start.size();
        pocl().queue().enqueueFillBuffer(field.field_buffer(), poison, 0, bytes);
        const auto stats = field.apply({random_brush(rng, d, 4)});
        const auto after = field.read();
        for (std::uint32_t z = 0; z < d.z; ++z) {
            for (std::uint32_t y = 0; y < d.y; ++y) {
                for (std::uint32_t x = 0; x < d.x; ++x) {
                    bool inside = false;
                    for (const Box& b : stats.regions) {
                        inside |= x >= b.min.x && x < b.max.x && y >= b.min.y && y < b.max.y &&
                                  z >= b.min.z && z < b.max.z;
                    }
                    if (!inside) {
                        ASSERT_EQ(decode_distance(after, Format::u16, d.index(x, y, z)), poison)
                            << "written outside the dirty chunks, batch " << batch;
                    }
                }
            }
        }
        field.regenerate();  // the real field again for the next batch
    }
}

TEST(Incremental, GlobalDissertationAlgorithmsNeedChunks) {
    ocl::GeneratorOptions o;
    o.algorithm = ocl::Algorithm::jfa;
    o = ocl::resolve_options(o, Dims{16, 16, 16});
    EXPECT_THROW(ocl::IncrementalField(pocl(), World(Dims{16, 16, 16}), Palette(), o), InputError);
}

TEST(Incremental, ChunkLocalAlgorithmsEqualTheirFullRegeneration) {
    std::mt19937_64 rng(31);
    const World start = scene_floor_spheres(Dims{40, 24, 36}, 13, 8);
    for (const std::string& name : ocl::algorithm_names()) {
        const ocl::Algorithm a = ocl::parse_algorithm(name);
        if (a == ocl::Algorithm::exact) {
            continue;
        }
        for (std::uint32_t chunk : {4u, 8u}) {
            ocl::GeneratorOptions o;
            o.algorithm = a;
            o.format = a == ocl::Algorithm::monolithic ? Format::packed32 : Format::u16;
            o.chunk = chunk;
            if (a == ocl::Algorithm::lod) {
                o.focus = Focus{{2, 1, 2}, 1};  // a partial focus: JFA-only chunks too
            }
            o = ocl::resolve_options(o, start.dims());
            ocl::IncrementalField field(pocl(), start, Palette(), o);
            for (int batch = 0; batch < 12; ++batch) {
                std::vector<Brush> brushes = {random_brush(rng, start.dims(), 6)};
                if (batch % 4 == 0) {
                    brushes.push_back(random_brush(rng, start.dims(), 6));
                }
                const auto stats = field.apply(brushes);
                const auto want = ocl::generate(pocl(), field.world(), Palette(), o).bytes;
                const std::string diff =
                    test::first_difference(field.read(), want, o.format, start.dims());
                ASSERT_TRUE(diff.empty())
                    << name << " chunk " << chunk << " batch " << batch << ": " << diff;
                // Only whole chunks holding a changed voxel are recomputed.
                for (const Box& b : stats.regions) {
                    EXPECT_LE(b.max.x - b.min.x, std::int64_t{chunk});
                    EXPECT_EQ(b.min.x % chunk, 0);
                }
                EXPECT_LE(stats.regions.size(), 2u * 8u * 27u);
            }
        }
    }
}

TEST(Incremental, UndoAndRedoOfStrokesStayExact) {
    // Strokes recorded by the viewer's UndoStack, undone and redone through apply_changes:
    // each is one edit, and the field equals a fresh one every time.
    std::mt19937_64 rng(404);
    const World start = scene_floor_spheres(Dims{40, 28, 36}, 21, 9);
    ocl::GeneratorOptions chunked;
    chunked.algorithm = ocl::Algorithm::fim;
    chunked.chunk = 8;
    for (ocl::GeneratorOptions o : {exact_options(Format::packed32), chunked}) {
        o = ocl::resolve_options(o, start.dims());
        ocl::IncrementalField field(pocl(), start, Palette(), o);
        UndoStack undo;
        const auto check = [&](const std::string& what) {
            const auto want = ocl::generate(pocl(), field.world(), Palette(), o).bytes;
            const std::string diff =
                test::first_difference(field.read(), want, o.format, start.dims());
            ASSERT_TRUE(diff.empty()) << to_string(o.algorithm) << ", " << what << ": " << diff;
        };
        for (int stroke = 0; stroke < 6; ++stroke) {
            undo.begin_stroke();
            for (int i = 0; i < 3; ++i) {
                undo.record(field.apply({random_brush(rng, start.dims(), 7)}).edits.front());
            }
            undo.end_stroke();
        }
        const World edited = field.world();
        for (int i = 0; i < 6 && undo.can_undo(); ++i) {
            const ocl::UpdateStats s = field.apply_changes(undo.undo());
            ASSERT_EQ(s.edits.size(), 1u);
            check("undo " + std::to_string(i));
        }
        EXPECT_EQ(field.world().voxels(), start.voxels());
        while (undo.can_redo()) {
            field.apply_changes(undo.redo());
            check("redo");
        }
        EXPECT_EQ(field.world().voxels(), edited.voxels());
        // A change that does not match the world is refused, and nothing changes.
        const std::vector<std::uint8_t> before = field.read();
        const std::uint8_t v = field.world().voxels()[5];
        EXPECT_THROW(field.apply_changes({{5, static_cast<std::uint8_t>(v + 1), 0}}), InputError);
        EXPECT_EQ(field.world().voxels(), edited.voxels());
        EXPECT_EQ(field.read(), before);
    }
}

// The focus as a chunk box; empty without a focus.
Box focus_box(const ChunkGrid& grid, const std::optional<Focus>& focus) {
    return focus ? focus_chunks(grid, *focus) : Box{};
}

bool contains(const Box& b, const Int3& c) {
    return c.x >= b.min.x && c.x < b.max.x && c.y >= b.min.y && c.y < b.max.y && c.z >= b.min.z &&
           c.z < b.max.z;
}

// Moves the focus of `field` (whose focus is `from`) to `to` and checks: the recomputed
// regions are exactly the voxel boxes of the chunks in one focus box but not the other,
// nothing outside them is written, and the field equals a fresh one with the new focus.
// (Seed-propagating JFA under L1 has been exact on every world tried, so FIM after it
// rarely changes a value: the region and poison checks are what pin down the chunk set.)
void expect_focus_move(ocl::IncrementalField& field, ocl::GeneratorOptions o,
                       const std::optional<Focus>& from, const std::optional<Focus>& to,
                       const std::string& what) {
    const Dims d = field.world().dims();
    const ChunkGrid grid(d, o.chunk);
    const Box a = focus_box(grid, from), b = focus_box(grid, to);
    std::vector<Box> want_regions;
    const Dims n = grid.chunks();
    for (std::int64_t z = 0; z < n.z; ++z) {
        for (std::int64_t y = 0; y < n.y; ++y) {
            for (std::int64_t x = 0; x < n.x; ++x) {
                if (contains(a, {x, y, z}) != contains(b, {x, y, z})) {
                    want_regions.push_back(grid.voxels_of({x, y, z}));
                }
            }
        }
    }
    // Poison the field: what set_focus leaves alone must stay poison.
    const std::vector<std::uint8_t> before = field.read();
    const cl_uchar poison = 0xA5;
    pocl().queue().enqueueFillBuffer(field.field_buffer(), poison, 0, before.size());
    const ocl::UpdateStats stats = field.set_focus(to);
    std::vector<std::uint8_t> merged = field.read();

    ASSERT_EQ(stats.regions.size(), want_regions.size()) << what;
    std::uint64_t volume = 0;
    for (const Box& r : stats.regions) {
        EXPECT_NE(std::find(want_regions.begin(), want_regions.end(), r), want_regions.end())
            << what << ": recomputed a chunk whose focus membership did not change";
        EXPECT_EQ(std::count(stats.regions.begin(), stats.regions.end(), r), 1) << what;
        volume += static_cast<std::uint64_t>(r.volume());
    }
    EXPECT_EQ(stats.voxels_recomputed, volume) << what;
    EXPECT_GE(stats.update_ms, 0.0) << what;
    if (want_regions.empty()) {
        EXPECT_EQ(stats.voxels_recomputed, 0u) << what;
    }

    // Outside the regions: still poison; put the old bytes back there.
    const std::size_t es = element_size(o.format);
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                const Int3 v{x, y, z};
                bool inside = false;
                for (const Box& r : stats.regions) {
                    inside |= contains(r, v);
                }
                if (inside) {
                    continue;
                }
                const std::size_t i = d.index(x, y, z) * es;
                for (std::size_t k = 0; k < es; ++k) {
                    ASSERT_EQ(merged[i + k], poison) << what << ": written outside the changed "
                                                     << "chunks at " << x << "," << y << "," << z;
                    merged[i + k] = before[i + k];
                }
            }
        }
    }
    pocl().queue().enqueueWriteBuffer(field.field_buffer(), CL_TRUE, 0, merged.size(),
                                      merged.data());

    o.focus = to;
    ocl::IncrementalField fresh(pocl(), field.world(), Palette(), o);
    const std::string diff = test::first_difference(field.read(), fresh.read(), o.format, d);
    ASSERT_TRUE(diff.empty()) << what << ": " << diff;
}

TEST(Incremental, MovingTheFocusEqualsAFreshField) {
    std::mt19937_64 rng(2024);
    const Dims d{48, 40, 56};
    for (const double density : {0.002, 0.03, 0.25}) {
        const World start = scene_random(d, density, static_cast<std::uint64_t>(density * 1000));
        for (const ocl::Algorithm a : {ocl::Algorithm::lod, ocl::Algorithm::monolithic}) {
            for (const std::uint32_t chunk : {8u, 16u}) {
                ocl::GeneratorOptions o;
                o.algorithm = a;
                o.format = a == ocl::Algorithm::monolithic ? Format::packed32 : Format::u16;
                o.chunk = chunk;
                o = ocl::resolve_options(o, d);  // the default focus: the centre chunk, size 1
                ocl::IncrementalField field(pocl(), start, Palette(), o);
                const Dims n = ChunkGrid(d, chunk).chunks();
                const std::int64_t nx = n.x, ny = n.y, nz = n.z;
                const std::vector<std::optional<Focus>> moves = {
                    o.focus,                             // the same focus
                    Focus{{0, 0, 0}, 1},                 // a corner chunk
                    Focus{{nx - 1, ny - 1, nz - 1}, 0},  // the far corner, one chunk
                    Focus{{1, 1, 1}, 100},               // every chunk
                    Focus{{nx / 2, 0, nz - 1}, 100},     // every chunk again
                    std::nullopt,                        // no focus
                    std::nullopt,                        // still none
                    Focus{{nx - 1, 0, nz / 2}, 2},       // clipped at the faces
                    Focus{{nx - 1, 0, nz / 2}, 2},       // the same again
                    Focus{{nx / 2, ny / 2, nz / 2}, 1},  // overlapping the last one
                };
                std::optional<Focus> current = o.focus;
                for (std::size_t m = 0; m < moves.size(); ++m) {
                    const std::string what = ocl::to_string(a) + " chunk " + std::to_string(chunk) +
                                             " density " + std::to_string(density) + " move " +
                                             std::to_string(m);
                    expect_focus_move(field, o, current, moves[m], what);
                    current = moves[m];
                    if (m == 3) {
                        // An edit between moves: the next ones start from the edited world.
                        field.apply({random_brush(rng, d, 8)});
                    }
                }
                // A focus outside the grid or of negative size: InputError, focus unchanged.
                EXPECT_THROW(field.set_focus(Focus{{nx, 0, 0}, 1}), InputError);
                EXPECT_THROW(field.set_focus(Focus{{0, 0, 0}, -1}), InputError);
                const auto same = field.set_focus(current);
                EXPECT_EQ(same.voxels_recomputed, 0u);
                EXPECT_TRUE(same.regions.empty());
            }
        }
    }
}

TEST(Incremental, OnlyLodAndMonolithicHaveAFocus) {
    const World start = scene_floor_spheres(Dims{32, 24, 16}, 2, 4);
    ocl::IncrementalField exact(pocl(), start, Palette(), exact_options(Format::u16));
    EXPECT_THROW(exact.set_focus(Focus{{0, 0, 0}, 1}), InputError);
    EXPECT_THROW(exact.set_focus(std::nullopt), InputError);
    ocl::GeneratorOptions o;
    o.algorithm = ocl::Algorithm::fim;
    o.chunk = 8;
    o = ocl::resolve_options(o, start.dims());
    ocl::IncrementalField fim(pocl(), start, Palette(), o);
    EXPECT_THROW(fim.set_focus(Focus{{0, 0, 0}, 1}), InputError);
    EXPECT_THROW(fim.set_focus(std::nullopt), InputError);
}

TEST(Incremental, VoxelsBufferFollowsTheWorld) {
    std::mt19937_64 rng(99);
    const World start = scene_floor_spheres(Dims{40, 24, 32}, 6, 6);
    ocl::GeneratorOptions chunked;
    chunked.algorithm = ocl::Algorithm::lod;
    chunked.chunk = 8;
    chunked = ocl::resolve_options(chunked, start.dims());
    auto gpu_packed = exact_options(Format::packed32);
    gpu_packed.layout = ocl::Layout::gpu;
    for (const auto& o : {exact_options(Format::u16), gpu_packed, chunked}) {
        ocl::IncrementalField field(pocl(), start, Palette(), o);
        for (int batch = 0; batch < 10; ++batch) {
            field.apply({random_brush(rng, start.dims(), 6), random_brush(rng, start.dims(), 3)});
            std::vector<std::uint8_t> got(start.size());
            pocl().queue().enqueueReadBuffer(field.voxels_buffer(), CL_TRUE, 0, got.size(),
                                             got.data());
            ASSERT_EQ(got, field.world().voxels())
                << ocl::to_string(o.algorithm) << " batch " << batch;
        }
    }
}

TEST(Incremental, DeviceFailuresLeaveWorldAndFieldAsBefore) {
    // A device failure in the middle of an update (the test seam throws ClError after the
    // update's commands were enqueued: the device voxels and part of the field already
    // written) leaves the world, the device voxels and the field as before the call, and the
    // next edit is exact. Every engine: the L1 sweeps (unbounded and bounded), the separable
    // engine (Euclidean), chunk-local; and a focus move.
    const World start = scene_floor_spheres(Dims{40, 32, 36}, 7, 7);
    ocl::GeneratorOptions bounded = exact_options(Format::u16);
    bounded.max_distance = 5.0;
    ocl::GeneratorOptions euclidean = exact_options(Format::f32);
    euclidean.metric = Metric::euclidean;
    ocl::GeneratorOptions chunked;
    chunked.algorithm = ocl::Algorithm::lod;
    chunked.chunk = 8;
    for (ocl::GeneratorOptions o : {exact_options(Format::packed32), bounded, euclidean, chunked}) {
        o = ocl::resolve_options(o, start.dims());
        const std::string what =
            to_string(o.algorithm) + " " + to_string(o.metric) + (o.max_distance ? " bounded" : "");
        ocl::IncrementalField field(pocl(), start, Palette(), o);
        std::mt19937_64 rng(606);
        const auto device_voxels = [&] {
            std::vector<std::uint8_t> got(start.size());
            pocl().queue().enqueueReadBuffer(field.voxels_buffer(), CL_TRUE, 0, got.size(),
                                             got.data());
            return got;
        };
        const auto expect_fresh = [&](const std::string& when) {
            const auto want = ocl::generate(pocl(), field.world(), Palette(), o).bytes;
            const std::string diff =
                test::first_difference(field.read(), want, o.format, start.dims());
            EXPECT_TRUE(diff.empty()) << what << " " << when << ": " << diff;
        };
        Brush ball;
        ball.centre = {20, 6, 18};
        ball.radius = 6;
        ball.material = 9;
        for (const BrushOp op : {BrushOp::place, BrushOp::erase}) {
            field.apply({random_brush(rng, start.dims(), 5)});
            const std::vector<std::uint8_t> world_before = field.world().voxels();
            const std::vector<std::uint8_t> field_before = field.read();
            ball.op = op;
            field.fail_next_update_for_testing();
            EXPECT_THROW(field.apply({random_brush(rng, start.dims(), 4), ball}), ocl::ClError)
                << what;
            EXPECT_EQ(field.world().voxels(), world_before) << what;
            EXPECT_EQ(device_voxels(), world_before) << what;
            EXPECT_EQ(field.read(), field_before) << what;
            // The same through apply_changes (an undo's path).
            World edited = field.world();
            const VoxelChanges changes = apply_brush(edited, ball).changes;
            field.fail_next_update_for_testing();
            EXPECT_THROW(field.apply_changes(changes), ocl::ClError) << what;
            EXPECT_EQ(field.world().voxels(), world_before) << what;
            EXPECT_EQ(device_voxels(), world_before) << what;
            EXPECT_EQ(field.read(), field_before) << what;
            // The next edits update from the restored state, exactly.
            field.apply({ball});
            EXPECT_EQ(field.world().voxels(), edited.voxels()) << what;
            expect_fresh("after the failed edits");
        }
        if (o.algorithm == ocl::Algorithm::lod) {
            const std::vector<std::uint8_t> field_before = field.read();
            field.fail_next_update_for_testing();
            EXPECT_THROW(field.set_focus(Focus{{0, 0, 0}, 1}), ocl::ClError);
            EXPECT_EQ(field.read(), field_before) << "a failed focus move";
            field.apply({random_brush(rng, start.dims(), 5)});
            expect_fresh("after a failed focus move");  // still the old focus
            field.set_focus(Focus{{0, 0, 0}, 1});
            o.focus = Focus{{0, 0, 0}, 1};
            expect_fresh("after the focus moved");
        }
    }
}

}  // namespace
}  // namespace voxfield
