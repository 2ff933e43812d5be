// Bounded fields of sparse worlds (cl/sparse_field.hpp) on PoCL, in both kernel layouts:
// equal voxel for voxel to the dense bounded field of the same world (the dense generator with
// max_distance), every metric, spacing, signed, formats, bounds up to beyond a tile; coarse
// distances are lower bounds; updates after random brushes equal recomputation; the Manhattan
// sweep equals run() by blocks.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "cl_test_util.hpp"
#include "voxfield/cl/sparse_field.hpp"
#include "voxfield/core/brush.hpp"
#include "voxfield/core/clock.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/reference.hpp"

namespace voxfield {
namespace {

using ocl::Layout;
using test::pocl;

// Solid boxes scattered in empty space (empty tiles between solid ones), plus noise.
World blob_world(Dims d, int blobs, double noise, std::mt19937& rng) {
    World w(d);
    for (int b = 0; b < blobs; ++b) {
        const auto cx = std::uniform_int_distribution<std::uint32_t>(0, d.x - 1)(rng);
        const auto cy = std::uniform_int_distribution<std::uint32_t>(0, d.y - 1)(rng);
        const auto cz = std::uniform_int_distribution<std::uint32_t>(0, d.z - 1)(rng);
        const auto r = std::uniform_int_distribution<std::uint32_t>(0, 9)(rng);
        const auto m = static_cast<std::uint8_t>(std::uniform_int_distribution<int>(1, 255)(rng));
        for (std::uint32_t z = cz > r ? cz - r : 0; z <= std::min(d.z - 1, cz + r); ++z) {
            for (std::uint32_t y = cy > r ? cy - r : 0; y <= std::min(d.y - 1, cy + r); ++y) {
                for (std::uint32_t x = cx > r ? cx - r : 0; x <= std::min(d.x - 1, cx + r); ++x) {
                    w.set(x, y, z, m);
                }
            }
        }
    }
    std::bernoulli_distribution solid(noise);
    for (auto& v : w.voxels()) {
        if (solid(rng)) {
            v = 7;
        }
    }
    return w;
}

struct Case {
    Metric metric = Metric::manhattan;
    Spacing spacing;
    bool signed_field = false;
    Format format = Format::u16;
    Layout layout = Layout::cpu;
    double bound = 16;
};

std::string describe(const Case& c, Dims d) {
    return to_string(c.metric) + " spacing " + c.spacing.to_string() +
           (c.signed_field ? " signed" : "") + " " + to_string(c.format) + " layout " +
           (c.layout == Layout::cpu ? "cpu" : "gpu") + " D " + std::to_string(c.bound) + " world " +
           d.to_string();
}

ocl::GeneratorOptions options_of(const Case& c) {
    ocl::GeneratorOptions o;
    o.metric = c.metric;
    o.spacing = c.spacing;
    o.signed_field = c.signed_field;
    o.format = c.format;
    o.layout = c.layout;
    o.max_distance = c.bound;
    return ocl::resolve_sparse_options(o, true);
}

std::vector<std::uint8_t> dense_field(const World& w, const Palette& p, const Case& c) {
    return ocl::generate(pocl(), w, p, options_of(c)).bytes;
}

// Byte for byte; on a difference, where and both values.
void expect_same(const std::vector<std::uint8_t>& got, const std::vector<std::uint8_t>& want,
                 const Case& c, Dims d, const std::string& what) {
    ASSERT_EQ(got.size(), want.size()) << what;
    if (got == want) {
        return;
    }
    const std::size_t e = element_size(c.format);
    std::size_t i = 0;
    while (std::equal(got.begin() + static_cast<long>(i * e),
                      got.begin() + static_cast<long>((i + 1) * e),
                      want.begin() + static_cast<long>(i * e))) {
        ++i;
    }
    FAIL() << what << " " << describe(c, d) << ": first difference at voxel (" << i % d.x << ","
           << i / d.x % d.y << "," << i / d.x / d.y << "): got " << decode_value(got, c.format, i)
           << ", want " << decode_value(want, c.format, i);
}

// Every node's coarse distance is the least of the field's distances to a solid (the value,
// its positive part when signed) over its voxels in the world, so at most each of them; a
// tile's is at most its nodes'.
void expect_coarse_bounds(ocl::SparseField& f, const std::vector<std::uint8_t>& field,
                          const Case& c, Dims d) {
    const Int3 nodes{(d.x + 15) / 16, (d.y + 15) / 16, (d.z + 15) / 16};
    std::vector<double> node_min(static_cast<std::size_t>(nodes.x * nodes.y * nodes.z),
                                 std::numeric_limits<double>::infinity());
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                const double v = std::max(0.0, decode_value(field, c.format, d.index(x, y, z)));
                double& m = node_min[static_cast<std::size_t>(
                    (z / 16 * nodes.y + y / 16) * nodes.x + x / 16)];
                m = std::min(m, v);
            }
        }
    }
    for (std::int64_t z = 0; z < nodes.z; ++z) {
        for (std::int64_t y = 0; y < nodes.y; ++y) {
            for (std::int64_t x = 0; x < nodes.x; ++x) {
                const double m =
                    node_min[static_cast<std::size_t>((z * nodes.y + y) * nodes.x + x)];
                const double coarse = f.coarse_node(x, y, z);
                // Tight: the node's least value (one float ulp lower in float formats).
                const double want =
                    c.format == Format::f32
                        ? static_cast<double>(std::nextafter(static_cast<float>(m), 0.0f))
                    : c.format == Format::f64 ? std::nextafter(m, 0.0)
                                              : m;
                ASSERT_LE(coarse, m);
                ASSERT_EQ(coarse, want)
                    << "node " << x << "," << y << "," << z << " " << describe(c, d);
                ASSERT_LE(f.coarse_tile(x / 4, y / 4, z / 4), coarse);
            }
        }
    }
}

void check_case(const World& w, const Case& c, bool coarse = false) {
    const Palette p = Palette::magicavoxel_default();
    const SparseWorld s = SparseWorld::from_dense(w);
    ocl::SparseField f(pocl(), s, p, options_of(c));
    f.run();
    const auto got = f.read_dense();
    expect_same(got, dense_field(w, p, c), c, w.dims(), "full field");
    if (coarse) {
        expect_coarse_bounds(f, got, c, w.dims());
    }
}

const Metric kMetrics[] = {Metric::manhattan, Metric::chebyshev, Metric::euclidean};
const Layout kLayouts[] = {Layout::cpu, Layout::gpu};

TEST(SparseField, EqualsTheDenseBoundedFieldEveryMetricSignedAndLayout) {
    std::mt19937 rng(21);
    const Dims sizes[] = {{100, 50, 70}, {64, 64, 64}, {65, 1, 129}, {150, 20, 40}};
    int i = 0;
    for (const Metric m : kMetrics) {
        for (const bool sgn : {false, true}) {
            for (const Layout layout : kLayouts) {
                for (const double bound : {3.0, 9.5, 16.0}) {
                    const Dims d = sizes[i++ % 4];
                    Case c;
                    c.metric = m;
                    c.signed_field = sgn;
                    c.layout = layout;
                    c.bound = bound;
                    c.format = ocl::default_format(m, c.spacing, sgn);
                    SCOPED_TRACE(describe(c, d));
                    check_case(blob_world(d, 10, 0.0005, rng), c, bound == 16.0);
                }
            }
        }
    }
}

