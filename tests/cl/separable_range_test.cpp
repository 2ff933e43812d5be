// ExactSeparable at the edges of its range: long axes (46342 voxels, where unit-spacing L2
// squares pass 2^31) in each direction, and f64 fields with spacing, whose scans run in double
// and must stay within 2 ulp of a float64 reference.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <random>
#include <string>

#include "cl_test_util.hpp"
#include "voxfield/cl/separable.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/scenes.hpp"

namespace voxfield {
namespace {

using ocl::Layout;
using test::pocl;

const Metric kMetrics[] = {Metric::manhattan, Metric::chebyshev, Metric::euclidean};
const Layout kLayouts[] = {Layout::cpu, Layout::gpu};

ocl::GeneratorOptions options(Metric m, const Spacing& s, Format f, Layout layout,
                              bool signed_field = false) {
    ocl::GeneratorOptions o;
    o.metric = m;
    o.spacing = s;
    o.format = f;
    o.layout = layout;
    o.signed_field = signed_field;
    o.max_distance.reset();
    return o;
}

std::string describe(const ocl::GeneratorOptions& o, Dims d) {
    return to_string(o.metric) + " spacing " + o.spacing.to_string() +
           (o.signed_field ? " signed" : "") + " format " + to_string(o.format) + " layout " +
           (o.layout == Layout::cpu ? "cpu" : "gpu") + " world " + d.to_string();
}

// Ulps between two doubles of the same sign (0 when equal).
std::uint64_t ulps(double a, double b) {
    if (a == b) {
        return 0;
    }
    if (std::signbit(a) != std::signbit(b) || std::isinf(a) || std::isinf(b)) {
        return UINT64_MAX;
    }
    std::int64_t ia = 0, ib = 0;
    std::memcpy(&ia, &a, sizeof a);
    std::memcpy(&ib, &b, sizeof b);
    return static_cast<std::uint64_t>(ia > ib ? ia - ib : ib - ia);
}

// f64 values within `max_ulps` of the float64 `ref`; other formats as the reference encodes
// them (unit spacing: exact).
void expect_field(const World& w, const ocl::GeneratorOptions& o, const std::vector<double>& ref,
                  std::uint64_t max_ulps, const std::string& what) {
    const auto got = ocl::generate(pocl(), w, Palette(), o).bytes;
    const auto want = encode_real_field(ref, w, Palette(), o.format);
    ASSERT_EQ(got.size(), want.size()) << what;
    const Dims d = w.dims();
    for (std::size_t i = 0; i < ref.size(); ++i) {
        const double a = decode_value(got, o.format, i);
        const double b = decode_value(want, o.format, i);
        const bool ok = o.format == Format::f64 ? ulps(a, ref[i]) <= max_ulps : a == b;
        if (!ok) {
            FAIL() << what << " " << describe(o, d) << ": voxel (" << i % d.x << ","
                   << i / d.x % d.y << "," << i / d.x / d.y << ") got " << a << ", want " << b
                   << " (exact " << ref[i] << ", " << ulps(a, ref[i]) << " ulp)";
        }
    }
}

// A line of n voxels along `axis` (0 x, 1 y, 2 z).
Dims line_dims(int axis, std::uint32_t n) {
    return {axis == 0 ? n : 1u, axis == 1 ? n : 1u, axis == 2 ? n : 1u};
}

constexpr std::uint32_t kLong = 46342;  // 46341^2 > 2^31: unit L2 squares overflow an int

// One solid at the line's start: every voxel's distance is its offset times the spacing,
// up to 46341 voxels (L2 squared 2147488281, past INT_MAX), in every metric and direction.
TEST(ExactSeparableRange, LongAxesWithOneSolidAtTheEnd) {
    for (int axis = 0; axis < 3; ++axis) {
        const Dims d = line_dims(axis, kLong);
        World w(d);
        w.set(0, 0, 0, 1);
        for (const Spacing& s : {Spacing{}, Spacing{0.75, 1.5, 0.5}}) {
            const double step = axis == 0 ? s.x : axis == 1 ? s.y : s.z;
            std::vector<double> ref(d.count());
            for (std::size_t i = 0; i < ref.size(); ++i) {
                ref[i] = static_cast<double>(i) * step;
            }
            for (Metric m : kMetrics) {
                for (Layout layout : kLayouts) {
                    for (Format f : {Format::f32, Format::f64, Format::u32}) {
                        if (f == Format::u32 && !s.unit() && m == Metric::euclidean) {
                            continue;  // float squares may round below an integer distance
                        }
                        expect_field(w, options(m, s, f, layout), ref, 0,
                                     "one solid, axis " + std::to_string(axis));
                        if (HasFailure()) {
                            return;
                        }
                    }
                }
            }
        }
    }
}

// Sparse random solids on the long lines against the CPU reference, unsigned and signed.
TEST(ExactSeparableRange, LongAxesMatchTheReference) {
    std::mt19937_64 rng(46342);
    for (int axis = 0; axis < 3; ++axis) {
        const Dims d = line_dims(axis, kLong);
        const World w = scene_random(d, 0.0003, rng());
        for (const Spacing& s : {Spacing{}, Spacing{0.75, 1.5, 0.5}}) {
            for (Metric m : kMetrics) {
                for (bool sgn : {false, true}) {
                    const auto ref = sgn ? reference_signed(w, m, s) : reference_distance(w, m, s);
                    for (Layout layout : kLayouts) {
                        expect_field(w, options(m, s, Format::f64, layout, sgn), ref, 2,
                                     "random, axis " + std::to_string(axis));
                        if (HasFailure()) {
                            return;
                        }
                    }
                }
            }
        }
    }
}

// Plane worlds with two long axes: the per-pass scratch (a 4000 x 4000 plane used to need
// 136 bytes x 4000^2 of it) and the unit-spacing L2 squares past 2^30 in 64 bits.
TEST(ExactSeparableRange, LongPlanes) {
    std::mt19937_64 rng(4000);
    for (const Dims d : {Dims{1, 4000, 300}, Dims{300, 4000, 1}, Dims{5, 33000, 2}}) {
        const World w = scene_random(d, d.y > 4000 ? 0.0005 : 0.002, rng());
        for (Metric m : {Metric::euclidean, Metric::chebyshev}) {
            const auto ref = reference_distance(w, m, Spacing{});
            expect_field(w, options(m, Spacing{}, Format::f64, Layout::cpu), ref, 0,
                         "plane " + d.to_string());
            if (HasFailure()) {
                return;
            }
        }
    }
}

// f64 fields with spacing: the scans in double, within 2 ulp of the float64 reference, in
// every metric, unsigned and signed, both layouts, with and without a bound.
TEST(ExactSeparableRange, F64WithSpacingIsWithinTwoUlp) {
    std::mt19937_64 rng(64);
    std::uniform_int_distribution<std::uint32_t> axis(1, 60);
    std::uniform_real_distribution<double> sp(0.1, 7.0);
    const double densities[] = {0.001, 0.01, 0.1, 0.5};
    for (int i = 0; i < 8; ++i) {
        const World w = scene_random(Dims{axis(rng), axis(rng), axis(rng)},
                                     densities[static_cast<std::size_t>(i) % 4], rng());
        const Spacing s{sp(rng), sp(rng), sp(rng)};
        for (Metric m : kMetrics) {
            for (bool sgn : {false, true}) {
                const auto ref = sgn ? reference_signed(w, m, s) : reference_distance(w, m, s);
                for (Layout layout : kLayouts) {
                    expect_field(w, options(m, s, Format::f64, layout, sgn), ref, 2,
                                 "random #" + std::to_string(i));
                    if (HasFailure()) {
                        return;
                    }
                }
            }
        }
    }
}

// Spacings whose float rounding differs from double's: 0.1 and 1/3 are inexact in both, and
// the float scans were off by up to 1.4e-7 relative.
TEST(ExactSeparableRange, F64ResolvesWhatFloatCannot) {
    const World w = scene_random(Dims{40, 37, 45}, 0.002, 7);
    const Spacing s{0.1, 1.0 / 3.0, 2.7};
    const auto ref = reference_distance(w, Metric::euclidean, s);
    for (Layout layout : kLayouts) {
        expect_field(w, options(Metric::euclidean, s, Format::f64, layout), ref, 2, "inexact");
    }
}

// Indices on a long line name the nearest solid (64-bit squares).
TEST(ExactSeparableRange, IndicesOnALongLine) {
    World w(line_dims(1, kLong));
    w.set(0, 0, 0, 1);
    w.set(0, kLong - 1, 0, 1);
    auto o = options(Metric::euclidean, Spacing{}, Format::f64, Layout::cpu);
    o.indices = true;
    for (Layout layout : kLayouts) {
        o.layout = layout;
        const auto r = ocl::generate(pocl(), w, Palette(), o);
        const std::size_t n = kLong;
        ASSERT_EQ(r.indices.size(), 3 * n);
        for (std::size_t y = 0; y < n; ++y) {
            const std::int32_t want = y <= (n - 1) / 2 ? 0 : static_cast<std::int32_t>(n - 1);
            ASSERT_EQ(r.indices[n + y], want) << "y " << y;
            ASSERT_EQ(r.indices[y], 0);
            ASSERT_EQ(r.indices[2 * n + y], 0);
        }
    }
}

}  // namespace
}  // namespace voxfield
