// `exact` for every metric, spacing, signed fields and the feature transform, on PoCL in both
// kernel layouts, against the CPU reference (core/reference_metric.cpp).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <optional>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "cl_test_util.hpp"
#include "voxfield/cl/separable.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield {
namespace {

using ocl::Layout;
using test::pocl;

const Metric kMetrics[] = {Metric::manhattan, Metric::chebyshev, Metric::euclidean};
const Layout kLayouts[] = {Layout::cpu, Layout::gpu};

ocl::GeneratorOptions options(Metric m, const Spacing& s, bool signed_field, Format f,
                              Layout layout, bool indices = false) {
    ocl::GeneratorOptions o;
    o.metric = m;
    o.spacing = s;
    o.signed_field = signed_field;
    o.format = f;
    o.layout = layout;
    o.indices = indices;
    return o;
}

std::string describe(const ocl::GeneratorOptions& o, Dims d) {
    return to_string(o.metric) + " spacing " + o.spacing.to_string() +
           (o.signed_field ? " signed" : "") + " format " + to_string(o.format) + " layout " +
           (o.layout == Layout::cpu ? "cpu" : "gpu") + " world " + d.to_string();
}

std::vector<double> reference(const World& w, const ocl::GeneratorOptions& o) {
    return o.signed_field ? reference_signed(w, o.metric, o.spacing)
                          : reference_distance(w, o.metric, o.spacing);
}

// Unit spacing: byte-identical to the reference's encoding (L2 floats correctly rounded).
// Other spacings: floats within 4 float ulps relative, integers equal except where the
// value lies within that rounding of an integer.
void expect_matches(const World& w, const Palette& p, const ocl::GeneratorOptions& o,
                    const std::vector<double>& ref, const std::string& what) {
    const auto got = ocl::generate(pocl(), w, p, o).bytes;
    const auto want = encode_real_field(ref, w, p, o.format);
    ASSERT_EQ(got.size(), want.size()) << what;
    if (o.spacing.unit()) {
        if (got != want) {
            std::size_t i = 0;
            while (decode_value(got, o.format, i) == decode_value(want, o.format, i)) {
                ++i;
            }
            const Dims d = w.dims();
            FAIL() << what << " " << describe(o, d) << ": first difference at voxel (" << i % d.x
                   << "," << i / d.x % d.y << "," << i / d.x / d.y << "): got "
                   << decode_value(got, o.format, i) << ", want " << decode_value(want, o.format, i)
                   << " (exact " << ref[i] << ")";
        }
        return;
    }
    for (std::size_t i = 0; i < ref.size(); ++i) {
        const double a = decode_value(got, o.format, i);
        const double b = decode_value(want, o.format, i);
        if (a == b) {
            continue;
        }
        const double tol = 5e-7 * std::max(1.0, std::fabs(ref[i]));
        const bool near_integer = std::fabs(ref[i] - std::round(ref[i])) <= tol;
        const bool ok =
            is_float(o.format) ? std::fabs(a - b) <= tol : near_integer && std::fabs(a - b) == 1;
        if (!ok) {
            FAIL() << what << " " << describe(o, w.dims()) << ": voxel " << i << " got " << a
                   << ", want " << b << " (exact " << ref[i] << ")";
        }
    }
}

Format float_or(Metric m, const Spacing& s, bool signed_field) {
    return ocl::default_format(m, s, signed_field);
}

// Random grids (1..70 voxels per axis, densities 0 to 100%), unit and random spacing,
// unsigned and signed, both layouts.
void expect_random_grids(Metric m, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    const double densities[] = {0.0, 0.0005, 0.005, 0.03, 0.1, 0.3, 0.6, 0.95, 1.0};
    std::uniform_int_distribution<std::uint32_t> axis(1, 70);
    std::uniform_real_distribution<double> sp(0.25, 3.0);
    for (int i = 0; i < 18; ++i) {
        const Dims dims{axis(rng), axis(rng), axis(rng)};
        const double density = densities[static_cast<std::size_t>(i) % std::size(densities)];
        const World w = scene_random(dims, density, rng());
        const std::string what =
            "random #" + std::to_string(i) + " density " + std::to_string(density);
        const Spacing spacings[] = {Spacing{}, Spacing{sp(rng), sp(rng), sp(rng)}};
        for (const Spacing& s : spacings) {
            for (bool sgn : {false, true}) {
                const auto o0 = options(m, s, sgn, float_or(m, s, sgn), Layout::cpu);
                const auto ref = reference(w, o0);
                for (Layout layout : kLayouts) {
                    auto o = o0;
                    o.layout = layout;
                    expect_matches(w, Palette(), o, ref, what);
                    if (::testing::Test::HasFailure()) {
                        return;
                    }
                }
            }
        }
    }
}

TEST(ExactSeparable, ManhattanMatchesReferenceOnRandomGrids) {
    expect_random_grids(Metric::manhattan, 20261201);
}

TEST(ExactSeparable, ChebyshevMatchesReferenceOnRandomGrids) {
    expect_random_grids(Metric::chebyshev, 20261202);
}

TEST(ExactSeparable, EuclideanMatchesReferenceOnRandomGrids) {
    expect_random_grids(Metric::euclidean, 20261203);
}

TEST(ExactSeparable, EveryFormatOfEveryMetric) {
    const World w = scene_random(Dims{37, 29, 41}, 0.01, 77);
    const Format unsigned_formats[] = {Format::u8,       Format::u16, Format::u32,
                                       Format::packed32, Format::i8,  Format::i16,
                                       Format::i32,      Format::f32, Format::f64};
    const Format signed_formats[] = {Format::i8, Format::i16, Format::i32, Format::f32,
                                     Format::f64};
    const Palette palette = Palette::dissertation();
    // Every format with unit spacing; with spacing (float arithmetic) a few of each kind.
    const Format spaced_unsigned[] = {Format::u8, Format::packed32, Format::f64};
    const Format spaced_signed[] = {Format::i32, Format::f32};
    for (Metric m : kMetrics) {
        for (const Spacing& s : {Spacing{}, Spacing{0.5, 2.0, 1.25}}) {
            const auto ref = reference_distance(w, m, s);
            const auto sref = reference_signed(w, m, s);
            const bool unit = s.unit();
            for (Layout layout : kLayouts) {
                for (Format f : unsigned_formats) {
                    if (unit || std::find(std::begin(spaced_unsigned), std::end(spaced_unsigned),
                                          f) != std::end(spaced_unsigned)) {
                        expect_matches(w, palette, options(m, s, false, f, layout), ref,
                                       "unsigned");
                    }
                }
                for (Format f : signed_formats) {
                    if (unit || std::find(std::begin(spaced_signed), std::end(spaced_signed), f) !=
                                    std::end(spaced_signed)) {
                        expect_matches(w, palette, options(m, s, true, f, layout), sref, "signed");
                    }
                }
            }
        }
    }
}

TEST(ExactSeparable, BoundedFieldsAreTheExactFieldCappedAtD) {
    const World w = scene_random(Dims{45, 33, 38}, 0.004, 5);
    for (Metric m : kMetrics) {
        for (const Spacing& s : {Spacing{}, Spacing{0.7, 1.3, 2.0}}) {
            for (double bound : {1.0, 4.5, 16.0}) {
                for (bool sgn : {false, true}) {
                    auto ref = sgn ? reference_signed(w, m, s) : reference_distance(w, m, s);
                    for (double& v : ref) {
                        v = v < 0 ? -std::min(-v, bound) : std::min(v, bound);
                    }
                    for (Layout layout : kLayouts) {
                        auto o = options(m, s, sgn, float_or(m, s, sgn), layout);
                        o.max_distance = bound;
                        expect_matches(w, Palette(), o, ref, "bounded " + std::to_string(bound));
                    }
                }
            }
        }
    }
}

// The CPU layout's unit L2 columns by vector windows (sub-tiles of 16 lines): lines whose
// sites lie hundreds of voxels apart pass the window's limit and fall back to the envelope
// (from the start, or midway) while other tiles stay on the windows; planes without any
// site; the last sub-tile of a row only partly filled. Unsigned and signed, both layouts.
TEST(ExactSeparable, SaturatesLongDistances) {
    // A lone voxel in a long world: distances beyond 255 saturate u8 and i8.
    World w(Dims{300, 2, 3});
    w.set(0, 0, 0, 1);
    for (Metric m : kMetrics) {
        for (Format f : {Format::u8, Format::i8, Format::u16}) {
            for (Layout layout : kLayouts) {
                expect_matches(w, Palette(), options(m, Spacing{}, false, f, layout),
                               reference_distance(w, m, Spacing{}), "saturation");
            }
        }
    }
}

// Every index names a solid voxel at exactly the field's distance; -1 only without solids.
void expect_indices(const World& w, const ocl::GeneratorOptions& o, const std::string& what) {
    const auto r = ocl::generate(pocl(), w, Palette(), o);
    const auto ref = reference_distance(w, o.metric, o.spacing);
    const Dims d = w.dims();
    const std::size_t n = d.count();
    ASSERT_EQ(r.indices.size(), 3 * n) << what;
    for (std::size_t i = 0; i < n; ++i) {
        const std::int32_t z = r.indices[i], y = r.indices[n + i], x = r.indices[2 * n + i];
        if (std::isinf(ref[i])) {
            ASSERT_TRUE(x == -1 && y == -1 && z == -1) << what << " voxel " << i;
            continue;
        }
        ASSERT_TRUE(d.contains(x, y, z))
            << what << " voxel " << i << " names " << x << "," << y << "," << z;
        ASSERT_NE(w.at(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y),
                       static_cast<std::uint32_t>(z)),
                  0)
            << what << " voxel " << i << " names an empty voxel";
        const long px = static_cast<long>(i % d.x), py = static_cast<long>(i / d.x % d.y),
                   pz = static_cast<long>(i / d.x / d.y);
        const double at = metric_distance(o.metric, o.spacing, px - x, py - y, pz - z);
        const double tol = o.spacing.unit() ? 0.0 : 1e-6 * std::max(1.0, ref[i]);
        ASSERT_LE(std::fabs(at - ref[i]), tol)
            << what << " " << describe(o, d) << " voxel " << i << ": index at distance " << at
            << ", nearest solid at " << ref[i];
    }
}