TEST(SparseField, EveryFormat) {
    std::mt19937 rng(22);
    const Dims d{100, 40, 70};
    const World w = blob_world(d, 8, 0.001, rng);
    for (const Format f : {Format::u8, Format::u16, Format::u32, Format::packed32, Format::i8,
                           Format::i16, Format::i32, Format::f32, Format::f64}) {
        for (const bool sgn : {false, true}) {
            if (sgn && !holds_sign(f)) {
                continue;
            }
            Case c;
            c.metric = f == Format::f64 ? Metric::euclidean : Metric::manhattan;
            c.signed_field = sgn;
            c.format = f;
            c.bound = f == Format::i8 || f == Format::u8 || f == Format::packed32 ? 12 : 20.5;
            SCOPED_TRACE(describe(c, d));
            check_case(w, c, true);
        }
    }
}

TEST(SparseField, SpacingAndBoundsBeyondATile) {
    std::mt19937 rng(23);
    struct Sc {
        Spacing s;
        double bound;
    };
    // Halos of ceil(D / spacing) voxels: D > 64 gathers from tiles two away.
    const Sc scs[] = {{{1, 1, 1}, 70}, {{0.5, 1, 2}, 20}, {{1.5, 0.75, 1}, 15}, {{1, 1, 1}, 130}};
    int i = 0;
    for (const Sc& sc : scs) {
        const Metric m = kMetrics[i % 3];
        Case c;
        c.metric = m;
        c.spacing = sc.s;
        c.bound = sc.bound;
        c.signed_field = i % 2 == 1;
        c.layout = kLayouts[i % 2];
        c.format = ocl::default_format(m, c.spacing, c.signed_field);
        const Dims d = i == 0 ? Dims{300, 20, 70} : i == 3 ? Dims{150, 10, 30} : Dims{100, 40, 70};
        ++i;
        SCOPED_TRACE(describe(c, d));
        check_case(blob_world(d, 4, 0.0, rng), c, true);
    }
}

TEST(SparseField, EmptyFullAndSingleVoxelWorlds) {
    const Palette p = Palette::magicavoxel_default();
    for (const bool sgn : {false, true}) {
        Case c;
        c.signed_field = sgn;
        c.format = sgn ? Format::i16 : Format::u16;
        for (const Dims d : {Dims{1, 1, 1}, Dims{70, 3, 130}}) {
            SCOPED_TRACE(describe(c, d));
            check_case(World(d), c, true);
            World full(d);
            std::fill(full.voxels().begin(), full.voxels().end(), std::uint8_t{3});
            check_case(full, c, true);
            World one(d);
            one.set(d.x - 1, 0, d.z / 2, 5);
            check_case(one, c, true);
        }
    }
    // Deep solid: constant tiles, not computed (unsigned: full tiles, 0; signed: full tiles
    // with a full halo inside the world, -D: the centre one).
    World deep(Dims{192, 192, 192});
    std::fill(deep.voxels().begin(), deep.voxels().end(), std::uint8_t{2});
    for (const int variant : {0, 1, 2}) {
        Case c;
        c.signed_field = variant == 1;
        c.format = c.signed_field ? Format::i16 : Format::u16;
        c.bound = 5;
        if (variant == 2) {
            deep.set(0, 0, 0, 0);
        }
        const SparseWorld s = SparseWorld::from_dense(deep);
        ocl::SparseField f(pocl(), s, p, options_of(c));
        f.run();
        EXPECT_EQ(f.dense_tiles(), variant == 0 ? 0u : variant == 1 ? 26u : 1u);
        const auto got = f.read_dense();
        expect_same(got, dense_field(deep, p, c), c, deep.dims(), "deep solid");
        expect_coarse_bounds(f, got, c, deep.dims());
    }
}

// run()'s Manhattan sweep (1-D passes in the field tiles, neighbours read while rewritten)
// against the dense bounded field and against run() by blocks: signed or not, formats, bounds
// up to a whole tile of halo (and just beyond, where run() takes blocks), full tiles beside
// empty ones, tiles cut by the world's edge, and whole runs after device edits (trees in
// slots).
TEST(SparseField, ManhattanSweepEqualsBlocksAndTheDenseField) {
    std::mt19937 rng(27);
    const Palette p = Palette::magicavoxel_default();
    // The widest: tiles enough for run() to find the field tiles on two threads.
    const Dims sizes[] = {{130, 70, 200}, {64, 64, 64}, {1, 129, 65}, {200, 3, 5}, {700, 20, 700}};
    const Format formats[] = {Format::u8, Format::u16, Format::u32, Format::i16, Format::f32};
    const Format signed_formats[] = {Format::i8, Format::i16, Format::i32, Format::f32};
    const double bounds[] = {1, 2.5, 16, 64, 64.5};
    int i = 0;
    for (const Dims d : sizes) {
        World w = blob_world(d, 6, 0.0003, rng);
        if (d.x >= 128 && d.z >= 128) {
            for (std::uint32_t z = 64; z < 128; ++z) {  // a full tile beside empty ones
                for (std::uint32_t y = 0; y < std::min<std::uint32_t>(64, d.y); ++y) {
                    for (std::uint32_t x = 64; x < 128; ++x) {
                        w.set(x, y, z, 9);
                    }
                }
            }
        }
        for (const double bound : bounds) {
            Case c;
            c.signed_field = i % 3 == 1;
            c.format = c.signed_field ? signed_formats[i % 4] : formats[i % 5];
            c.layout = kLayouts[i % 2];
            c.bound = bound;
            ++i;
            SCOPED_TRACE(describe(c, d));
            const SparseWorld s = SparseWorld::from_dense(w);
            ocl::SparseField f(pocl(), s, p, options_of(c));
            EXPECT_EQ(f.run_method(), bound <= 64 ? "sweep" : "blocks");
            f.run();
            const auto got = f.read_dense();
            expect_same(got, dense_field(w, p, c), c, d, "sweep");
            if (bound == 16) {
                expect_coarse_bounds(f, got, c, d);
            }
            f.force_blocks(true);
            EXPECT_EQ(f.run_method(), "blocks");
            f.run();
            expect_same(f.read_dense(), got, c, d, "blocks vs sweep");
        }
    }
    // After edits on the device: the trees of edited tiles lie in slots.
    World w = blob_world(Dims{150, 60, 140}, 8, 0.0005, rng);
    for (const Layout layout : kLayouts) {
        SparseWorld s = SparseWorld::from_dense(w);
        Case c;
        c.layout = layout;
        c.signed_field = layout == Layout::gpu;
        c.format = c.signed_field ? Format::i16 : Format::u16;
        c.bound = 12;
        ocl::SparseField f(pocl(), s, p, options_of(c));
        f.run();
        for (int e = 0; e < 6; ++e) {
            Brush b;
            b.op = e % 3 == 1 ? BrushOp::erase : BrushOp::place;
            b.centre = {std::uniform_int_distribution<std::int64_t>(0, 149)(rng),
                        std::uniform_int_distribution<std::int64_t>(0, 59)(rng),
                        std::uniform_int_distribution<std::int64_t>(0, 139)(rng)};
            b.radius = std::uniform_int_distribution<std::int64_t>(2, 20)(rng);
            b.material = 4;
            apply_brush(w, b);
            f.apply_brush(b);
        }
        f.run();
        expect_same(f.read_dense(), dense_field(w, p, c), c, w.dims(), "sweep after edits");
    }
}

