// Implicit parts (.sdf.json): parser errors, every primitive and operator against closed forms,
// materials, interval soundness, gradients, and the solid world against brute-force sampling.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <numbers>
#include <random>
#include <sstream>
#include <string>

#include "sdf_random.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/sdf.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield::sdf {
namespace {

Part part_of(const std::string& shape, double h = 0.1) {
    std::ostringstream hs;
    hs << std::setprecision(17) << h;
    return parse_part(R"({"version": 1, "voxel_size": )" + hs.str() +
                          R"(, "bounds": [[-2, -2, -2], [2, 2, 2]], "shape": )" + shape + "}",
                      "test");
}

float f(const Part& p, double x, double y, double z) {
    return evaluate(p.tape, Vec3{float(x), float(y), float(z)});
}

double len(double x, double y, double z) {
    return std::sqrt(x * x + y * y + z * z);
}

constexpr double kTol = 2e-6;

TEST(SdfPrimitive, Sphere) {
    const Part p = part_of(R"({"sphere": {"center": [0.5, -0.25, 0.1], "radius": 0.75}})");
    std::mt19937 rng(1);
    std::uniform_real_distribution<double> u(-2, 2);
    for (int i = 0; i < 200; ++i) {
        const double x = u(rng), y = u(rng), z = u(rng);
        EXPECT_NEAR(f(p, x, y, z), len(x - 0.5, y + 0.25, z - 0.1) - 0.75, kTol);
    }
}

double box_sd(double x, double y, double z, double sx, double sy, double sz) {
    const double qx = std::abs(x) - sx, qy = std::abs(y) - sy, qz = std::abs(z) - sz;
    return len(std::max(qx, 0.0), std::max(qy, 0.0), std::max(qz, 0.0)) +
           std::min(std::max({qx, qy, qz}), 0.0);
}

TEST(SdfPrimitive, BoxAndRoundBox) {
    const Part b = part_of(R"({"box": {"center": [0.1, 0.2, 0.3], "half_size": [0.5, 0.25, 1]}})");
    const Part r = part_of(
        R"({"round_box": {"center": [0.1, 0.2, 0.3], "half_size": [0.5, 0.25, 1], "radius": 0.2}})");
    // Closed form values at chosen points: outside a face, an edge, a corner, inside.
    EXPECT_NEAR(f(b, 1.1, 0.2, 0.3), 0.5, kTol);
    EXPECT_NEAR(f(b, 0.1, 0.2, 0.3), -0.25, kTol);
    EXPECT_NEAR(f(b, 0.9, 0.75, 0.3), std::sqrt(0.3 * 0.3 + 0.3 * 0.3), kTol);
    EXPECT_NEAR(f(b, 1.6, 1.45, 2.3), len(1, 1, 1), kTol);
    EXPECT_NEAR(f(r, 0.1, 0.2, 0.3), -0.25, kTol);
    // The rounded corner: the corner of the inner box (0.3, 0.05, 0.8) plus the radius.
    EXPECT_NEAR(f(r, 0.1 + 0.3 + 1, 0.2 + 0.05 + 1, 0.3 + 0.8 + 1), len(1, 1, 1) - 0.2, kTol);
    std::mt19937 rng(2);
    std::uniform_real_distribution<double> u(-2, 2);
    for (int i = 0; i < 200; ++i) {
        const double x = u(rng), y = u(rng), z = u(rng);
        EXPECT_NEAR(f(b, x, y, z), box_sd(x - 0.1, y - 0.2, z - 0.3, 0.5, 0.25, 1), kTol);
        EXPECT_NEAR(f(r, x, y, z), box_sd(x - 0.1, y - 0.2, z - 0.3, 0.3, 0.05, 0.8) - 0.2, kTol);
    }
}

TEST(SdfPrimitive, CylinderTorusCapsulePlane) {
    const Part c =
        part_of(R"({"cylinder": {"center": [0, 0.5, 0], "radius": 0.5, "half_height": 1}})");
    const Part t = part_of(R"({"torus": {"center": [0, 0, 0.2], "major": 1, "minor": 0.25}})");
    const Part k = part_of(R"({"capsule": {"a": [-1, 0, 0], "b": [1, 0, 0], "radius": 0.3}})");
    const Part pl = part_of(R"({"plane": {"normal": [0, 2, 0], "offset": 0.5}})");
    EXPECT_NEAR(f(c, 1.5, 0.5, 0), 1.0, kTol);           // side
    EXPECT_NEAR(f(c, 0, 2, 0), 0.5, kTol);               // cap (axis y)
    EXPECT_NEAR(f(c, 0, 0.5, 0), -0.5, kTol);            // inside: the nearer side
    EXPECT_NEAR(f(c, 1.5, 2.5, 0), len(1, 1, 0), kTol);  // rim
    EXPECT_NEAR(f(t, 1, 0, 0.2), -0.25, kTol);           // tube centre (x-z plane)
    EXPECT_NEAR(f(t, 0, 0, 1.7), 0.25, kTol);
    EXPECT_NEAR(f(t, 0, 1, 0.2), len(1, 1, 0) - 0.25, kTol);
    EXPECT_NEAR(f(k, 0, 1, 0), 0.7, kTol);
    EXPECT_NEAR(f(k, 2, 0, 0), 0.7, kTol);  // past the end: distance to b
    EXPECT_NEAR(f(k, -2, 1, 0), len(1, 1, 0) - 0.3, kTol);
    EXPECT_NEAR(f(pl, 0.3, 1.5, -0.7), 1.0, kTol);  // normal normalised
    EXPECT_NEAR(f(pl, 0, -0.5, 0), -1.0, kTol);
}

TEST(SdfOperator, BooleansSmoothAndShell) {
    const std::string a = R"({"sphere": {"center": [-0.3, 0, 0], "radius": 0.5}})";
    const std::string b = R"({"sphere": {"center": [0.3, 0, 0], "radius": 0.5}})";
    const Part u = part_of(R"({"union": [)" + a + "," + b + "]}");
    const Part i = part_of(R"({"intersection": [)" + a + "," + b + "]}");
    const Part d = part_of(R"({"difference": [)" + a + "," + b + "]}");
    const Part su = part_of(R"({"smooth_union": {"k": 0.4, "of": [)" + a + "," + b + "]}}");
    const Part sd = part_of(R"({"smooth_difference": {"k": 0.4, "of": [)" + a + "," + b + "]}}");
    const Part sh = part_of(R"({"shell": {"thickness": 0.1, "of": )" + a + "}}");
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> r(-2, 2);
    auto smin = [](double x, double y, double k) {
        const double h = std::max(k - std::abs(x - y), 0.0) / k;
        return std::min(x, y) - h * h * k / 4;
    };
    for (int n = 0; n < 300; ++n) {
        const double x = r(rng), y = r(rng), z = r(rng);
        const double fa = len(x + 0.3, y, z) - 0.5, fb = len(x - 0.3, y, z) - 0.5;
        EXPECT_NEAR(f(u, x, y, z), std::min(fa, fb), kTol);
        EXPECT_NEAR(f(i, x, y, z), std::max(fa, fb), kTol);
        EXPECT_NEAR(f(d, x, y, z), std::max(fa, -fb), kTol);
        EXPECT_NEAR(f(su, x, y, z), smin(fa, fb, 0.4), kTol);
        EXPECT_NEAR(f(sd, x, y, z), -smin(-fa, fb, 0.4), kTol);
        EXPECT_NEAR(f(sh, x, y, z), std::abs(fa) - 0.1, kTol);
    }
    // Where the spheres meet (origin): fa = fb = -0.2, h = 1, so smin = -0.2 - 0.1.
    EXPECT_NEAR(f(su, 0, 0, 0), -0.3, kTol);
}

TEST(SdfOperator, TransformRotatesXThenYThenZ) {
    // A box long in x, rotated 90 degrees about x (no change to the x extent), then about z:
    // R = Rz(90) Ry(0) Rx(90): the x axis goes to y. Scale 2, then translated.
    const Part p = part_of(R"({"transform": {"translate": [0.2, 0.1, 0], "rotate_deg": [90, 0, 90],
        "scale": 0.5, "of": {"box": {"center": [0, 0, 0], "half_size": [1, 0.2, 0.4]}}}})");
    // Rx(90): (x, y, z) -> (x, -z, y); then Rz(90): (x, y, z) -> (-y, x, z). So the box's axis
    // x (half 1 * 0.5) points along world y, its y (0.2 * 0.5) along world z, its z (0.4 * 0.5)
    // along world x.
    std::mt19937 rng(4);
    std::uniform_real_distribution<double> u(-1.5, 1.5);
    for (int n = 0; n < 300; ++n) {
        const double x = u(rng), y = u(rng), z = u(rng);
        const double dx = x - 0.2, dy = y - 0.1, dz = z;
        EXPECT_NEAR(f(p, x, y, z), box_sd(dx, dy, dz, 0.2, 0.5, 0.1), 4e-6);
    }
    // R = Rz Ry Rx applied in that order (x first): a point on the local x axis, rotated by
    // x = 90 (stays), then y = 90 (x -> -z), then z = 90 (-z stays -z).
    const Part q = part_of(R"({"transform": {"rotate_deg": [90, 90, 90],
        "of": {"sphere": {"center": [1, 0, 0], "radius": 0.1}}}})");
    EXPECT_NEAR(f(q, 0, 0, -1), -0.1, kTol);
}