TEST(ExactSeparable, EuclideanWindowsAndTheirFallback) {
    std::mt19937_64 rng(20261226);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    // y long: plane z = 0 has solids only at y = 0 (its y lines fall back), z = 1 random 3%
    // (windows), z = 2 none.
    World ylong(Dims{37, 700, 3});
    for (std::uint32_t x = 0; x < 37; x += 3) {
        ylong.set(x, 0, 0, 1);
    }
    // z long: solids at z = 0 and random beyond z = 420, none between (the z lines fall back
    // midway).
    World zlong(Dims{21, 2, 650});
    zlong.set(4, 1, 0, 2);
    zlong.set(17, 0, 0, 2);
    // A cube: random solids only at x >= 32 (the first two sub-tiles of each row far).
    World cube(Dims{50, 300, 40});
    for (std::uint32_t z = 0; z < 650; ++z) {
        for (std::uint32_t y = 0; y < 700; ++y) {
            for (std::uint32_t x = 0; x < 50; ++x) {
                if (z == 1 && y < 700 && x < 37 && u(rng) < 0.03) {
                    ylong.set(x, y, z, 1);
                }
                if (z > 420 && y < 2 && x < 21 && u(rng) < 0.03) {
                    zlong.set(x, y, z, 1);
                }
                if (z < 40 && y < 300 && x >= 32 && u(rng) < 0.03) {
                    cube.set(x, y, z, 1);
                }
            }
        }
    }
    for (const World* w : {&ylong, &zlong, &cube}) {
        for (bool sgn : {false, true}) {
            const auto o0 = options(Metric::euclidean, Spacing{}, sgn,
                                    float_or(Metric::euclidean, Spacing{}, sgn), Layout::cpu);
            const auto ref = reference(*w, o0);
            for (Layout layout : kLayouts) {
                auto o = o0;
                o.layout = layout;
                expect_matches(*w, Palette(), o, ref, "window fallback");
            }
        }
        // The windows carry each lane's nearest site for the feature transform.
        expect_indices(*w,
                       options(Metric::euclidean, Spacing{}, false, Format::f64, Layout::cpu, true),
                       "window fallback, indices");
    }
}