// The edit tests' k-th case of metric m, signed or not: the layouts in turn, a bound beyond a
// tile for k = 2 (9.5 otherwise), packed32 for unsigned Manhattan (the others' default format).
Case edit_case(Metric m, bool sgn, int k) {
    Case c;
    c.metric = m;
    c.signed_field = sgn;
    c.layout = kLayouts[k % 2];
    c.bound = k == 2 ? 70 : 9.5;
    c.format =
        m == Metric::manhattan && !sgn ? Format::packed32 : ocl::default_format(m, c.spacing, sgn);
    return c;
}

// A random brush: any operation and shape, centred up to 3 voxels outside `d`, radius up to
// `most`, any material.
Brush random_brush(const Dims& d, std::int64_t most, std::mt19937& rng) {
    Brush b;
    b.op = static_cast<BrushOp>(std::uniform_int_distribution<int>(0, 2)(rng));
    b.shape = static_cast<BrushShape>(std::uniform_int_distribution<int>(0, 1)(rng));
    b.centre = {std::uniform_int_distribution<std::int64_t>(-3, d.x + 3)(rng),
                std::uniform_int_distribution<std::int64_t>(-3, d.y + 3)(rng),
                std::uniform_int_distribution<std::int64_t>(-3, d.z + 3)(rng)};
    b.radius = std::uniform_int_distribution<std::int64_t>(0, most)(rng);
    b.material = static_cast<std::uint8_t>(std::uniform_int_distribution<int>(1, 255)(rng));
    return b;
}

TEST(SparseField, UpdatesAfterRandomBrushesEqualRecomputation) {
    std::mt19937 rng(24);
    const Palette p = Palette::magicavoxel_default();
    int k = 0;
    for (const Metric m : kMetrics) {
        for (const bool sgn : {false, true}) {
            const Dims d = k % 2 == 0 ? Dims{100, 50, 70} : Dims{64, 100, 65};
            const Case c = edit_case(m, sgn, k++);
            SCOPED_TRACE(describe(c, d));
            World w = blob_world(d, 6, 0.0002, rng);
            SparseWorld s = SparseWorld::from_dense(w);
            ocl::SparseField f(pocl(), s, p, options_of(c));
            f.run();
            for (int e = 0; e < 12; ++e) {
                const Brush b = random_brush(d, e == 5 ? 60 : 12, rng);
                apply_brush(w, b);
                const Box changed = apply_brush(s, b);
                const auto u = f.update(changed);
                if (!changed.empty()) {
                    EXPECT_GT(u.tiles, 0u);
                }
                const auto got = f.read_dense();
                expect_same(got, dense_field(w, p, c), c, d, "after edit " + std::to_string(e));
                if (e % 4 == 3) {
                    expect_coarse_bounds(f, got, c, d);
                }
            }
            ocl::SparseField fresh(pocl(), s, p, options_of(c));
            fresh.run();
            expect_same(fresh.read_dense(), f.read_dense(), c, d, "recomputed vs updated");
        }
    }
}

// A tile's stored 64-tree (nodes and materials from its bases).
SparseWorld::EncodedTile stored_tile(const SparseWorld& s, std::uint32_t t) {
    SparseWorld::EncodedTile e;
    const auto nb = static_cast<long>(s.node_bases()[t]);
    const auto mb = static_cast<long>(s.material_bases()[t]);
    e.masks.assign(s.node_masks().begin() + nb, s.node_masks().begin() + nb + s.node_counts()[t]);
    e.offsets.assign(s.node_offsets().begin() + nb,
                     s.node_offsets().begin() + nb + s.node_counts()[t]);
    e.materials.assign(s.materials().begin() + mb,
                       s.materials().begin() + mb + s.material_counts()[t]);
    return e;
}

TEST(SparseDeviceWorld, EncodesTilesBitForBitAsCore) {
    std::mt19937 rng(31);
    std::vector<std::vector<std::uint8_t>> tiles;
    tiles.emplace_back(kTileVoxels, 0);
    tiles.emplace_back(kTileVoxels, 255);
    for (const double density : {0.0001, 0.01, 0.2, 0.5, 0.9, 0.9999}) {
        std::bernoulli_distribution solid(density);
        std::uniform_int_distribution<int> material(1, 255);
        std::vector<std::uint8_t> t(kTileVoxels);
        for (auto& v : t) {
            v = solid(rng) ? static_cast<std::uint8_t>(material(rng)) : 0;
        }
        tiles.push_back(std::move(t));
    }
    for (std::uint32_t corner = 0; corner < 8; ++corner) {
        std::vector<std::uint8_t> t(kTileVoxels, 0);
        const std::uint32_t x = corner & 1 ? 63 : 0, y = corner & 2 ? 63 : 0,
                            z = corner & 4 ? 63 : 0;
        t[(z * 64 + y) * 64 + x] = static_cast<std::uint8_t>(corner + 1);
        tiles.push_back(std::move(t));
    }
    {
        // One solid 4^3 leaf per 16^3 node, and one 16^3 node full.
        std::vector<std::uint8_t> t(kTileVoxels, 0);
        for (std::uint32_t n = 0; n < 64; ++n) {
            const std::uint32_t x = (n & 3) * 16 + 4, y = (n >> 2 & 3) * 16 + 8, z = (n >> 4) * 16;
            t[(z * 64 + y) * 64 + x] = 9;
        }
        for (std::uint32_t z = 16; z < 32; ++z) {
            for (std::uint32_t y = 32; y < 48; ++y) {
                for (std::uint32_t x = 48; x < 64; ++x) {
                    t[(z * 64 + y) * 64 + x] = static_cast<std::uint8_t>(x + y + z);
                }
            }
        }
        tiles.push_back(std::move(t));
    }
    std::vector<std::uint8_t> all;
    for (const auto& t : tiles) {
        all.insert(all.end(), t.begin(), t.end());
    }
    const auto got = ocl::encode_tiles(pocl(), all);
    ASSERT_EQ(got.size(), tiles.size());
    for (std::size_t i = 0; i < tiles.size(); ++i) {
        const auto want = SparseWorld::encode_tile(tiles[i]);
        EXPECT_EQ(got[i].masks, want.masks) << "tile " << i;
        EXPECT_EQ(got[i].offsets, want.offsets) << "tile " << i;
        EXPECT_EQ(got[i].materials, want.materials) << "tile " << i;
    }
}