TEST(SdfMaterial, UnionNearestDifferenceKeepsA) {
    const Part p = part_of(R"({"difference": [
        {"union": [{"sphere": {"center": [-0.5, 0, 0], "radius": 0.6}, "material": 3},
                   {"box": {"center": [0.5, 0, 0], "half_size": [0.5, 0.5, 0.5]}}],
         "material": 7},
        {"sphere": {"center": [0, 1, 0], "radius": 0.3}, "material": 9}]})");
    EXPECT_EQ(evaluate_material(p.tape, {-0.6f, 0, 0}).material, 3);
    EXPECT_EQ(evaluate_material(p.tape, {0.7f, 0, 0}).material, 7);  // inherited from the union
    // Inside B: the difference keeps A's material (the union's nearest child there, the box).
    EXPECT_EQ(evaluate_material(p.tape, {0, 0.9f, 0}).material, 7);
    const Part i = part_of(R"({"intersection": [{"sphere": {"center": [0, 0, 0], "radius": 1},
        "material": 4}, {"plane": {"normal": [1, 0, 0], "offset": 0}, "material": 5}]})");
    EXPECT_EQ(evaluate_material(i.tape, {-0.1f, 0, 0}).material, 5);  // the larger value
    EXPECT_EQ(evaluate_material(i.tape, {-0.95f, 0, 0}).material, 4);
    const Part d = part_of(R"({"sphere": {"center": [0, 0, 0], "radius": 1}})");
    EXPECT_EQ(evaluate_material(d.tape, {0, 0, 0}).material, 1);  // the default
}