TEST(ExactSeparable, IndicesNameANearestSolid) {
    std::mt19937_64 rng(99);
    std::uniform_int_distribution<std::uint32_t> axis(1, 50);
    const double densities[] = {0.0, 0.002, 0.02, 0.2, 1.0};
    for (int i = 0; i < 10; ++i) {
        const World w = scene_random(Dims{axis(rng), axis(rng), axis(rng)},
                                     densities[static_cast<std::size_t>(i) % 5], rng());
        for (Metric m : kMetrics) {
            for (const Spacing& s : {Spacing{}, Spacing{1.5, 0.75, 2.0}}) {
                for (Layout layout : kLayouts) {
                    expect_indices(w, options(m, s, false, Format::f32, layout, true),
                                   "random #" + std::to_string(i));
                    if (HasFatalFailure()) {
                        return;
                    }
                }
            }
        }
    }
}

// Every index equals the reference's with SciPy's ties (the nearest solid of lowest
// (x, y, z)).
void expect_scipy_ties(const World& w, const ocl::GeneratorOptions& o, const std::string& what) {
    const auto r = ocl::generate(pocl(), w, Palette(), o);
    const auto ref = reference_features(w, o.metric, o.spacing);
    const Dims d = w.dims();
    const std::size_t n = d.count();
    ASSERT_EQ(r.indices.size(), 3 * n) << what;
    for (std::size_t i = 0; i < n; ++i) {
        const std::int64_t f = ref[i];
        const std::int64_t want[3] = {f < 0 ? -1 : f / d.x / d.y, f < 0 ? -1 : f / d.x % d.y,
                                      f < 0 ? -1 : f % d.x};
        const std::int32_t z = r.indices[i], y = r.indices[n + i], x = r.indices[2 * n + i];
        ASSERT_TRUE(z == want[0] && y == want[1] && x == want[2])
            << what << " " << describe(o, d) << " voxel (" << i % d.x << "," << i / d.x % d.y << ","
            << i / d.x / d.y << ") names (" << x << "," << y << "," << z << "), want (" << want[2]
            << "," << want[1] << "," << want[0] << ")";
    }
}

// Ties on worlds full of them (dense random worlds, small worlds, lattices of solids an
// even number of voxels apart, long lines that leave the L2 windows for the envelope, one
// whose squares need WIDE): L1 and L2 (L-inf keeps its passes' position ties, for speed),
// both layouts.
TEST(ExactSeparable, IndicesBreakTiesAsScipy) {
    std::mt19937_64 rng(2027);
    std::uniform_int_distribution<std::uint32_t> small(1, 12), axis(1, 48);
    const double densities[] = {0.02, 0.2, 0.5, 0.8, 0.97};
    std::vector<std::pair<std::string, World>> worlds;
    for (int i = 0; i < 12; ++i) {
        const Dims d = i < 6 ? Dims{small(rng), small(rng), small(rng)}
                             : Dims{axis(rng), axis(rng), axis(rng)};
        worlds.emplace_back("random #" + std::to_string(i),
                            scene_random(d, densities[static_cast<std::size_t>(i) % 5], rng()));
    }
    World lattice(Dims{33, 21, 17});
    for (std::uint32_t z = 0; z < 17; z += 4) {
        for (std::uint32_t y = 1; y < 21; y += 6) {
            for (std::uint32_t x = 0; x < 33; x += 2 + z % 3) {
                lattice.set(x, y, z, 1);
            }
        }
    }
    worlds.emplace_back("lattice", lattice);
    // Solids at both ends of long y and z lines only (midpoints equally near two of them).
    World ends(Dims{18, 600, 2});
    World zends(Dims{5, 3, 700});
    for (std::uint32_t x = 0; x < 18; ++x) {
        ends.set(x, 0, x % 2, 1);
        ends.set(x, 598 + x % 2, 0, 1);
        zends.set(x % 5, x % 3, x % 2 == 0 ? 0 : 699, 1);
    }
    worlds.emplace_back("y ends", ends);
    worlds.emplace_back("z ends", zends);
    for (const auto& [name, w] : worlds) {
        for (Metric m : {Metric::manhattan, Metric::euclidean}) {
            for (Layout layout : kLayouts) {
                expect_scipy_ties(w, options(m, Spacing{}, false, Format::f32, layout, true), name);
                if (HasFatalFailure()) {
                    return;
                }
            }
        }
    }
    // Squared distances past 2^30: 64-bit partials (WIDE); rows of 33008 take the GPU layout's
    // banded passes with WIDE partials and keyed product tests.
    const World wide = scene_random(Dims{3, 33000, 1}, 0.3, rng());
    for (Layout layout : kLayouts) {
        expect_scipy_ties(
            wide, options(Metric::euclidean, Spacing{}, false, Format::f64, layout, true), "wide");
    }
    const World wide_rows = scene_random(Dims{33008, 3, 2}, 0.0005, rng());
    const auto banded_wide =
        options(Metric::euclidean, Spacing{}, false, Format::f64, Layout::gpu, true);
    ASSERT_EQ(ocl::ExactSeparable(pocl(), wide_rows, Palette(), banded_wide).variant(),
              "gpu layout, banded");
    expect_scipy_ties(wide_rows, banded_wide, "wide rows");
    expect_matches(wide_rows, Palette(), banded_wide, reference(wide_rows, banded_wide),
                   "wide rows field");
}