// Random brushes applied on the device (no host re-encoding): after each the field equals the
// dense bounded field of the same edits on a dense world, and the host world, once read, holds
// the dense world's voxels, every tile stored as encode_tile would store it. Host edits (update)
// mixed in, and a brush over more tiles than a device edit takes.
TEST(SparseDeviceWorld, BrushesOnTheDeviceEqualTheDenseReference) {
    std::mt19937 rng(32);
    const Palette p = Palette::magicavoxel_default();
    int k = 0;
    for (const Metric m : kMetrics) {
        for (const bool sgn : {false, true}) {
            const Dims d = k % 3 == 0   ? Dims{100, 50, 70}
                           : k % 3 == 1 ? Dims{64, 100, 65}
                                        : Dims{130, 20, 129};
            const Case c = edit_case(m, sgn, k++);
            SCOPED_TRACE(describe(c, d));
            World w = blob_world(d, 6, 0.0002, rng);
            SparseWorld s = SparseWorld::from_dense(w);
            ocl::SparseField f(pocl(), s, p, options_of(c));
            f.run();
            for (int e = 0; e < 14; ++e) {
                const Brush b = random_brush(d, e == 5 ? 60 : 12, rng);
                apply_brush(w, b);
                if (e % 5 == 4) {
                    // On the host: the world read (brought up to date) and edited there.
                    f.world();
                    f.update(apply_brush(s, b));
                } else {
                    const auto u = f.apply_brush(b);
                    EXPECT_EQ(u.tiles > 0, !brush_bounds(b, d).empty());
                }
                const auto got = f.read_dense();
                expect_same(got, dense_field(w, p, c), c, d, "after edit " + std::to_string(e));
                if (e % 4 == 3) {
                    expect_coarse_bounds(f, got, c, d);
                }
            }
            EXPECT_GT(f.device_world().slots_used(), 0u);
            const SparseWorld& host = f.world();
            ASSERT_EQ(host.to_dense().voxels(), w.voxels());
            std::vector<std::uint8_t> tile(kTileVoxels);
            for (std::uint32_t t = 0; t < host.tile_count(); ++t) {
                host.decode_tile(t, tile);
                ASSERT_EQ(stored_tile(host, t), SparseWorld::encode_tile(tile)) << "tile " << t;
            }
            ocl::SparseField fresh(pocl(), s, p, options_of(c));
            fresh.run();
            expect_same(fresh.read_dense(), f.read_dense(), c, d, "recomputed vs updated");
        }
    }
}

// Device edits re-encode only the 16^3 nodes a brush touches and copy the others: many small
// brushes on a few tiles of solid ground (full nodes: long material runs to copy), centred on
// 16^3 node and 64^3 tile borders and at the world's edges, each tile re-edited many times
// (its previous tree in a slot). Every few edits the host world, read back, holds every tile as
// encode_tile stores it and the dense world's voxels; the field equals the dense bounded field.
TEST(SparseDeviceWorld, RepeatedSmallEditsKeepTheUntouchedNodes) {
    std::mt19937 rng(34);
    const Palette p = Palette::magicavoxel_default();
    const Dims d{150, 90, 140};  // 3 x 2 x 3 tiles, cut by the world's edge
    World w(d);
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                const std::uint32_t ground = 40 + (x * 3 + z * 5) % 30;
                if (y < ground) {
                    w.set(x, y, z, static_cast<std::uint8_t>(1 + (x + 2 * y + 3 * z) % 200));
                }
            }
        }
    }
    int k = 0;
    for (const Metric m : kMetrics) {
        for (const bool sgn : {false, true}) {
            Case c;
            c.metric = m;
            c.signed_field = sgn;
            c.layout = kLayouts[k % 2];
            c.bound = 5;
            c.format = ocl::default_format(m, c.spacing, sgn);
            ++k;
            SCOPED_TRACE(describe(c, d));
            World dense = w;
            SparseWorld s = SparseWorld::from_dense(dense);
            ocl::SparseField f(pocl(), s, p, options_of(c));
            f.run();
            auto border = [&](std::uint32_t extent) {
                // A 16^3 or 64^3 border (or the world's edge), moved by -2..2.
                const std::int64_t step = std::bernoulli_distribution(0.5)(rng) ? 16 : 64;
                const std::int64_t n = extent / step + 1;
                const std::int64_t at =
                    std::uniform_int_distribution<std::int64_t>(0, n)(rng) * step;
                return std::min<std::int64_t>(at, extent) +
                       std::uniform_int_distribution<std::int64_t>(-2, 2)(rng);
            };
            for (int e = 0; e < 24; ++e) {
                Brush b;
                b.op = static_cast<BrushOp>(e % 3);
                b.shape = static_cast<BrushShape>(e / 3 % 2);
                b.centre = {border(d.x), border(d.y), border(d.z)};
                b.radius = std::uniform_int_distribution<std::int64_t>(0, 6)(rng);
                b.material = static_cast<std::uint8_t>(1 + e);
                apply_brush(dense, b);
                f.apply_brush(b);
                if (e % 8 == 7) {
                    expect_same(f.read_dense(), dense_field(dense, p, c), c, d,
                                "after edit " + std::to_string(e));
                    const SparseWorld& host = f.world();
                    ASSERT_EQ(host.to_dense().voxels(), dense.voxels()) << "after edit " << e;
                    std::vector<std::uint8_t> tile(kTileVoxels);
                    for (std::uint32_t t = 0; t < host.tile_count(); ++t) {
                        host.decode_tile(t, tile);
                        ASSERT_EQ(stored_tile(host, t), SparseWorld::encode_tile(tile))
                            << "tile " << t << " after edit " << e;
                    }
                }
            }
        }
    }
}

// An edit of one block says where its wall time went: the host's stages (the world's edit, the
// field's tables, their enqueue, the wait, what came after) lie within the call, and the
// device's span of its commands holds their kernels and their idle part. An edit of several blocks
// says nothing of it.
// A terrain: every column (x, z) solid up to height(x, z), voxel (x, y) of material(x, y).
template <class Height, class Material>
World terrain_world(Dims d, Height height, Material material) {
    World w(d);
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t x = 0; x < d.x; ++x) {
            for (std::uint32_t y = 0; y < height(x, z); ++y) {
                w.set(x, y, z, material(x, y));
            }
        }
    }
    return w;
}