TEST(SdfParse, GridAndCounts) {
    const Part p = parse_part(R"({"version": 1, "voxel_size": 0.3,
        "bounds": [[0, -1, 2], [1, 1, 2.3]],
        "shape": {"union": [{"sphere": {"center": [0,0,0], "radius": 1}},
                            {"transform": {"translate": [1,0,0],
                              "of": {"shell": {"thickness": 0.1,
                                "of": {"box": {"center": [0,0,0], "half_size": [1,1,1]}}}}}}]}})",
                              "x");
    EXPECT_EQ(p.dims, (Dims{4, 7, 1}));  // ceil(1 / 0.3), ceil(2 / 0.3), ceil(0.3 / 0.3)
    EXPECT_EQ(p.nodes, 5u);
    EXPECT_EQ(p.depth, 4u);
    EXPECT_EQ(p.tape.max_points, 2u);
    EXPECT_FLOAT_EQ(p.centre(1, 0, 0).x, 0.45f);
    EXPECT_FLOAT_EQ(p.corner(0, 2, 0).y, -0.4f);
}

std::string error_of(const std::string& text) {
    try {
        parse_part(text, "part.sdf.json");
    } catch (const InputError& e) {
        return e.what();
    }
    return "(no error)";
}

std::string doc(const std::string& shape, const std::string& h = "0.1",
                const std::string& bounds = "[[-1, -1, -1], [1, 1, 1]]") {
    return R"({"version": 1, "voxel_size": )" + h + R"(, "bounds": )" + bounds + R"(, "shape": )" +
           shape + "}";
}