// Unit L1 with indices in the CPU layout (l1_xy_keys and l1_z_out; rows of 65535 or more
// take col_pass): the field in every unsigned format and SciPy's ties, on ragged and long
// axes, distances past 255 and past 65535 (u16 saturates), a world without solids (-1) and
// one of only solids; the same worlds' zero voxels as the targets.
TEST(ExactSeparable, ManhattanIndicesEveryFormatAndShape) {
    std::mt19937_64 rng(4242);
    std::vector<std::pair<std::string, World>> worlds;
    worlds.reserve(11);
    worlds.emplace_back("ragged", scene_random(Dims{37, 23, 19}, 0.01, rng()));
    worlds.emplace_back("dense", scene_random(Dims{48, 32, 16}, 0.6, rng()));
    worlds.emplace_back("empty", World(Dims{17, 9, 5}));
    World full(Dims{5, 6, 7});
    for (std::uint32_t z = 0; z < 7; ++z) {
        for (std::uint32_t y = 0; y < 6; ++y) {
            for (std::uint32_t x = 0; x < 5; ++x) {
                full.set(x, y, z, 3);
            }
        }
    }
    worlds.emplace_back("full", full);
    for (const Dims d : {Dims{4000, 1, 1}, Dims{1, 4000, 1}, Dims{1, 1, 4000}}) {
        World w(d);
        w.set(d.x / 3, d.y / 3, d.z / 3, 1);
        w.set(d.x - 1, d.y - 1, d.z - 1, 2);
        worlds.emplace_back("long " + d.to_string(), w);
    }
    // Rows of 1024 or more: ramps between at most 16 targets, the doubling past them.
    worlds.emplace_back("long rows", scene_random(Dims{1500, 3, 4}, 0.004, rng()));
    worlds.emplace_back("long dense rows", scene_random(Dims{1100, 2, 3}, 0.05, rng()));
    World far(Dims{300, 2, 400});
    far.set(0, 1, 0, 1);
    worlds.emplace_back("far", far);
    for (const auto& [name, w] : worlds) {
        const auto ref = reference_distance(w, Metric::manhattan, Spacing{});
        for (Format f :
             {Format::u8, Format::u16, Format::u32, Format::f32, Format::f64, Format::packed32}) {
            const auto o = options(Metric::manhattan, Spacing{}, false, f, Layout::cpu, true);
            const std::string what = name + " " + describe(o, w.dims());
            const auto r = ocl::generate(pocl(), w, Palette(), o);
            ASSERT_TRUE(r.bytes == encode_real_field(ref, w, Palette(), f)) << what;
            if (f == Format::u16) {
                expect_scipy_ties(w, o, name);
                if (HasFatalFailure()) {
                    return;
                }
            }
        }
    }
    // The zero voxels as the targets (voxfield.ndimage's cdt), read in place, with SciPy's
    // ties against the inverted world's reference.
    for (const auto& [name, w] : worlds) {
        const Dims d = w.dims();
        std::vector<std::uint8_t> inverted(w.voxels().size());
        for (std::size_t k = 0; k < inverted.size(); ++k) {
            inverted[k] = w.voxels()[k] == 0 ? 1 : 0;
        }
        const World targets(d, inverted);
        const auto ref = reference_features(targets, Metric::manhattan, Spacing{});
        const auto o = options(Metric::manhattan, Spacing{}, false, Format::u32, Layout::cpu, true);
        ocl::HostMemory field(d.count() * 4);
        std::vector<std::int32_t> planes(3 * d.count(), -7);
        {
            ocl::ExactSeparable job(pocl(), d, w.voxels(), Palette(), o,
                                    {field.data(), d.count() * 4}, planes, true);
            job.run();
            const ocl::MappedBuffer mapped(pocl(), job.field_buffer(), d.count() * 4);
            job.read_indices([](std::span<const std::uint8_t>) {});
        }
        const std::size_t n = d.count();
        const auto* got = reinterpret_cast<const std::uint32_t*>(field.data());
        for (std::size_t i = 0; i < n; ++i) {
            const std::int64_t f = ref[i];
            const std::int64_t want[3] = {f < 0 ? -1 : f / d.x / d.y, f < 0 ? -1 : f / d.x % d.y,
                                          f < 0 ? -1 : f % d.x};
            ASSERT_TRUE(planes[i] == want[0] && planes[n + i] == want[1] &&
                        planes[2 * n + i] == want[2])
                << "zero targets " << name << " voxel " << i;
            const long dist = f < 0 ? -1
                                    : std::labs(static_cast<long>(i % d.x) - want[2]) +
                                          std::labs(static_cast<long>(i / d.x % d.y) - want[1]) +
                                          std::labs(static_cast<long>(i / d.x / d.y) - want[0]);
            ASSERT_EQ(got[i], f < 0 ? 0xFFFFFFFFu : static_cast<std::uint32_t>(dist))
                << "zero targets " << name << " voxel " << i;
        }
    }
    // One axis past 16 bits (the reference's lines would take seconds): along z distances
    // past 65535 (u16 saturates), along x rows too long for the keys (col_pass); the solids
    // at `a` and `b` of the line, its midpoint a tie (the lower one wins).
    for (const auto& [d, a, b] :
         {std::tuple{Dims{1, 1, 70000}, 0u, 0u}, std::tuple{Dims{65540, 1, 1}, 7u, 65539u}}) {
        World w(d);
        const bool along_x = d.x > 1;
        w.set(along_x ? a : 0, 0, along_x ? 0 : a, 1);
        w.set(along_x ? b : 0, 0, along_x ? 0 : b, 1);
        for (Format f : {Format::u16, Format::u32}) {
            const auto r =
                ocl::generate(pocl(), w, Palette(),
                              options(Metric::manhattan, Spacing{}, false, f, Layout::cpu, true));
            const std::size_t n = d.count();
            ASSERT_EQ(r.indices.size(), 3 * n);
            for (std::uint32_t p = 0; p < n; ++p) {
                const std::uint32_t da = p > a ? p - a : a - p, db = p > b ? p - b : b - p;
                const std::uint32_t want = std::min(da, db);
                const double got = decode_value(r.bytes, f, p);
                ASSERT_EQ(got, f == Format::u16 ? std::min(want, 65535u) : want)
                    << d.to_string() << " " << to_string(f) << " voxel " << p;
                const std::int32_t s = static_cast<std::int32_t>(db < da ? b : a);
                ASSERT_TRUE(r.indices[p] == (along_x ? 0 : s) && r.indices[n + p] == 0 &&
                            r.indices[2 * n + p] == (along_x ? s : 0))
                    << d.to_string() << " voxel " << p;
            }
        }
    }
}