TEST(SparseDeviceWorld, OneBlockEditsTellWhereTheirTimeWent) {
    const Palette p = Palette::magicavoxel_default();
    const Dims d{300, 90, 140};
    const World w = terrain_world(
        d, [](std::uint32_t x, std::uint32_t z) { return 30 + (x + z) % 20; },
        [](std::uint32_t, std::uint32_t) { return std::uint8_t{7}; });
    const std::vector<std::string> names = {"world edit", "field tables", "field enqueue", "wait",
                                            "after"};
    for (const Layout layout : kLayouts) {
        Case c;
        c.layout = layout;
        c.bound = 8;
        SCOPED_TRACE(describe(c, d));
        SparseWorld s = SparseWorld::from_dense(w);
        ocl::SparseField f(pocl(), s, p, options_of(c));
        f.run();
        for (int e = 0; e < 4; ++e) {
            Brush b;
            b.op = e % 2 == 0 ? BrushOp::place : BrushOp::erase;
            b.centre = {30 + 70 * e, 40, 70};
            b.radius = 8;
            b.material = 3;
            const auto t0 = Clock::now();
            const ocl::SparseField::Update u = f.apply_brush(b);
            const double wall = ms_since(t0);
            ASSERT_EQ(u.host_stages.size(), names.size()) << "edit " << e;
            double sum = 0;
            for (std::size_t i = 0; i < names.size(); ++i) {
                EXPECT_EQ(u.host_stages[i].first, names[i]);
                EXPECT_GE(u.host_stages[i].second, 0.0) << names[i];
                sum += u.host_stages[i].second;
            }
            EXPECT_LE(sum, wall) << "edit " << e;
            // The span holds every command: the kernels (the world's and the field's) too.
            EXPECT_GE(u.device_span_ms + 1e-6, u.kernel_ms) << "edit " << e;
            EXPECT_GT(u.device_span_ms, 0.0) << "edit " << e;
            EXPECT_GE(u.device_idle_ms, 0.0) << "edit " << e;
            EXPECT_LE(u.device_idle_ms, u.device_span_ms) << "edit " << e;
        }
        // Two tiles far apart written back (an undo's update): two blocks, nothing said.
        const std::vector<Int3> apart = {{0, 0, 0}, {4, 1, 2}};
        const cl::Buffer tiles(pocl().context(), CL_MEM_READ_WRITE,
                               apart.size() * std::size_t{kTileVoxels});
        f.device_world().gather_tiles(apart, tiles);
        const ocl::SparseField::Update u = f.write_tiles(tiles, apart);
        EXPECT_TRUE(u.host_stages.empty());
        EXPECT_EQ(u.device_span_ms, 0.0);
    }
}

// Edits without stage events (set_edit_stage_events(false)) change the world and the field as
// profiled ones do, enqueue as many commands, wait as often, and say so: profiled false, no
// stages, no event on any command (the world's table write included) and, on the queue without
// profiling, no kernel time or device span; switched back, an edit has its stages again.
TEST(SparseDeviceWorld, LeanEditsEqualProfiledOnes) {
    const Palette p = Palette::magicavoxel_default();
    const Dims d{200, 70, 150};
    const World w = terrain_world(
        d, [](std::uint32_t x, std::uint32_t z) { return 20 + (x * 3 + z) % 25; },
        [](std::uint32_t x, std::uint32_t y) {
            return static_cast<std::uint8_t>(1 + (x + y) % 9);
        });
    for (const Layout layout : kLayouts) {
        Case c;
        c.layout = layout;
        c.bound = 8;
        SCOPED_TRACE(describe(c, d));
        SparseWorld sp = SparseWorld::from_dense(w), sl = SparseWorld::from_dense(w);
        ocl::SparseField profiled(pocl(), sp, p, options_of(c)), lean(pocl(), sl, p, options_of(c));
        profiled.run();
        lean.run();
        lean.set_edit_stage_events(false);
        std::mt19937 rng(71);
        for (int e = 0; e < 6; ++e) {
            Brush b;
            b.op = e % 3 == 0 ? BrushOp::erase : e % 3 == 1 ? BrushOp::place : BrushOp::paint;
            b.shape = e % 2 == 0 ? BrushShape::sphere : BrushShape::cube;
            b.centre = {static_cast<std::int64_t>(rng() % d.x),
                        static_cast<std::int64_t>(rng() % 60),
                        static_cast<std::int64_t>(rng() % d.z)};
            b.radius = 3 + rng() % 7;
            b.material = static_cast<std::uint8_t>(1 + rng() % 200);
            const ocl::SparseField::Update a = profiled.apply_brush(b), l = lean.apply_brush(b);
            SCOPED_TRACE("edit " + std::to_string(e));
            EXPECT_TRUE(a.profiled);
            EXPECT_FALSE(a.stages.empty());
            EXPECT_FALSE(l.profiled);
            EXPECT_TRUE(l.stages.empty());
            EXPECT_EQ(l.edit_kernel_ms, 0.0);
            EXPECT_EQ(l.recomputed.min, a.recomputed.min);
            EXPECT_EQ(l.recomputed.max, a.recomputed.max);
            EXPECT_EQ(l.tiles, a.tiles);
            EXPECT_EQ(l.traffic.enqueues, a.traffic.enqueues);
            EXPECT_EQ(l.traffic.host_waits, a.traffic.host_waits);
            ASSERT_EQ(l.host_stages.empty(), a.host_stages.empty());
            EXPECT_EQ(l.kernel_ms, 0.0);
            EXPECT_EQ(l.device_span_ms, 0.0);
            EXPECT_EQ(l.device_idle_ms, 0.0);
            if (!a.host_stages.empty()) {
                EXPECT_GT(a.device_span_ms, 0.0);
            }
            // The lean edit's table write has no event either (the edit's scatter_minima
            // fences its pinned table); the profiled one's starts its commands' timeline.
            EXPECT_TRUE(lean.device_world().last_edit_commands().empty());
            EXPECT_EQ(profiled.device_world().last_edit_commands().empty(), a.host_stages.empty());
        }
        const Box all{{0, 0, 0}, {d.x, d.y, d.z}};
        EXPECT_EQ(lean.read_box(all), profiled.read_box(all));
        EXPECT_EQ(lean.world().to_dense().voxels(), profiled.world().to_dense().voxels());
        // Tiles written back (an undo's update) without events say so too, and are the same.
        const std::vector<Int3> back = {{0, 0, 0}, {2, 0, 1}};
        for (ocl::SparseField* f : {&lean, &profiled}) {
            const cl::Buffer tiles(pocl().context(), CL_MEM_READ_WRITE,
                                   back.size() * std::size_t{kTileVoxels});
            f->device_world().gather_tiles(back, tiles);
            EXPECT_EQ(f->write_tiles(tiles, back).profiled, f == &profiled);
        }
        EXPECT_EQ(lean.read_box(all), profiled.read_box(all));
        lean.set_edit_stage_events(true);
        Brush b;
        b.centre = {100, 40, 75};
        b.radius = 8;
        b.material = 5;
        const ocl::SparseField::Update u = lean.apply_brush(b);
        EXPECT_TRUE(u.profiled);
        EXPECT_FALSE(u.stages.empty());
        EXPECT_GT(u.edit_kernel_ms, 0.0);
    }
}