TEST(SdfParse, ErrorsAreOneLine) {
    const std::string sphere = R"({"sphere": {"center": [0, 0, 0], "radius": 1}})";
    const struct {
        std::string text, expect;
    } cases[] = {
        {"{", "not valid JSON"},
        {R"({"version": 2, "voxel_size": 1, "bounds": [[0,0,0],[1,1,1]], "shape": {}})",
         "unsupported version 2"},
        {doc(R"({"cone": {"radius": 1}})"), "shape: unknown node 'cone'"},
        {doc(R"({"sphere": {"center": [0, 0, 0]}})"), "shape.sphere: missing field 'radius'"},
        {doc(R"({"sphere": {"center": [0, 0], "radius": 1}})"),
         "shape.sphere.center: expected an array of 3 numbers"},
        {doc(R"({"sphere": {"center": [0, 0, 0], "radius": "1"}})"),
         "shape.sphere.radius: expected a number, got a string"},
        {doc(R"({"sphere": {"center": [0, 0, 0], "radius": -1}})"),
         "shape.sphere.radius: must be positive"},
        {doc(R"({"sphere": {"center": [0, 0, 0], "radius": 1, "colour": 2}})"),
         "shape.sphere: unknown field 'colour'"},
        {doc(sphere, "0"), "voxel_size: must be positive"},
        {doc(sphere, "-0.5"), "voxel_size: must be positive"},
        {doc(sphere, "0.1", "[[0, 0, 0], [1, 0, 1]]"), "empty bounds: y from"},
        {doc(sphere, "0.1", "[[0, 0, 0]]"), "bounds: expected [[x0, y0, z0], [x1, y1, z1]]"},
        {R"({"version": 1, "voxel_size": 1, "bounds": [[0,0,0],[1,1,1]]})",
         "top level: missing field 'shape'"},
        {doc(R"({"difference": [)" + sphere + "]}"),
         "shape.difference: expected an array of two nodes"},
        {doc(R"({"union": []})"), "shape.union: expected an array of at least 1 node(s)"},
        {doc(R"({"transform": {"scale": 0, "of": )" + sphere + "}}"),
         "shape.transform.scale: must be positive"},
        {doc(R"({"sphere": {"center": [0, 0, 0], "radius": 1}, "material": 256})"),
         "shape.material: must be an integer in 1..255"},
        {doc(R"({"sphere": {"center": [0, 0, 0], "radius": 1}, "material": 0})"),
         "shape.material: must be an integer in 1..255"},
        {doc(R"({"sphere": {"center": [0, 0, 0], "radius": 1}, "box": {}})"),
         "a node has one kind"},
        {doc(R"({"round_box": {"center": [0,0,0], "half_size": [1, 0.1, 1], "radius": 0.2}})"),
         "must not exceed the smallest half_size"},
        {doc(R"({"plane": {"normal": [0, 0, 0], "offset": 1}})"), "must not be zero"},
        {doc("[]"), "shape: expected a node (an object), got an array"},
    };
    for (const auto& c : cases) {
        const std::string e = error_of(c.text);
        EXPECT_NE(e.find(c.expect), std::string::npos) << c.text << "\n -> " << e;
        EXPECT_EQ(e.find('\n'), std::string::npos) << e;
        EXPECT_EQ(e.rfind("part.sdf.json: ", 0), 0u) << e;
    }
    // A tree too deep: shells nested past the limit.
    std::string deep = sphere;
    for (int i = 0; i < VF_SDF_MAX_DEPTH; ++i) {
        deep = R"({"shell": {"thickness": 0.01, "of": )" + deep + "}}";
    }
    EXPECT_NE(error_of(doc(deep)).find("tree too deep (more than 32 nested nodes)"),
              std::string::npos)
        << error_of(doc(deep));
    std::string ok = sphere;
    for (int i = 1; i < VF_SDF_MAX_DEPTH; ++i) {
        ok = R"({"transform": {"translate": [0, 0, 0], "of": )" + ok + "}}";
    }
    EXPECT_EQ(error_of(doc(ok)), "(no error)");
}