// The span constructor as voxfield.ndimage uses it: the world read in place with its zero
// voxels as the targets (zero_targets), the f64 field and the index planes written into the
// caller's memory by the z pass (no finish pass), on random grids of every density, against
// the reference of the inverted world (SciPy's ties included); the GPU layout takes the banded
// passes (x rows with the zero voxels as targets), or x_pass (its `solid` 0) and col_pass where
// rows are too long.
TEST(ExactSeparable, ZeroTargetsInPlaceFieldAndIndices) {
    std::mt19937_64 rng(2612);
    std::uniform_int_distribution<std::uint32_t> axis(1, 90);
    const double densities[] = {0.0, 0.001, 0.02, 0.3, 0.7, 0.98, 1.0};
    for (int i = 0; i < 15; ++i) {
        // #4: rows of 65535, past the banded passes' x (the GPU layout's x_pass and col_pass).
        const Dims d = i == 0   ? Dims{1, 1, 77}
                       : i == 1 ? Dims{1, 83, 1}
                       : i == 2 ? Dims{91, 1, 1}
                       : i == 3 ? Dims{64, 48, 1}
                       : i == 4 ? Dims{65535, 2, 1}
                                : Dims{axis(rng), axis(rng), axis(rng)};
        const World w = scene_random(d, densities[static_cast<std::size_t>(i) % 7], rng());
        std::vector<std::uint8_t> inverted(w.voxels().size());
        for (std::size_t k = 0; k < inverted.size(); ++k) {
            inverted[k] = w.voxels()[k] == 0 ? 1 : 0;
        }
        const World targets(d, inverted);
        const auto ref = reference_distance(targets, Metric::euclidean, Spacing{});
        const auto features = reference_features(targets, Metric::euclidean, Spacing{});
        for (bool indices : {false, true}) {
            for (Layout layout : kLayouts) {
                const auto o =
                    options(Metric::euclidean, Spacing{}, false, Format::f64, layout, indices);
                const std::string what = "zero targets #" + std::to_string(i) +
                                         (indices ? " indices " : " ") + describe(o, d);
                ocl::HostMemory field(d.count() * 8);
                std::vector<std::int32_t> planes(indices ? 3 * d.count() : 0, -7);
                {
                    ocl::ExactSeparable job(pocl(), d, w.voxels(), Palette(), o,
                                            {field.data(), d.count() * 8}, planes, true);
                    if (layout == Layout::gpu) {
                        ASSERT_EQ(job.variant(), i == 4 ? "gpu layout" : "gpu layout, banded")
                            << what;
                    }
                    job.run();
                    const ocl::MappedBuffer mapped(pocl(), job.field_buffer(), d.count() * 8);
                    ASSERT_EQ(mapped.bytes().data(), field.data()) << what;
                    if (indices) {
                        job.read_indices([](std::span<const std::uint8_t>) {});
                    }
                }
                const auto* got = reinterpret_cast<const double*>(field.data());
                const std::size_t n = d.count();
                for (std::size_t k = 0; k < n; ++k) {
                    // Bit for bit: the correctly rounded root of the exact squared distance.
                    ASSERT_EQ(got[k], ref[k]) << what << " voxel " << k;
                    if (!indices) {
                        continue;
                    }
                    const std::int32_t z = planes[k], y = planes[n + k], x = planes[2 * n + k];
                    if (std::isinf(ref[k])) {
                        ASSERT_TRUE(x == -1 && y == -1 && z == -1) << what << " voxel " << k;
                        continue;
                    }
                    ASSERT_TRUE(d.contains(x, y, z)) << what << " voxel " << k;
                    ASSERT_EQ(w.at(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y),
                                   static_cast<std::uint32_t>(z)),
                              0)
                        << what << " voxel " << k << " names a nonzero voxel";
                    const long px = static_cast<long>(k % d.x),
                               py = static_cast<long>(k / d.x % d.y),
                               pz = static_cast<long>(k / d.x / d.y);
                    ASSERT_EQ(metric_distance(Metric::euclidean, Spacing{}, px - x, py - y, pz - z),
                              ref[k])
                        << what << " voxel " << k;
                    // SciPy's ties: the nearest zero voxel of lowest (x, y, z).
                    ASSERT_EQ((static_cast<std::int64_t>(z) * d.y + y) * d.x + x, features[k])
                        << what << " voxel " << k;
                }
            }
        }
    }
    const World w = scene_random(Dims{5, 6, 7}, 0.2, 1);
    std::vector<std::int32_t> short_planes(10);
    ocl::HostMemory field(5 * 6 * 7 * 8);
    EXPECT_THROW(ocl::ExactSeparable(
                     pocl(), w.dims(), w.voxels(), Palette(),
                     options(Metric::euclidean, Spacing{}, false, Format::f64, Layout::cpu, true),
                     {field.data(), 5 * 6 * 7 * 8}, short_planes, true),
                 std::invalid_argument);
    EXPECT_THROW(
        ocl::ExactSeparable(pocl(), w.dims(), w.voxels(), Palette(),
                            options(Metric::euclidean, Spacing{}, true, Format::f32, Layout::cpu),
                            {}, {}, true),
        std::invalid_argument);
    for (Layout layout : kLayouts) {
        EXPECT_THROW(ocl::ExactSeparable(
                         pocl(), w.dims(), w.voxels(), Palette(),
                         options(Metric::euclidean, Spacing{}, true, Format::f32, layout, true)),
                     std::invalid_argument);
    }
}

// The streaming read hands the same bytes as the whole read, in order, in slabs of at most
// the size asked for (a last short one included), and survives a sink that throws.
TEST(ExactSeparable, IndicesStreamInSlabs) {
    std::mt19937_64 rng(7);
    const World w = scene_random(Dims{23, 17, 31}, 0.01, rng());
    const std::size_t bytes = 3 * w.dims().count() * sizeof(std::int32_t);
    for (Layout layout : kLayouts) {
        auto job = ocl::make_generator(
            pocl(), w, Palette(),
            options(Metric::euclidean, Spacing{}, false, Format::f32, layout, true));
        job->run();
        const std::vector<std::int32_t> whole = job->read_indices();
        ASSERT_EQ(whole.size() * sizeof(std::int32_t), bytes);
        const auto* want = reinterpret_cast<const std::uint8_t*>(whole.data());
        for (std::size_t slab : {std::size_t{60}, std::size_t{4096}, std::size_t{5000}, bytes - 1,
                                 bytes, ocl::Generator::kIndexSlabBytes}) {
            std::vector<std::uint8_t> got;
            std::size_t pieces = 0;
            job->read_indices(
                [&](std::span<const std::uint8_t> piece) {
                    ASSERT_LE(piece.size(), slab);
                    ASSERT_FALSE(piece.empty());
                    got.insert(got.end(), piece.begin(), piece.end());
                    ++pieces;
                },
                slab);
            ASSERT_EQ(got.size(), bytes) << "slab " << slab;
            EXPECT_TRUE(std::equal(got.begin(), got.end(), want)) << "slab " << slab;
            EXPECT_EQ(pieces, (bytes + slab - 1) / slab) << "slab " << slab;
        }
        int calls = 0;
        EXPECT_THROW(job->read_indices(
                         [&](std::span<const std::uint8_t>) {
                             if (++calls == 3) {
                                 throw std::runtime_error("sink failed");
                             }
                         },
                         1024),
                     std::runtime_error);
        EXPECT_EQ(calls, 3);
        EXPECT_EQ(job->read_indices(), whole) << "after a sink threw";
    }
    auto plain =
        ocl::make_generator(pocl(), w, Palette(),
                            options(Metric::euclidean, Spacing{}, false, Format::f32, Layout::cpu));
    EXPECT_THROW(plain->read_indices([](std::span<const std::uint8_t>) {}), std::logic_error);
}