// An edit's block whose field starts with a slice stage (unsigned L1 in the GPU layout) reads
// its slices from the world's trees in that launch (sparse_slices.cl), without a gather: in
// u8, u16 and u32, near the world's edges (blocks reaching past them, tiles cut by them),
// across tile borders, on the device and from the host (update), the field equals the dense
// bounded field after every edit, and the profiled edit names the kernel. packed32 (coloured
// from the gathered materials) keeps the gather, and equals it too.
TEST(SparseDeviceWorld, EditBlocksReadTheirSlicesFromTheTrees) {
    std::mt19937 rng(73);
    const Palette p = Palette::magicavoxel_default();
    const Dims d{150, 90, 140};
    const World start = terrain_world(
        d, [](std::uint32_t x, std::uint32_t z) { return 25 + (x * 7 + z * 3) % 30; },
        [](std::uint32_t x, std::uint32_t y) {
            return static_cast<std::uint8_t>(1 + (x * 5 + y) % 200);
        });
    for (const Format format : {Format::u8, Format::u16, Format::u32, Format::packed32}) {
        Case c;
        c.layout = Layout::gpu;
        c.format = format;
        c.bound = format == Format::u8 ? 6 : 9.5;
        SCOPED_TRACE(describe(c, d));
        World w = start;
        SparseWorld s = SparseWorld::from_dense(w);
        ocl::SparseField f(pocl(), s, p, options_of(c));
        f.run();
        int named_edits = 0;
        for (int e = 0; e < 10; ++e) {
            Brush b = random_brush(d, 9, rng);
            if (e == 0) {
                b.centre = {64, 40, 64};  // on a tile corner
            }
            apply_brush(w, b);
            const ocl::SparseField::Update u =
                e % 4 == 3 ? (f.world(), f.update(apply_brush(s, b))) : f.apply_brush(b);
            SCOPED_TRACE("edit " + std::to_string(e));
            if (u.tiles > 0 && !u.host_stages.empty()) {
                const auto named = [&](const std::string& name) {
                    return std::any_of(u.stages.begin(), u.stages.end(),
                                       [&](const auto& st) { return st.first == name; });
                };
                const bool tree = format != Format::packed32;
                EXPECT_EQ(named("xy_tree_local") || named("xy_tree_segments"), tree);
                EXPECT_EQ(named("gather"), !tree);
                EXPECT_EQ(named("xy_slice_local") || named("xy_slice_segments"), !tree);
                ++named_edits;
            }
            expect_same(f.read_dense(), dense_field(w, p, c), c, d, "after the edit");
        }
        EXPECT_GE(named_edits, 3);
    }
}

TEST(SparseDeviceWorld, LargeBrushesAndReadOnlyWorlds) {
    std::mt19937 rng(33);
    const Palette p = Palette::magicavoxel_default();
    const Dims d{600, 40, 600};  // 10 x 1 x 10 tiles
    World w = blob_world(d, 30, 0.0, rng);
    SparseWorld s = SparseWorld::from_dense(w);
    Case c;
    c.bound = 6;
    ocl::SparseField f(pocl(), s, p, options_of(c));
    f.run();
    Brush small{BrushOp::place, BrushShape::cube, {300, 20, 300}, 5, 7};
    Brush large{BrushOp::erase, BrushShape::sphere, {250, 10, 280}, 290, 1};
    Brush paint{BrushOp::paint, BrushShape::sphere, {310, 20, 300}, 9, 42};
    for (const Brush& b : {small, large, paint}) {
        apply_brush(w, b);
        f.apply_brush(b);
        expect_same(f.read_dense(), dense_field(w, p, c), c, d, "after " + to_string(b.op));
    }
    EXPECT_EQ(f.world().to_dense().voxels(), w.voxels());
    Brush bad = small;
    bad.material = 0;
    EXPECT_THROW(f.apply_brush(bad), InputError);
    const SparseWorld& read_only = s;
    ocl::SparseField g(pocl(), read_only, p, options_of(c));
    EXPECT_THROW(g.apply_brush(small), std::logic_error);
}

// Slot buffers that cannot grow (an allocator refusing them past 32 slots, as a device out of
// memory does) make the world whole again, which frees every slot, and the edit goes on (the
// refused size is not asked for again): after many edits over many tiles the field equals the
// dense bounded field and the host world the dense world, and no slot buffer was ever made
// past the limit.
TEST(SparseDeviceWorld, RefusedSlotGrowthUploadsTheWorldWholeAndGoesOn) {
    std::mt19937 rng(35);
    const Palette p = Palette::magicavoxel_default();
    const Dims d{600, 40, 600};  // 10 x 1 x 10 tiles
    World w = blob_world(d, 40, 0.0001, rng);
    SparseWorld s = SparseWorld::from_dense(w);
    Case c;
    c.bound = 6;
    constexpr std::size_t kMaxSlots = 32;
    int refused = 0, dropped = 0;
    std::size_t largest = 0;
    ocl::TreeAllocator limited;
    limited.allocate = [&](std::size_t bytes, const std::string& what) {
        if (what == "sparse slot materials") {
            if (bytes > kMaxSlots * kTileVoxels) {
                ++refused;
                throw std::runtime_error("refused: " + std::to_string(bytes) + " bytes");
            }
            largest = std::max(largest, bytes);
        }
        return cl::Buffer(pocl().context(), CL_MEM_READ_WRITE, std::max<std::size_t>(bytes, 1));
    };
    limited.dropped = [&](const std::vector<cl::Buffer>&) { ++dropped; };
    ocl::SparseField f(pocl(), s, p, options_of(c), limited);
    f.run();
    const int dropped_at_start = dropped;
    for (int e = 0; e < 40; ++e) {
        Brush b;
        b.op = e % 4 == 3 ? BrushOp::erase : BrushOp::place;
        b.shape = BrushShape::sphere;
        // Centred on tile corners: 4 tiles an edit (one tile high), most not edited before.
        b.centre = {std::uniform_int_distribution<std::int64_t>(1, 9)(rng) * 64, 20,
                    std::uniform_int_distribution<std::int64_t>(1, 9)(rng) * 64};
        b.radius = 6;
        b.material = static_cast<std::uint8_t>(1 + e);
        apply_brush(w, b);
        f.apply_brush(b);
        ASSERT_LE(f.device_world().slots_used(), kMaxSlots) << "after edit " << e;
    }
    EXPECT_EQ(refused, 1);                 // a refused size is not tried again
    EXPECT_GT(dropped, dropped_at_start);  // whole uploads after the refusals
    EXPECT_EQ(largest, kMaxSlots * kTileVoxels);
    expect_same(f.read_dense(), dense_field(w, p, c), c, d, "after the edits");
    EXPECT_EQ(f.world().to_dense().voxels(), w.voxels());
}