// Points of a box: its 8 corners and random interior points.
std::vector<Vec3> points_in(const Box& b, std::mt19937& rng, int n) {
    std::vector<Vec3> pts;
    for (int c = 0; c < 8; ++c) {
        pts.push_back({c & 1 ? b.x.hi : b.x.lo, c & 2 ? b.y.hi : b.y.lo, c & 4 ? b.z.hi : b.z.lo});
    }
    std::uniform_real_distribution<float> u(0, 1);
    for (int i = 0; i < n; ++i) {
        pts.push_back({b.x.lo + u(rng) * (b.x.hi - b.x.lo), b.y.lo + u(rng) * (b.y.hi - b.y.lo),
                       b.z.lo + u(rng) * (b.z.hi - b.z.lo)});
    }
    return pts;
}

TEST(SdfInterval, EnclosesEverySampleOnRandomTreesAndBoxes) {
    test::RandomPart gen(5);
    std::mt19937 rng(6);
    std::uniform_real_distribution<float> centre(-1.2f, 1.2f), size(0.0f, 0.6f);
    std::size_t boxes = 0, decided = 0;
    for (int t = 0; t < 150; ++t) {
        const Part p = parse_part(gen.part(4, 0.1), "random");
        for (int b = 0; b < 40; ++b) {
            const float cx = centre(rng), cy = centre(rng), cz = centre(rng);
            const Box box{{cx, cx + size(rng)}, {cy, cy + size(rng)}, {cz, cz + size(rng)}};
            const IntervalMaterial r = evaluate_interval(p.tape, box);
            ASSERT_LE(r.value.lo, r.value.hi);
            ++boxes;
            decided += r.material != 0;
            for (const Vec3& q : points_in(box, rng, 30)) {
                const ValueMaterial v = evaluate_material(p.tape, q);
                ASSERT_GE(v.value, r.value.lo) << "tree " << t << " box " << b;
                ASSERT_LE(v.value, r.value.hi) << "tree " << t << " box " << b;
                if (r.material != 0) {
                    ASSERT_EQ(v.material, r.material) << "tree " << t << " box " << b;
                }
            }
        }
    }
    EXPECT_EQ(boxes, 6000u);
    EXPECT_GT(decided, boxes / 4);  // the material is decided on many boxes
}

TEST(SdfInterval, TightOnAPointBox) {
    test::RandomPart gen(7);
    std::mt19937 rng(8);
    std::uniform_real_distribution<float> u(-1, 1);
    for (int t = 0; t < 100; ++t) {
        const Part p = parse_part(gen.part(4, 0.1), "random");
        const Vec3 q{u(rng), u(rng), u(rng)};
        const IntervalMaterial r = evaluate_interval(p.tape, {{q.x, q.x}, {q.y, q.y}, {q.z, q.z}});
        const float v = evaluate(p.tape, q);
        EXPECT_GE(v, r.value.lo);
        EXPECT_LE(v, r.value.hi);
        EXPECT_LE(r.value.hi - r.value.lo, 1e-5f * (1 + std::abs(v)));
    }
}

TEST(SdfGradient, ValueMatchesAndGradientMatchesCentralDifferences) {
    test::RandomPart gen(9);
    std::mt19937 rng(10);
    std::uniform_real_distribution<float> u(-1, 1);
    std::size_t points = 0, agree = 0;
    for (int t = 0; t < 100; ++t) {
        const Part p = parse_part(gen.part(3, 0.1), "random");
        for (int n = 0; n < 50; ++n) {
            const Vec3 q{u(rng), u(rng), u(rng)};
            const ValueGradient g = evaluate_gradient(p.tape, q);
            EXPECT_FLOAT_EQ(g.value, evaluate(p.tape, q));
            // Distance bounds are 1-Lipschitz: |grad f| <= 1.
            EXPECT_LE(std::sqrt(g.gradient.x * g.gradient.x + g.gradient.y * g.gradient.y +
                                g.gradient.z * g.gradient.z),
                      1.0f + 1e-4f);
            const float e = 1e-3f;
            auto at = [&](float dx, float dy, float dz) {
                return evaluate(p.tape, {q.x + dx, q.y + dy, q.z + dz});
            };
            const float cx = (at(e, 0, 0) - at(-e, 0, 0)) / (2 * e);
            const float cy = (at(0, e, 0) - at(0, -e, 0)) / (2 * e);
            const float cz = (at(0, 0, e) - at(0, 0, -e)) / (2 * e);
            ++points;
            agree += std::abs(cx - g.gradient.x) < 2e-2f && std::abs(cy - g.gradient.y) < 2e-2f &&
                     std::abs(cz - g.gradient.z) < 2e-2f;
        }
    }
    // Away from kinks (min/max switches, box edges) they agree; kinks are rare at random.
    EXPECT_GE(agree, points * 97 / 100) << agree << " of " << points;
}