TEST(ExactSeparable, BundledModels) {
    const std::filesystem::path dir = std::filesystem::path(VOXFIELD_DATA_DIR) / "vox";
    for (const char* file : {"chr_army1.vox", "veh_car1.vox", "obj_house4.vox"}) {
        const VoxModel model = load_world(dir / file);
        for (Metric m : {Metric::chebyshev, Metric::euclidean}) {
            const auto ref = reference_distance(model.world, m, Spacing{});
            const auto sref = reference_signed(model.world, m, Spacing{});
            for (Layout layout : kLayouts) {
                expect_matches(model.world, model.palette,
                               options(m, Spacing{}, false, float_or(m, Spacing{}, false), layout),
                               ref, file);
                expect_matches(model.world, model.palette,
                               options(m, Spacing{}, true, float_or(m, Spacing{}, true), layout),
                               sref, file);
            }
        }
        for (Layout layout : kLayouts) {
            expect_matches(model.world, model.palette,
                           options(Metric::manhattan, Spacing{}, true, Format::i16, layout),
                           reference_signed(model.world, Metric::manhattan, Spacing{}), file);
        }
    }
}

// The GPU layout's full transforms at unit spacing run the banded passes
// (cols_banded): long lines (many sites per band), sparse lines (bands without a site), rows
// without any solid, and lines shorter than the bands, every metric and an integer and a
// float format.
// Unsigned, and signed: a second banded transform whose targets are the empty voxels and the
// space around the world (mostly solid worlds, a full one, an empty one, a single voxel). The
// feature transform too: the banded passes carrying the sites' keys (SciPy's ties for L1 and
// L2, a nearest solid for L-inf).
TEST(ExactSeparable, BandedGpuPassesMatchTheReference) {
    std::mt19937_64 rng(1234);
    // The ninth shape's rows are too long for x_rows_local's local memory on PoCL (x_rows_long),
    // the tenth's for a work-group of x_rows_map (its chunks).
    const Dims shapes[] = {{48, 181, 97}, {3, 260, 5},  {70, 2, 300}, {16, 64, 64},  {33, 41, 29},
                           {29, 17, 40},  {20, 30, 25}, {1, 1, 1},    {60001, 2, 3}, {32784, 3, 2}};
    const double densities[] = {0.0004, 0.02, 0.5, 0.0004, 0.97, 1.0, 0.0, 1.0, 0.0001, 0.0003};
    for (std::size_t i = 0; i < std::size(shapes); ++i) {
        const World w = scene_random(shapes[i], densities[i], rng());
        for (Metric m : kMetrics) {
            for (bool sgn : {false, true}) {
                for (Format f : {sgn ? Format::i16 : Format::u16, Format::f32}) {
                    auto o = options(m, Spacing{}, sgn, f, Layout::gpu);
                    std::vector<double> ref = reference(w, o);
                    if (m == Metric::manhattan) {
                        o.max_distance = 1e6;  // through ExactSeparable, not exact_manhattan.cl
                        for (double& v : ref) {
                            v = std::clamp(v, -1e6, 1e6);
                        }
                    }
                    ocl::ExactSeparable g(pocl(), w, Palette(), o);
                    ASSERT_EQ(g.variant(), "gpu layout, banded") << describe(o, w.dims());
                    expect_matches(w, Palette(), o, ref, "banded #" + std::to_string(i));
                    if (::testing::Test::HasFailure()) {
                        return;
                    }
                }
            }
            const auto o = options(m, Spacing{}, false, Format::f32, Layout::gpu, true);
            ocl::ExactSeparable g(pocl(), w, Palette(), o);
            ASSERT_EQ(g.variant(), "gpu layout, banded") << describe(o, w.dims()) << " indices";
            const std::string what = "banded indices #" + std::to_string(i);
            if (m == Metric::chebyshev) {
                expect_indices(w, o, what);
            } else {
                expect_scipy_ties(w, o, what);
            }
            // The z pass finds its sites' partials from the y pass's targets: unit partials are
            // exact, so the field is the one without indices byte for byte.
            ASSERT_EQ(ocl::generate(pocl(), w, Palette(), o).bytes,
                      ocl::generate(pocl(), w, Palette(),
                                    options(m, Spacing{}, false, Format::f32, Layout::gpu))
                          .bytes)
                << what << " field";
            if (::testing::Test::HasFailure()) {
                return;
            }
        }
    }
}