// prepare_edits sets up the programs of an edit's block update: in a fresh context, the
// edits after it (radius 0 to 12, both layouts) build or load no program. Without it the first
// L1 edit does (run() sweeps, with other programs); an L2 run() transforms blocks with the
// edits' programs already.
TEST(SparseField, PreparedEditsSetUpNoProgram) {
    std::mt19937 rng(36);
    const Palette p = Palette::magicavoxel_default();
    const Dims d{300, 120, 260};
    const World w = blob_world(d, 12, 0.0001, rng);
    const auto set_up = [](const ocl::Context& ctx) {
        return ctx.program_cache_stats().built + ctx.program_cache_stats().loaded;
    };
    for (const Metric m : {Metric::manhattan, Metric::euclidean}) {
        for (const Layout layout : kLayouts) {
            for (const bool prepare : {false, true}) {
                Case c;
                c.metric = m;
                c.layout = layout;
                c.bound = 16;
                c.format = m == Metric::manhattan ? Format::u8 : Format::f32;
                SCOPED_TRACE(describe(c, d) + (prepare ? " prepared" : " not prepared"));
                ocl::Context ctx(pocl().info());
                SparseWorld s = SparseWorld::from_dense(w);
                ocl::SparseField f(ctx, s, p, options_of(c));
                f.run();
                const bool sweeps = m == Metric::manhattan;
                const auto before = set_up(ctx);
                if (prepare) {
                    f.prepare_edits(8);
                    EXPECT_EQ(set_up(ctx) > before, sweeps);
                }
                const auto ready = set_up(ctx);
                World dense = w;
                for (const std::int64_t r : {8, 0, 5, 12}) {
                    const Brush b{
                        BrushOp::place, BrushShape::sphere, {150 + 7 * r, 60, 130 - 5 * r}, r, 9};
                    apply_brush(dense, b);
                    f.apply_brush(b);
                }
                EXPECT_EQ(set_up(ctx) > ready, sweeps && !prepare);
                expect_same(f.read_dense(), dense_field(dense, p, c), c, d, "after the edits");
            }
        }
    }
}

// figures() gives what the host world reports once brought up to date (tiles, solid voxels,
// live 64-tree bytes) without reading it back: after device edits (a tile emptied among them),
// host edits and a whole upload, the host world lagging until it is compared.
TEST(SparseDeviceWorld, FiguresReadTheDeviceNotTheHost) {
    std::mt19937 rng(37);
    const Palette p = Palette::magicavoxel_default();
    const Dims d{300, 70, 200};  // 5 x 2 x 4 tiles, cut by the world's edge
    World w = blob_world(d, 25, 0.001, rng);
    SparseWorld s = SparseWorld::from_dense(w);
    Case c;
    c.bound = 5;
    ocl::SparseField f(pocl(), s, p, options_of(c));
    f.run();
    const auto host_figures = [&] {
        const SparseWorld& h = f.world();
        ocl::SparseDeviceWorld::Figures want;
        want.tiles = h.tile_count();
        want.solid = h.solid_count();
        for (std::uint32_t t = 0; t < h.tile_count(); ++t) {
            want.tree_bytes += std::uint64_t{h.node_counts()[t]} * 12 + h.material_counts()[t];
        }
        return want;
    };
    const auto expect_figures = [&](const std::string& when) {
        const ocl::SparseDeviceWorld::Figures got = f.device_world().figures();
        const ocl::SparseDeviceWorld::Figures want = host_figures();
        EXPECT_EQ(got.tiles, want.tiles) << when;
        EXPECT_EQ(got.solid, want.solid) << when;
        EXPECT_EQ(got.tree_bytes, want.tree_bytes) << when;
    };
    expect_figures("at the start");
    for (int e = 0; e < 30; ++e) {
        Brush b;
        b.op = e % 3 == 0 ? BrushOp::erase : e % 3 == 1 ? BrushOp::place : BrushOp::paint;
        b.shape = static_cast<BrushShape>(e % 2);
        b.centre = {std::uniform_int_distribution<std::int64_t>(0, d.x)(rng),
                    std::uniform_int_distribution<std::int64_t>(0, d.y)(rng),
                    std::uniform_int_distribution<std::int64_t>(0, d.z)(rng)};
        b.radius = std::uniform_int_distribution<std::int64_t>(0, 14)(rng);
        b.material = static_cast<std::uint8_t>(1 + e);
        if (e == 12) {
            // One whole tile emptied (a cube over tile (1, 0, 1) and beyond).
            b = Brush{BrushOp::erase, BrushShape::cube, {96, 32, 96}, 40, 1};
        }
        if (e % 7 == 6) {
            f.world();
            f.update(apply_brush(s, b));
        } else {
            f.apply_brush(b);
            EXPECT_TRUE(f.device_world().host_lags());
        }
        const ocl::SparseDeviceWorld::Figures before_read = f.device_world().figures();
        if (e % 7 != 6) {
            EXPECT_TRUE(f.device_world().host_lags()) << "figures() read the world back";
        }
        if (e % 5 == 4 || e == 12) {
            expect_figures("after edit " + std::to_string(e));
            EXPECT_EQ(f.device_world().figures().solid, before_read.solid);
        }
    }
    f.device_world().refresh();
    expect_figures("after a refresh");
    EXPECT_GT(f.device_world().slots_used(), 0u);
}

TEST(SparseField, CoarseDistancesBoundTheExactDistance) {
    std::mt19937 rng(25);
    const Dims d{140, 66, 70};
    const World w = blob_world(d, 5, 0.0, rng);
    const auto exact = reference_distance(w, Metric::euclidean, Spacing{});
    const Palette p = Palette::magicavoxel_default();
    const SparseWorld s = SparseWorld::from_dense(w);
    Case c;
    c.metric = Metric::euclidean;
    c.format = Format::f32;
    ocl::SparseField f(pocl(), s, p, options_of(c));
    f.run();
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                ASSERT_LE(f.coarse_node(x / 16, y / 16, z / 16), exact[d.index(x, y, z)]);
            }
        }
    }
    // Far from everything the coarse distance is D (rounded down by a float ulp).
    EXPECT_EQ(f.coarse_tile(100, 100, 100), std::nextafter(16.0f, 0.0f));
}

TEST(SparseField, OptionsForSparseWorlds) {
    ocl::GeneratorOptions o;
    EXPECT_EQ(*ocl::resolve_sparse_options(o, false).max_distance, 16.0);
    o.indices = true;
    EXPECT_THROW(ocl::resolve_sparse_options(o, false), InputError);
    o.indices = false;
    o.algorithm = ocl::Algorithm::jfa;
    EXPECT_THROW(ocl::resolve_sparse_options(o, false), InputError);
    o.algorithm = ocl::Algorithm::exact;
    o.max_distance = 5000;
    EXPECT_THROW(ocl::resolve_sparse_options(o, false), InputError);
    o.max_distance = -1;
    EXPECT_THROW(ocl::resolve_sparse_options(o, false), InputError);
}