TEST(SdfGradient, AnalyticNormalsOfPrimitives) {
    const Part s = part_of(R"({"sphere": {"center": [0.5, 0, 0], "radius": 0.5}})");
    const ValueGradient g = evaluate_gradient(s.tape, {1.1f, 0.8f, 0});
    EXPECT_NEAR(g.gradient.x, 0.6, 1e-6);
    EXPECT_NEAR(g.gradient.y, 0.8, 1e-6);
    const Part t = part_of(R"({"transform": {"rotate_deg": [0, 0, 90], "scale": 2,
        "of": {"box": {"center": [0, 0, 0], "half_size": [0.5, 0.1, 0.1]}}}})");
    // The box's x axis turned to world y: above its top face the gradient points along +y.
    const ValueGradient h = evaluate_gradient(t.tape, {0, 1.5f, 0});
    EXPECT_NEAR(h.value, 0.5, 1e-6);
    EXPECT_NEAR(h.gradient.x, 0, 1e-6);
    EXPECT_NEAR(h.gradient.y, 1, 1e-6);
}

// Brute force: every voxel centre sampled.
World brute_solid(const Part& p) {
    World w(p.dims);
    for (std::uint32_t z = 0; z < p.dims.z; ++z) {
        for (std::uint32_t y = 0; y < p.dims.y; ++y) {
            for (std::uint32_t x = 0; x < p.dims.x; ++x) {
                const ValueMaterial v = evaluate_material(p.tape, p.centre(x, y, z));
                if (v.value < 0) {
                    w.set(x, y, z, v.material);
                }
            }
        }
    }
    return w;
}

TEST(SdfWorld, SolidWorldEqualsBruteForceOnRandomTrees) {
    test::RandomPart gen(11);
    for (int t = 0; t < 40; ++t) {
        const double h = gen.real(0.02, 0.07);
        const Part p = parse_part(gen.part(4, h), "random");
        const World w = solid_world(p, "random");
        const World b = brute_solid(p);
        ASSERT_EQ(w.dims(), b.dims());
        EXPECT_TRUE(w.voxels() == b.voxels()) << "tree " << t;
    }
}

TEST(SdfWorld, RefusesGridsLargerThanADenseWorld) {
    const Part p = part_of(R"({"sphere": {"center": [0, 0, 0], "radius": 1}})", 1.0 / 512);
    try {
        solid_world(p, "big.sdf.json");
        FAIL() << "no error";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("2048x2048x2048 = 8589934592 voxels"),
                  std::string::npos)
            << e.what();
    }
}

TEST(SdfWorld, GalleryPartsLoadAsWorlds) {
    for (const char* name : {"bracket", "gear_ring", "pipe_elbow"}) {
        const std::filesystem::path path =
            std::filesystem::path(VOXFIELD_DATA_DIR) / "parts" / (std::string(name) + ".sdf.json");
        const Part p = load_part(path);
        EXPECT_GE(p.nodes, 20u) << name;
        const VoxModel m = load_world(path);
        EXPECT_EQ(m.world.dims(), p.dims);
        EXPECT_GT(m.world.solid_count(), 1000u) << name;
        EXPECT_TRUE(m.world.voxels() == brute_solid(p).voxels()) << name;
    }
}

}  // namespace
}  // namespace voxfield::sdf