// With spacing (float partials, double for f64 fields; the x rows' distances scaled by the x
// spacing, the signed border by each axis's): every metric, unsigned, signed and indices,
// within rounding of the reference.
TEST(ExactSeparable, BandedGpuPassesTakeSpacing) {
    std::mt19937_64 rng(4321);
    const Dims shapes[] = {{48, 181, 37}, {3, 60, 5}, {40, 2, 100}, {23, 17, 29}, {1, 1, 1}};
    const double densities[] = {0.002, 0.05, 0.5, 0.97, 1.0};
    const Spacing spacings[] = {{1.5, 0.75, 2.0}, {0.05, 0.05, 0.05}, {1.0, 3.0, 0.5}};
    for (std::size_t i = 0; i < std::size(shapes); ++i) {
        const World w = scene_random(shapes[i], densities[i], rng());
        for (const Spacing& sp : spacings) {
            for (Metric m : kMetrics) {
                const std::string what = "banded spacing #" + std::to_string(i);
                for (bool sgn : {false, true}) {
                    for (Format f : {Format::f32, Format::f64}) {
                        const auto o = options(m, sp, sgn, f, Layout::gpu);
                        ocl::ExactSeparable g(pocl(), w, Palette(), o);
                        ASSERT_EQ(g.variant(), "gpu layout, banded") << describe(o, w.dims());
                        expect_matches(w, Palette(), o, reference(w, o), what);
                    }
                }
                for (Format f : {Format::f32, Format::f64}) {
                    const auto o = options(m, sp, false, f, Layout::gpu, true);
                    ASSERT_EQ(ocl::ExactSeparable(pocl(), w, Palette(), o).variant(),
                              "gpu layout, banded");
                    expect_indices(w, o, what + " indices");
                    // The z pass finds its sites' partials from the y pass's targets: the
                    // field within rounding of the reference (ties between sites may round
                    // apart, so not always the field without indices byte for byte).
                    expect_matches(w, Palette(), o, reference(w, o), what + " indices field");
                }
                if (::testing::Test::HasFailure()) {
                    return;
                }
            }
        }
    }
}

// A signed field's solids take the space around the world as empty: along x too where a row
// holds one voxel (the CPU layout's row_doubling once took no step there, so that a solid of a
// world one voxel wide was as far from its outside as its y neighbours). With the x spacing
// the smallest, the outside along x is the nearest empty space.
TEST(ExactSeparable, RowsOfOneVoxelSeeTheOutsideAlongX) {
    World lone(Dims{1, 50, 1});
    lone.set(0, 20, 0, 1);
    const World worlds[] = {lone, scene_random(Dims{1, 9, 7}, 0.3, 5),
                            scene_random(Dims{1, 1, 40}, 0.2, 6)};
    const Spacing spacings[] = {{0.5, 1.0, 2.0}, {0.25, 3.0, 1.0}};
    for (const World& w : worlds) {
        for (const Spacing& sp : spacings) {
            for (Metric m : kMetrics) {
                for (Layout layout : {Layout::cpu, Layout::gpu}) {
                    const auto o = options(m, sp, true, Format::f32, layout);
                    expect_matches(
                        w, Palette(), o, reference(w, o),
                        layout == Layout::cpu ? "one-voxel rows, cpu" : "one-voxel rows, gpu");
                }
            }
        }
    }
    const auto o = options(Metric::euclidean, spacings[0], true, Format::f32, Layout::cpu);
    const auto field = ocl::generate(pocl(), lone, Palette(), o).bytes;
    float v = 0;
    std::memcpy(&v, field.data() + 20 * sizeof(float), sizeof v);
    EXPECT_EQ(v, -0.5f);
}

// Lines longer than the banded passes' local memory holds (kBandedLocalCap, 64 KiB): that
// pass keeps its lists in global memory (cols_banded built with BANDED_GLOBAL), the other pass
// its own in local memory. Long z lines, long y lines (their 2-byte x rows do not fit), and
// long y lines that fit only without index planes (the y pass's target x takes 2 bytes more):
// every metric, unsigned and signed, unit spacing and not, indices.
TEST(ExactSeparable, BandedGlobalListsMatchTheReference) {
    std::mt19937_64 rng(8642);
    struct Case {
        Dims dims;
        double density;
        const char* global;          // the stage with global lists
        const char* global_indices;  // the same with index planes
    };
    const Case cases[] = {
        {{3, 2, 17000}, 0.002, "z_banded_global", "z_banded_global"},
        {{2, 33000, 2}, 0.001, "y_banded_global", "y_banded_global"},
        {{3, 17000, 2}, 0.3, nullptr, "y_banded_global"},
        {{1, 1, 20000}, 0.0, "z_banded_global", "z_banded_global"},
    };
    const auto stage_names = [](ocl::ExactSeparable& g) {
        g.run();
        std::string names;
        for (const auto& [name, ms] : g.stage_ms()) {
            names += name + " ";
        }
        return names;
    };
    for (const Case& c : cases) {
        const World w = scene_random(c.dims, c.density, rng());
        const std::string what = "global lists " + c.dims.to_string();
        for (const Spacing& sp : {Spacing{}, Spacing{1.5, 0.75, 2.0}}) {
            for (Metric m : kMetrics) {
                for (bool sgn : {false, true}) {
                    auto o = options(m, sp, sgn, Format::f32, Layout::gpu);
                    std::vector<double> ref = reference(w, o);
                    if (m == Metric::manhattan && sp.unit()) {
                        o.max_distance = 1e6;  // through ExactSeparable, not exact_manhattan.cl
                        for (double& v : ref) {
                            v = std::clamp(v, -1e6, 1e6);
                        }
                    }
                    ocl::ExactSeparable g(pocl(), w, Palette(), o);
                    ASSERT_EQ(g.variant(), "gpu layout, banded") << describe(o, w.dims());
                    const std::string names = stage_names(g);
                    if (c.global != nullptr) {
                        EXPECT_NE(names.find(c.global), std::string::npos)
                            << describe(o, w.dims()) << ": " << names;
                    } else {
                        EXPECT_EQ(names.find("global"), std::string::npos)
                            << describe(o, w.dims()) << ": " << names;
                    }
                    expect_matches(w, Palette(), o, ref, what);
                }
                const auto o = options(m, sp, false, Format::f32, Layout::gpu, true);
                ocl::ExactSeparable g(pocl(), w, Palette(), o);
                EXPECT_NE(stage_names(g).find(c.global_indices), std::string::npos)
                    << describe(o, w.dims()) << " indices";
                if (m == Metric::chebyshev || !sp.unit()) {
                    expect_indices(w, o, what + " indices");
                } else {
                    expect_scipy_ties(w, o, what + " indices");
                }
                if (::testing::Test::HasFailure()) {
                    return;
                }
            }
        }
    }
}