// Brush e of a sequence: place, erase, paint in turn, sphere and cube in turn, centred at a
// random voxel of `d`, radius in [lo, hi], material 1 + e.
Brush cycling_brush(int e, const Dims& d, std::int64_t lo, std::int64_t hi, std::mt19937& rng) {
    Brush b;
    b.op = static_cast<BrushOp>(e % 3);
    b.shape = static_cast<BrushShape>(e % 2);
    b.centre = {std::uniform_int_distribution<std::int64_t>(0, d.x)(rng),
                std::uniform_int_distribution<std::int64_t>(0, d.y)(rng),
                std::uniform_int_distribution<std::int64_t>(0, d.z)(rng)};
    b.radius = std::uniform_int_distribution<std::int64_t>(lo, hi)(rng);
    b.material = static_cast<std::uint8_t>(1 + e);
    return b;
}

// The sparse viewer's reads without the host world: after device edits (the host lagging),
// voxels() at random cells (inside, outside the world, in tiles not stored, in slots) equals the
// world read back after; pick() equals core's pick over the world read back, hit for hit (voxel,
// face and distance), for rays from outside and inside the world, with and without a limit.
TEST(SparseDeviceWorld, VoxelsAndPicksReadTheDeviceNotTheHost) {
    std::mt19937 rng(36);
    const Palette p = Palette::magicavoxel_default();
    const Dims d{150, 90, 200};
    World w = blob_world(d, 12, 0.001, rng);
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t x = 0; x < d.x; ++x) {
            for (std::uint32_t y = 0; y < 3 + (x + z) % 9; ++y) {
                w.set(x, y, z, 3);  // a ground, and tiles of the empty air above it
            }
        }
    }
    SparseWorld s = SparseWorld::from_dense(w);
    Case c;
    c.metric = Metric::manhattan;
    c.format = Format::u8;
    c.bound = 6;
    ocl::SparseField f(pocl(), s, p, options_of(c));
    for (int e = 0; e < 10; ++e) {
        const Brush b = cycling_brush(e, d, 2, 14, rng);
        f.apply_brush(b);
    }
    ASSERT_TRUE(f.device_world().host_lags());
    std::vector<Int3> cells;
    std::uniform_int_distribution<std::int64_t> cx(-70, d.x + 70), cy(-70, d.y + 70),
        cz(-70, d.z + 70);
    for (int i = 0; i < 20000; ++i) {
        cells.push_back({cx(rng), cy(rng), cz(rng)});
    }
    const std::vector<std::uint8_t> got = f.device_world().voxels(cells);
    ocl::SparseDeviceWorld& dw = f.device_world();
    std::vector<PickHit> device_hits;
    std::vector<std::pair<Vec3d, Vec3d>> rays;
    std::uniform_real_distribution<double> u(0, 1);
    for (int i = 0; i < 300; ++i) {
        const Vec3d target{u(rng) * d.x, u(rng) * d.y, u(rng) * d.z};
        const Vec3d origin = i % 3 == 0 ? Vec3d{u(rng) * d.x, u(rng) * d.y, u(rng) * d.z}
                                        : Vec3d{-40 + u(rng) * 30, d.y + 20 * u(rng), -30.5};
        const Vec3d dir{target[0] - origin[0], target[1] - origin[1], target[2] - origin[2]};
        rays.emplace_back(origin, dir);
        const auto hit = dw.pick(origin, dir, i % 4 == 0 ? 0.7 : 1e9);
        device_hits.push_back(hit.value_or(PickHit{{-1, -1, -1}, {0, 0, 0}, -1}));
    }
    ASSERT_TRUE(f.device_world().host_lags());  // nothing above read the host world back
    const SparseWorld& host = f.world();
    std::size_t solid = 0;
    for (std::size_t i = 0; i < cells.size(); ++i) {
        const Int3 v = cells[i];
        const bool inside = v.x >= 0 && v.y >= 0 && v.z >= 0 && v.x < d.x && v.y < d.y && v.z < d.z;
        const std::uint8_t want =
            inside ? host.at(static_cast<std::uint32_t>(v.x), static_cast<std::uint32_t>(v.y),
                             static_cast<std::uint32_t>(v.z))
                   : 0;
        ASSERT_EQ(got[i], want) << "cell " << v.x << ", " << v.y << ", " << v.z;
        solid += want != 0;
    }
    EXPECT_GT(solid, 100u);
    std::size_t hits = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const auto want = pick_solid_voxel(
            d,
            [&host](std::uint32_t x, std::uint32_t y, std::uint32_t z) {
                return host.at(x, y, z) != 0;
            },
            rays[i].first, rays[i].second, i % 4 == 0 ? 0.7 : 1e9);
        EXPECT_EQ(device_hits[i], want.value_or(PickHit{{-1, -1, -1}, {0, 0, 0}, -1}))
            << "ray " << i;
        hits += want.has_value();
    }
    EXPECT_GT(hits, 100u);
}

// The sparse viewer's undo: before each brush the tiles it touches are gathered on the device
// (SparseDeviceWorld::gather_tiles), and writing them back (SparseField::write_tiles) in reverse
// undoes the brushes: the world equals the dense world before them, and the field its dense
// bounded field, in both layouts, unsigned L1 and signed L2.
TEST(SparseDeviceWorld, GatheredTilesWrittenBackUndoBrushes) {
    std::mt19937 rng(37);
    const Palette p = Palette::magicavoxel_default();
    const Dims d{150, 90, 140};  // tiles cut by the world's edge
    for (const bool l2 : {false, true}) {
        Case c;
        c.metric = l2 ? Metric::euclidean : Metric::manhattan;
        c.signed_field = l2;
        c.layout = l2 ? Layout::gpu : Layout::cpu;
        c.bound = 7;
        c.format = ocl::default_format(c.metric, c.spacing, c.signed_field);
        SCOPED_TRACE(describe(c, d));
        World w = blob_world(d, 6, 0.0005, rng);
        SparseWorld s = SparseWorld::from_dense(w);
        ocl::SparseField f(pocl(), s, p, options_of(c));
        f.run();
        struct Step {
            std::vector<Int3> tiles;
            cl::Buffer before;
        };
        std::vector<Step> history;
        std::vector<World> states;
        for (int e = 0; e < 8; ++e) {
            const Brush b = cycling_brush(e, d, 3, e == 4 ? 40 : 12, rng);
            const Box bounds = brush_bounds(b, d);
            Step step;
            step.tiles = tiles_overlapping(bounds);
            step.before = cl::Buffer(pocl().context(), CL_MEM_READ_WRITE,
                                     step.tiles.size() * std::size_t{kTileVoxels});
            f.device_world().gather_tiles(step.tiles, step.before);
            history.push_back(step);
            states.push_back(w);
            apply_brush(w, b);
            f.apply_brush(b);
        }
        ASSERT_NE(f.world().to_dense().voxels(), states[3].voxels());
        for (int k = 7; k >= 3; --k) {
            f.write_tiles(history[static_cast<std::size_t>(k)].before,
                          history[static_cast<std::size_t>(k)].tiles);
        }
        ASSERT_EQ(f.world().to_dense().voxels(), states[3].voxels());
        expect_same(f.read_dense(), dense_field(states[3], p, c), c, d, "after 5 undos");
    }
}

}  // namespace
}  // namespace voxfield