// L2 with spacing along lines of thousands of voxels: a separator's tie point there keeps few
// bits below the point in float, so each separator is checked against the partials at its
// integer positions (l2_sep). Without that check the 3 x 2 x 17000 world was 0.0125 voxels off
// at distance 90 (1.4e-4 relative) in both layouts, and its signed field -2 for -0.75.
TEST(ExactSeparable, LongLinesWithSpacingMatchTheReference) {
    std::mt19937_64 rng(97531);
    for (const Dims d : {Dims{3, 2, 17000}, Dims{2, 17000, 3}}) {
        const World w = scene_random(d, 0.002, rng());
        for (const Spacing& sp : {Spacing{1.5, 0.75, 2.0}, Spacing{0.3, 0.7, 0.1}}) {
            for (Layout layout : kLayouts) {
                for (bool sgn : {false, true}) {
                    for (Format f : {Format::f32, Format::f64}) {
                        const auto o = options(Metric::euclidean, sp, sgn, f, layout);
                        expect_matches(w, Palette(), o, reference(w, o), "long lines");
                    }
                }
                expect_indices(w, options(Metric::euclidean, sp, false, Format::f32, layout, true),
                               "long lines indices");
                if (::testing::Test::HasFailure()) {
                    return;
                }
            }
        }
    }
}

// Spacings a million apart: an L1 separator's tie point (gu - gi + s (u + i)) / (2 s) sums the
// partials' difference (thousandths) with s (u + i) (tens of thousands), whose float sum loses
// it, so that its floor alone gave a z position to the farther of two sites (1000.010 for
// 1000.009 below). Every metric, both layouts, f32 and f64, signed too.
TEST(ExactSeparable, SpacingsOfFarApartScales) {
    World pair(Dims{20, 1, 21});
    pair.set(0, 0, 18, 1);
    pair.set(19, 0, 20, 1);
    std::mt19937_64 rng(1357);
    const World worlds[] = {pair, scene_random(Dims{71, 53, 37}, 0.0005, rng()),
                            scene_random(Dims{33, 40, 45}, 0.01, rng())};
    for (const Spacing& sp : {Spacing{1e-3, 1.0, 1e3}, Spacing{1e3, 1e-3, 1.0}}) {
        for (std::size_t i = 0; i < std::size(worlds); ++i) {
            for (Metric m : kMetrics) {
                for (Layout layout : kLayouts) {
                    for (bool sgn : {false, true}) {
                        for (Format f : {Format::f32, Format::f64}) {
                            const auto o = options(m, sp, sgn, f, layout);
                            expect_matches(worlds[i], Palette(), o, reference(worlds[i], o),
                                           "far apart scales #" + std::to_string(i));
                        }
                    }
                    if (::testing::Test::HasFailure()) {
                        return;
                    }
                }
            }
        }
    }
}

TEST(ExactSeparable, StackedBlocksTakeTheirOwnZLines) {
    // A z period (a sparse field's batch of blocks stacked along z): every block's field is
    // the field of that block alone, byte for byte, its borders and bounds at its own z ends;
    // the blocks are an empty one, a full one and random ones.
    constexpr std::uint32_t kP = 37;
    const Dims block{23, 19, kP};
    const double densities[] = {0.02, 0.0, 1.0, 0.3, 0.001};
    const std::uint32_t blocks = std::size(densities);
    // Blocks stacked along z lie one after another in memory.
    std::vector<World> alone;
    std::vector<std::uint8_t> voxels;
    for (std::uint32_t b = 0; b < blocks; ++b) {
        alone.push_back(scene_random(block, densities[b], 77 + b));
        voxels.insert(voxels.end(), alone.back().voxels().begin(), alone.back().voxels().end());
    }
    const World stacked(Dims{block.x, block.y, kP * blocks}, std::move(voxels));
    for (Metric m : kMetrics) {
        for (const Spacing& sp : {Spacing{}, Spacing{1.5, 0.75, 2.0}}) {
            for (bool sgn : {false, true}) {
                for (std::optional<double> bound : {std::optional<double>(), std::optional(5.0)}) {
                    auto o = options(m, sp, sgn, Format::f32, Layout::gpu);
                    // L1 through ExactSeparable (a bound), not exact_manhattan.cl.
                    o.max_distance = m == Metric::manhattan && !bound ? 1e6 : bound;
                    ocl::ExactSeparable g(pocl(), stacked, Palette(), o, false, kP);
                    ASSERT_EQ(g.variant(), "gpu layout, banded") << describe(o, stacked.dims());
                    g.run();
                    const auto got = g.read();
                    for (std::uint32_t b = 0; b < blocks; ++b) {
                        const auto want = ocl::generate(pocl(), alone[b], Palette(), o).bytes;
                        ASSERT_TRUE(
                            std::equal(want.begin(), want.end(), got.begin() + b * want.size()))
                            << describe(o, stacked.dims()) << " block " << b;
                    }
                }
            }
        }
    }
    auto o = options(Metric::euclidean, Spacing{}, false, Format::f32, Layout::gpu);
    EXPECT_THROW(ocl::ExactSeparable(pocl(), stacked, Palette(), o, false, kP + 1),
                 std::invalid_argument);
    EXPECT_THROW(ocl::ExactSeparable(pocl(), stacked, Palette(), o, true, kP),
                 std::invalid_argument);
    o.indices = true;
    EXPECT_THROW(ocl::ExactSeparable(pocl(), stacked, Palette(), o, false, kP),
                 std::invalid_argument);
}

TEST(ExactSeparable, RefusesBadCombinations) {
    const World w = scene_random(Dims{8, 8, 8}, 0.1, 1);
    auto o = options(Metric::euclidean, Spacing{}, true, Format::u16, Layout::cpu);
    EXPECT_THROW(ocl::generate(pocl(), w, Palette(), o), InputError);
    o = options(Metric::euclidean, Spacing{}, true, Format::f32, Layout::cpu, true);
    EXPECT_THROW(ocl::generate(pocl(), w, Palette(), o), InputError);
    o = options(Metric::chebyshev, Spacing{}, false, Format::u16, Layout::cpu);
    o.algorithm = ocl::Algorithm::fim;
    EXPECT_THROW(ocl::generate(pocl(), w, Palette(), o), InputError);
    for (double bad : {0.0, -1.0, std::nan("")}) {
        o = options(Metric::euclidean, Spacing{}, false, Format::f32, Layout::cpu);
        o.max_distance = bad;
        EXPECT_THROW(ocl::generate(pocl(), w, Palette(), o), InputError) << bad;
    }
}

}  // namespace
}  // namespace voxfield
