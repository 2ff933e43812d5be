// The ray marcher's tracing of implicit parts (raymarch.comp with an ImplicitSurface) on lavapipe,
// the parts discretised on PoCL: on a sphere, boxes (faces on and off grid planes, and one with
// a pocket: concave edges) and a torus, every traced hit point lies
// within 0.05 voxel of the analytic surface and its normal within 2 degrees of the analytic
// normal, and the flat image's hit mask agrees with an independent CPU ray-surface intersection
// of the analytic shape (sphere: closed form; boxes: slabs; torus: dense sampling of its exact
// distance along the ray, then bisection) on >= 99.5% of the pixels.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <optional>
#include <string>
#include <vector>

#include "cl_test_util.hpp"
#include "traced_part.hpp"
#include "voxfield/cl/implicit.hpp"
#include "voxfield/core/camera.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/scene_file.hpp"
#include "voxfield/core/sdf.hpp"
#include "voxfield/core/vox.hpp"
#include "voxfield/vk/raymarcher.hpp"
#include "vulkan_env.hpp"

namespace voxfield::test {
namespace {

namespace fs = std::filesystem;
using D3 = std::array<double, 3>;

D3 add(const D3& a, const D3& b) {
    return {a[0] + b[0], a[1] + b[1], a[2] + b[2]};
}
D3 sub(const D3& a, const D3& b) {
    return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}
D3 mul(const D3& a, double s) {
    return {a[0] * s, a[1] * s, a[2] * s};
}
double dot(const D3& a, const D3& b) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
double norm(const D3& a) {
    return std::sqrt(dot(a, a));
}

// An analytic shape in the part's coordinates: its exact signed distance, the unit normal there
// (the distance's gradient) and the first t >= 0 where the ray o + t d (d unit) meets it.
struct Shape {
    std::string json;  // the part (.sdf.json text)
    std::function<double(const D3&)> distance;
    std::function<D3(const D3&)> normal;
    std::function<std::optional<double>(const D3&, const D3&)> intersect;
    // Whether p lies within `band` of an edge of the shape, where its distance has a kink that
    // the trilinear interpolant of corner samples rounds off (box edges; never for smooth
    // shapes).
    std::function<bool(const D3&, double band)> near_edge = [](const D3&, double) { return false; };
};

Shape sphere() {
    const D3 c{0.3, -0.2, 0.1};
    const double r = 3.0;
    Shape s;
    s.json = R"({"version": 1, "voxel_size": 0.25, "bounds": [[-4, -4, -4], [4, 4, 4]],
                 "shape": {"sphere": {"center": [0.3, -0.2, 0.1], "radius": 3}}})";
    s.distance = [=](const D3& p) { return norm(sub(p, c)) - r; };
    s.normal = [=](const D3& p) {
        const D3 v = sub(p, c);
        return mul(v, 1 / norm(v));
    };
    s.intersect = [=](const D3& o, const D3& d) -> std::optional<double> {
        // |o + t d - c|^2 = r^2, d unit.
        const D3 oc = sub(o, c);
        const double b = dot(oc, d), q = dot(oc, oc) - r * r, disc = b * b - q;
        if (disc < 0) {
            return std::nullopt;
        }
        const double t0 = -b - std::sqrt(disc), t1 = -b + std::sqrt(disc);
        if (t1 < 0) {
            return std::nullopt;
        }
        return t0 >= 0 ? t0 : t1;
    };
    return s;
}

// A box of half sizes h about c, voxel size 0.25.
Shape box(const D3& c, const D3& h) {
    Shape s;
    const auto num = [](double v) { return std::to_string(v); };
    s.json = R"({"version": 1, "voxel_size": 0.25, "bounds": [[-3, -3, -3], [3, 3, 3]],
                 "shape": {"box": {"center": [)" +
             num(c[0]) + "," + num(c[1]) + "," + num(c[2]) + "], \"half_size\": [" + num(h[0]) +
             "," + num(h[1]) + "," + num(h[2]) + "]}}}";
    s.near_edge = [=](const D3& p, double band) {
        int close = 0;
        for (int a = 0; a < 3; ++a) {
            close += std::abs(std::abs(p[a] - c[a]) - h[a]) < band ? 1 : 0;
        }
        return close >= 2;
    };
    s.distance = [=](const D3& p) {
        D3 q{}, out{};
        for (int a = 0; a < 3; ++a) {
            q[a] = std::abs(p[a] - c[a]) - h[a];
            out[a] = std::max(q[a], 0.0);
        }
        return norm(out) + std::min(std::max({q[0], q[1], q[2]}), 0.0);
    };
    s.normal = [=](const D3& p) {
        D3 q{}, out{}, sign{};
        for (int a = 0; a < 3; ++a) {
            sign[a] = p[a] >= c[a] ? 1 : -1;
            q[a] = std::abs(p[a] - c[a]) - h[a];
            out[a] = std::max(q[a], 0.0);
        }
        if (norm(out) > 0) {
            return D3{sign[0] * out[0] / norm(out), sign[1] * out[1] / norm(out),
                      sign[2] * out[2] / norm(out)};
        }
        const int a = q[0] >= q[1] && q[0] >= q[2] ? 0 : (q[1] >= q[2] ? 1 : 2);
        D3 n{0, 0, 0};
        n[a] = sign[a];
        return n;
    };
    s.intersect = [=](const D3& o, const D3& d) -> std::optional<double> {
        double t0 = -1e300, t1 = 1e300;  // the slab method
        for (int a = 0; a < 3; ++a) {
            const double lo = c[a] - h[a], hi = c[a] + h[a];
            if (d[a] == 0) {
                if (o[a] < lo || o[a] > hi) {
                    return std::nullopt;
                }
                continue;
            }
            const double ta = (lo - o[a]) / d[a], tb = (hi - o[a]) / d[a];
            t0 = std::max(t0, std::min(ta, tb));
            t1 = std::min(t1, std::max(ta, tb));
        }
        if (t0 > t1 || t1 < 0) {
            return std::nullopt;
        }
        return std::max(t0, 0.0);
    };
    return s;
}

// A box with a box-shaped pocket cut into its top (a difference): convex outer edges and
// concave edges along the pocket's floor and walls, every face between grid planes.
Shape pocketed_box() {
    const D3 ca{0.1, -0.3, 0.05}, ha{2.3, 1.45, 2.05};  // the block
    const D3 cb{0.35, 1.1, -0.2}, hb{1.15, 1.0, 0.95};  // the pocket, open at the top
    Shape s;
    s.json = R"({"version": 1, "voxel_size": 0.25, "bounds": [[-3, -3, -3], [3, 3, 3]],
                 "shape": {"difference": [
                   {"box": {"center": [0.1, -0.3, 0.05], "half_size": [2.3, 1.45, 2.05]}},
                   {"box": {"center": [0.35, 1.1, -0.2], "half_size": [1.15, 1.0, 0.95]}}]}})";
    const auto box_distance = [](const D3& c, const D3& h, const D3& p) {
        D3 q{}, out{};
        for (int a = 0; a < 3; ++a) {
            q[a] = std::abs(p[a] - c[a]) - h[a];
            out[a] = std::max(q[a], 0.0);
        }
        return norm(out) + std::min(std::max({q[0], q[1], q[2]}), 0.0);
    };
    s.distance = [=](const D3& p) {
        return std::max(box_distance(ca, ha, p), -box_distance(cb, hb, p));
    };
    const auto distance = s.distance;
    s.normal = [=](const D3& p) {
        // Central differences of the distance (the faces are planes: exact off the edges).
        const double e = 1e-5;
        D3 n{};
        for (int a = 0; a < 3; ++a) {
            D3 hi = p, lo = p;
            hi[a] += e;
            lo[a] -= e;
            n[a] = (distance(hi) - distance(lo)) / (2 * e);
        }
        return mul(n, 1 / norm(n));
    };
    s.near_edge = [=](const D3& p, double band) {
        for (const auto& [c, h] : {std::pair{ca, ha}, std::pair{cb, hb}}) {
            int close = 0;
            for (int a = 0; a < 3; ++a) {
                close += std::abs(std::abs(p[a] - c[a]) - h[a]) < band ? 1 : 0;
            }
            if (close >= 2) {
                return true;
            }
        }
        return false;
    };
    // The slab intervals of both boxes: the first t >= 0 inside the block and outside the
    // pocket.
    const auto slab = [](const D3& c, const D3& h, const D3& o,
                         const D3& d) -> std::optional<std::pair<double, double>> {
        double t0 = -1e300, t1 = 1e300;
        for (int a = 0; a < 3; ++a) {
            const double lo = c[a] - h[a], hi = c[a] + h[a];
            if (d[a] == 0) {
                if (o[a] < lo || o[a] > hi) {
                    return std::nullopt;
                }
                continue;
            }
            const double ta = (lo - o[a]) / d[a], tb = (hi - o[a]) / d[a];
            t0 = std::max(t0, std::min(ta, tb));
            t1 = std::min(t1, std::max(ta, tb));
        }
        if (t0 > t1) {
            return std::nullopt;
        }
        return std::pair{t0, t1};
    };
    s.intersect = [=](const D3& o, const D3& d) -> std::optional<double> {
        const auto a = slab(ca, ha, o, d);
        if (!a || a->second < 0) {
            return std::nullopt;
        }
        const double start = std::max(a->first, 0.0);
        const auto b = slab(cb, hb, o, d);
        if (!b || b->second < start || b->first > start) {
            return start;  // the block's entry is outside the pocket
        }
        return b->second < a->second ? std::optional<double>(b->second) : std::nullopt;
    };
    return s;
}

Shape torus() {
    // In the x-z plane (DESIGN §3), major radius 3, minor 1.2.
    const D3 c{0.05, 0.1, -0.1};
    const double major = 3.0, minor = 1.2;
    Shape s;
    s.json = R"({"version": 1, "voxel_size": 0.2, "bounds": [[-4.6, -1.6, -4.6], [4.6, 1.6, 4.6]],
                 "shape": {"torus": {"center": [0.05, 0.1, -0.1], "major": 3, "minor": 1.2}}})";
    s.distance = [=](const D3& p) {
        const D3 v = sub(p, c);
        const double ring = std::hypot(v[0], v[2]) - major;
        return std::hypot(ring, v[1]) - minor;
    };
    s.normal = [=](const D3& p) {
        const D3 v = sub(p, c);
        const double rho = std::hypot(v[0], v[2]);
        const D3 centre = add(c, D3{v[0] / rho * major, 0, v[2] / rho * major});
        const D3 n = sub(p, centre);
        return mul(n, 1 / norm(n));
    };
    const auto distance = s.distance;
    s.intersect = [=](const D3& o, const D3& d) -> std::optional<double> {
        // Dense samples along the ray (a step of minor / 64: no crossing of the tube is
        // narrower than that unless it grazes), the first sign change bisected.
        const double step = minor / 64, far = norm(sub(o, c)) + major + minor + 1;
        double prev_t = 0, prev = distance(o);
        if (prev < 0) {
            return 0.0;
        }
        for (double t = step; t <= far; t += step) {
            const double f = distance(add(o, mul(d, t)));
            if (f < 0) {
                double lo = prev_t, hi = t;
                for (int i = 0; i < 60; ++i) {
                    const double mid = 0.5 * (lo + hi);
                    (distance(add(o, mul(d, mid))) < 0 ? hi : lo) = mid;
                }
                return 0.5 * (lo + hi);
            }
            prev_t = t;
            prev = f;
        }
        return std::nullopt;
    };
    return s;
}

// The part discretised on PoCL and the world the ray marcher's field is built from, as
// `render` builds them (cli::load_traced_part).
struct Traced {
    sdf::Part part;
    cli::TracedPart traced;
    const ocl::ImplicitGrid& grid() const { return traced.grid; }
    const World& world() const { return traced.model.world; }
};

Traced discretise(const Shape& shape) {
    sdf::Part part = sdf::parse_part(shape.json, "test part");
    cli::TracedPart traced = cli::load_traced_part(pocl(), part, "test part");
    return Traced{std::move(part), std::move(traced)};
}

// The exact Manhattan field of the world, compact (distance << 8 | material).
std::vector<std::uint16_t> compact_field(const World& world) {
    const std::vector<std::uint32_t> d = reference_manhattan(world);
    std::vector<std::uint16_t> out(world.size());
    for (std::size_t i = 0; i < out.size(); ++i) {
        out[i] = static_cast<std::uint16_t>((std::min<std::uint32_t>(d[i], 255) << 8) |
                                            world.voxels()[i]);
    }
    return out;
}

struct Stats {
    std::size_t pixels = 0, mask_agree = 0, hits = 0, smooth = 0, edge_hits = 0;
    double max_distance = 0;  // voxels, of a hit point from the analytic surface
    double max_angle = 0;     // degrees, between a hit's normal and the analytic one
    // The same for hits within one voxel of an edge (Shape::near_edge).
    double edge_distance = 0, edge_angle = 0;

    void merge(const Stats& s) {
        pixels += s.pixels;
        mask_agree += s.mask_agree;
        hits += s.hits;
        smooth += s.smooth;
        edge_hits += s.edge_hits;
        max_distance = std::max(max_distance, s.max_distance);
        max_angle = std::max(max_angle, s.max_angle);
        edge_distance = std::max(edge_distance, s.edge_distance);
        edge_angle = std::max(edge_angle, s.edge_angle);
    }
};

// Renders `shape` from `camera` (voxel coordinates) and compares every pixel with the analytic
// shape.
Stats compare(vk::Raymarcher& marcher, const Traced& t, const Shape& shape, const D3& camera,
              std::uint32_t width, std::uint32_t height) {
    vk::RenderOptions r;
    r.width = width;
    r.height = height;
    r.shading = vk::Shading::flat;
    r.camera.fov_deg = 35;
    r.sky = Rgba{255, 0, 255, 255};  // the default palette's material 1 is white
    const Dims d = t.world().dims();
    r.camera.position = camera;
    r.camera.target = {d.x / 2.0, d.y / 2.0, d.z / 2.0};
    r.surface = true;
    const vk::Image img = marcher.render(r);
    const double h = t.part.voxel_size;
    const D3 lo{t.part.lo[0], t.part.lo[1], t.part.lo[2]};
    const auto to_part = [&](const D3& v) { return add(lo, mul(v, h)); };
    const D3 forward = sub(r.camera.target, r.camera.position);
    Stats s;
    for (std::uint32_t j = 0; j < height; ++j) {
        for (std::uint32_t i = 0; i < width; ++i) {
            const std::size_t p = std::size_t{j} * width + i;
            const D3 dir =
                pixel_direction(forward, r.camera.fov_deg, width, height, i + 0.5, j + 0.5);
            const bool analytic = shape.intersect(to_part(camera), dir).has_value();
            const bool sky =
                img.rgba[4 * p] == 255 && img.rgba[4 * p + 1] == 0 && img.rgba[4 * p + 2] == 255;
            ++s.pixels;
            s.mask_agree += analytic == !sky ? 1 : 0;
            const vk::SurfaceHit& hit = img.surface[p];
            EXPECT_EQ(hit.kind != VF_TRACE_MISS, !sky) << "pixel " << i << ", " << j;
            if (hit.kind == VF_TRACE_MISS) {
                continue;
            }
            ++s.hits;
            s.smooth += hit.kind == VF_TRACE_SMOOTH ? 1 : 0;
            const D3 at = to_part({hit.x, hit.y, hit.z});
            const D3 want = shape.normal(at);
            const double c =
                std::clamp(dot(want, D3{hit.nx, hit.ny, hit.nz}) / norm(D3{hit.nx, hit.ny, hit.nz}),
                           -1.0, 1.0);
            const double distance = std::abs(shape.distance(at)) / h;
            const double angle = std::acos(c) * 180 / M_PI;
            if (shape.near_edge(at, 2 * h)) {
                ++s.edge_hits;
                s.edge_distance = std::max(s.edge_distance, distance);
                s.edge_angle = std::max(s.edge_angle, angle);
            } else {
                s.max_distance = std::max(s.max_distance, distance);
                s.max_angle = std::max(s.max_angle, angle);
            }
        }
    }
    return s;
}

// What a shape must meet beyond the 0.05 voxel and 2 degrees away from edges: the hit mask's
// agreement and, within two voxels of an edge, the hit points' distance (normals there are not
// bounded: at an edge the analytic normal is either face's; measured, they are exact on the
// boxes).
struct Expect {
    double mask = 0.995;
    double edge_distance = 0.05;
};

void check_shape(const Shape& shape, const std::string& name, Expect expect = {}) {
    const Traced t = discretise(shape);
    vk::Raymarcher marcher(validated_vulkan());
    marcher.upload_compact(t.world().dims(), Palette(), compact_field(t.world()));
    marcher.set_implicit(cli::surface_of(t.grid()));
    EXPECT_TRUE(marcher.has_implicit());
    EXPECT_GT(marcher.implicit_bytes(), 0u);
    const Dims d = t.world().dims();
    const double x = d.x, y = d.y, z = d.z;
    // Views from several sides, near and far, one nearly along an axis.
    const std::vector<D3> cameras = {{-0.6 * x, 1.4 * y, -0.9 * z},
                                     {1.8 * x, 0.7 * y, 1.2 * z},
                                     {0.5 * x + 0.3, 2.5 * y + 0.6 * x, 0.5 * z - 0.2},
                                     {0.3 * x, -0.8 * y, 1.9 * z},
                                     {0.5 * x + 0.01, 0.5 * y + 0.02, -1.1 * z}};
    Stats all;
    for (const D3& camera : cameras) {
        all.merge(compare(marcher, t, shape, camera, 96, 72));
    }
    const double agree = double(all.mask_agree) / double(all.pixels);
    std::cout << name << ": " << all.hits << " hits of " << all.pixels << " pixels, mask agrees on "
              << agree * 100 << "%, hit points within " << all.max_distance
              << " voxel of the surface, normals within " << all.max_angle << " degrees; "
              << all.edge_hits << " hits within two voxels of an edge: within " << all.edge_distance
              << " voxel, " << all.edge_angle << " degrees\n";
    EXPECT_GT(all.hits, all.pixels / 10);
    EXPECT_EQ(all.smooth, all.hits);  // every hit on the trilinear surface, none on a cube
    EXPECT_GE(agree, expect.mask);
    EXPECT_LE(all.max_distance, 0.05);
    EXPECT_LE(all.max_angle, 2.0);
    EXPECT_LE(all.edge_distance, expect.edge_distance);
}

TEST(ImplicitTrace, SphereMatchesTheAnalyticSphere) {
    check_shape(sphere(), "sphere");
}

// Faces on grid planes: the corner samples there are exactly 0 and the surface is the box,
// edges included; voxels at an edge are traced on their corners' planes, so the normals there
// are the faces' too.
TEST(ImplicitTrace, BoxMatchesTheAnalyticBox) {
    check_shape(box({0, 0, 0}, {2.25, 1.5, 2}), "box on grid planes");
}

// Faces between grid planes: a voxel that an edge passes through has corners on both sides of
// the kink, where the trilinear interpolant would round the edge off by up to 0.37 voxel (the
// silhouette then lost a fraction of a voxel along every edge: 97.97% of the pixels agreed).
// Such a voxel (corner gradients 90 degrees apart, f convex) is traced on its corners' tangent
// planes, whose maximum is the box: edges and faces exact.
TEST(ImplicitTrace, BoxOffTheGridPlanes) {
    check_shape(box({0.1, 0.2, -0.15}, {2.3, 1.7, 2.05}), "box off the grid planes");
}

// Concave edges (a pocket's floor and walls, f concave there) are traced on the minimum of the
// corners' planes. Where a convex and a concave kink meet in one voxel (the top ends of the
// pocket's vertical corner edges, at its rim) f is neither and the interpolant stays: hit
// points there lie within 0.29 voxel of the surface (measured; 25 of about 8000 hits within
// two voxels of an edge are beyond 0.05).
TEST(ImplicitTrace, PocketedBoxMatchesTheAnalyticShape) {
    check_shape(pocketed_box(), "pocketed box", Expect{0.995, 0.3});
}

TEST(ImplicitTrace, TorusMatchesTheAnalyticTorus) {
    check_shape(torus(), "torus");
}

// Lit shading lights the smooth surface as voxel worlds are lit: a floor under a floating
// sphere is in the sphere's shadow exactly where the analytic ray from the floor toward the
// sun meets the analytic sphere.
TEST(ImplicitTrace, LitSurfaceCastsShadows) {
    Shape scene = sphere();
    scene.json = R"({"version": 1, "voxel_size": 0.25, "bounds": [[-8, -1, -8], [8, 8, 8]],
        "shape": {"union": [{"box": {"center": [0, -0.5, 0], "half_size": [7.5, 0.5, 7.5]}},
                            {"sphere": {"center": [0, 5, 0], "radius": 2}}]}})";
    const Traced t = discretise(scene);
    vk::Raymarcher marcher(validated_vulkan());
    marcher.upload_compact(t.world().dims(), Palette(), compact_field(t.world()));
    marcher.set_implicit(cli::surface_of(t.grid()));
    vk::RenderOptions r;
    r.width = 96;
    r.height = 72;
    r.shading = vk::Shading::lit;
    r.surface = true;
    const Dims d = t.world().dims();
    r.camera.position = {0.5 * d.x, 3.0 * d.y, -0.4 * d.z};
    r.camera.target = {0.5 * d.x, 0, 0.5 * d.z};
    const vk::Image img = marcher.render(r);
    const double h = t.part.voxel_size;
    const D3 lo{t.part.lo[0], t.part.lo[1], t.part.lo[2]};
    const D3 sun{1 / std::sqrt(3.0), 1 / std::sqrt(3.0), 1 / std::sqrt(3.0)};
    const D3 centre{0, 5, 0};
    int shadowed_max = -1, lit_min = 256, shadowed = 0, lit = 0;
    for (std::size_t p = 0; p < img.surface.size(); ++p) {
        const vk::SurfaceHit& hit = img.surface[p];
        const D3 at = add(lo, mul(D3{hit.x, hit.y, hit.z}, h));
        // Floor points (the box's top face), clearly in or out of the shadow (the analytic
        // shadow ray passes the sphere's surface more than a voxel away).
        if (hit.kind != VF_TRACE_SMOOTH || std::abs(at[1]) > 0.01 || hit.ny < 0.99 ||
            std::abs(at[0]) > 6 || std::abs(at[2]) > 6) {
            continue;
        }
        const D3 oc = sub(at, centre);
        const double b = dot(oc, sun);
        const double miss = norm(sub(oc, mul(sun, b))) - 2;  // closest approach - radius
        if (std::abs(miss) < h || b > 0) {
            continue;
        }
        const int red = img.rgba[4 * p];
        if (miss < 0) {
            ++shadowed;
            shadowed_max = std::max(shadowed_max, red);
        } else {
            ++lit;
            lit_min = std::min(lit_min, red);
        }
    }
    EXPECT_GT(shadowed, 20);
    EXPECT_GT(lit, 200);
    EXPECT_LT(shadowed_max, lit_min);
}

// Hit records of a voxel world: cube faces; the surface of another grid's dims is not traced.
TEST(ImplicitTrace, VoxelWorldsKeepCubes) {
    const Traced t = discretise(sphere());
    vk::Raymarcher marcher(validated_vulkan());
    World world(Dims{8, 8, 8});
    world.set(3, 3, 3, 5);
    marcher.upload_compact(world.dims(), Palette(), compact_field(world));
    marcher.set_implicit(cli::surface_of(t.grid()));  // 32^3: not this field's
    vk::RenderOptions r;
    r.width = r.height = 16;
    r.camera.position = {3.5, 3.5, -10};
    r.camera.target = {3.5, 3.5, 3.5};
    r.camera.fov_deg = 10;
    r.surface = true;
    const vk::Image img = marcher.render(r);
    const vk::SurfaceHit& centre = img.surface[8 * 16 + 8];
    EXPECT_EQ(centre.kind, float(VF_TRACE_CUBE));
    EXPECT_EQ(centre.nz, -1.0f);
    EXPECT_FLOAT_EQ(centre.z, 3.0f);
    EXPECT_NEAR(centre.t, 13.0, 1e-3);
    EXPECT_EQ(img.surface[0].kind, float(VF_TRACE_MISS));
    marcher.clear_implicit();
    EXPECT_FALSE(marcher.has_implicit());
    EXPECT_EQ(marcher.implicit_bytes(), 0u);
    // A frame of the swapchain records no hits.
    EXPECT_THROW(static_cast<void>(marcher.render_to(r, vk::ExternalMemory())), std::logic_error);
}

// A mixed scene (.scene.json): a sphere part and a .vox block overlapping its side. Rays that
// meet the block first hit cubes (the block's voxels win; the sphere's crossed voxels under the
// block are dropped from the grid), the others the sphere's smooth surface, and every hit
// agrees with the union of the analytic sphere and the block's box.
TEST(ImplicitTrace, MixedSceneTracesPartsAndModels) {
    const fs::path dir =
        fs::temp_directory_path() / ("voxfield-mixed-" + std::to_string(::getpid()));
    fs::create_directories(dir);
    World block(Dims{6, 10, 6});
    for (std::uint32_t z = 0; z < 6; ++z) {
        for (std::uint32_t y = 0; y < 10; ++y) {
            for (std::uint32_t x = 0; x < 6; ++x) {
                block.set(x, y, z, 5);
            }
        }
    }
    write_vox(dir / "block.vox", block, Palette());
    const Shape ball = sphere();
    std::ofstream(dir / "ball.sdf.json") << ball.json;
    // The block: x from 2.5 to 4 (into the sphere's side: it reaches 3.3), y -1.25..1.25,
    // z -0.75..0.75, voxel size 0.25.
    std::ofstream(dir / "mixed.scene.json") << R"({"version": 1, "voxel_size": 0.25, "items": [
        {"sdf": "ball.sdf.json"}, {"vox": "block.vox", "translate": [2.5, -1.25, -0.75]}]})";
    const scene::Scene sc = scene::load_scene(dir / "mixed.scene.json");
    fs::remove_all(dir);
    ASSERT_TRUE(sc.part);
    const cli::TracedPart traced = cli::load_traced_scene(pocl(), sc, "mixed");
    const World& world = traced.model.world;
    const double h = sc.voxel_size;
    const D3 lo{sc.lo[0], sc.lo[1], sc.lo[2]};
    const auto in_block = [&](const D3& p) {
        return p[0] >= 2.5 - 1e-4 && p[0] <= 4 + 1e-4 && std::abs(p[1]) <= 1.25 + 1e-4 &&
               std::abs(p[2]) <= 0.75 + 1e-4;
    };
    for (const auto& c : traced.grid.crossed()) {
        const D3 centre = add(lo, mul(D3{c.x + 0.5, c.y + 0.5, c.z + 0.5}, h));
        EXPECT_FALSE(in_block(centre)) << c.x << "," << c.y << "," << c.z;
    }
    vk::Raymarcher marcher(validated_vulkan());
    marcher.upload_compact(world.dims(), traced.model.palette, compact_field(world));
    marcher.set_implicit(traced.surface());
    vk::RenderOptions r;
    r.width = 96;
    r.height = 72;
    r.shading = vk::Shading::flat;
    r.surface = true;
    r.camera.fov_deg = 35;
    const Dims d = world.dims();
    r.camera.position = {2.2 * d.x, 0.8 * d.y, 0.3 * d.z};
    r.camera.target = {0.5 * d.x, 0.5 * d.y, 0.5 * d.z};
    const vk::Image img = marcher.render(r);
    std::size_t cubes = 0, smooth = 0;
    for (const vk::SurfaceHit& hit : img.surface) {
        if (hit.kind == VF_TRACE_MISS) {
            continue;
        }
        const D3 at = add(lo, mul(D3{hit.x, hit.y, hit.z}, h));
        if (hit.kind == VF_TRACE_CUBE) {
            ++cubes;
            EXPECT_TRUE(in_block(at)) << at[0] << "," << at[1] << "," << at[2];
        } else {
            ++smooth;
            EXPECT_LE(std::abs(ball.distance(at)) / h, 0.05);
            EXPECT_FALSE(in_block(at));
        }
    }
    EXPECT_GT(cubes, 100u);
    EXPECT_GT(smooth, 500u);
}

// A crossing narrower than any fixed sampling of the segment: one crossed voxel whose
// interpolant along the ray is 0.225 (1 - 2x)^2 + c, x the ray's progress through the voxel.
// With c = -0.001 it dips below 0 only for |1 - 2x| < 0.067 (both ends of the segment at
// +0.224): the root at x = 0.4667 is found; with c = +0.001 the ray passes.
TEST(ImplicitTrace, ThinCrossingInsideOneVoxel) {
    for (const double c : {-0.001, 0.001}) {
        // f(x, y, z) = -(1 - 2x)(1 - 2y) / 4 + c over the voxel (1, 1, 1) of a 4^3 grid: one
        // tile of depth 0, one leaf, one crossed voxel (child 1 + 4 + 16).
        std::vector<float> vertices;
        for (std::uint32_t k = 0; k < 8; ++k) {
            const double x = k & 1, y = k >> 1 & 1;
            const double f = -(1 - 2 * x) * (1 - 2 * y) / 4 + c;
            const double gx = (1 - 2 * y) / 2, gy = (1 - 2 * x) / 2;
            vertices.insert(vertices.end(), {float(gx), float(gy), 0.0f, float(f)});
        }
        const std::vector<std::uint32_t> tiles = {0};
        const std::vector<std::uint32_t> nodes = {0, 0, 1u << 21, 0, 0, 0};
        const std::vector<std::uint32_t> voxels = {0x03020100u, 0x07060504u, 1};
        vk::ImplicitSurface surface;
        surface.dims = Dims{4, 4, 4};
        surface.tiles = Dims{1, 1, 1};
        surface.tile_depth = 0;
        surface.tile_table = tiles;
        surface.nodes = nodes;
        surface.voxels = voxels;
        surface.vertices = vertices;
        World world(Dims{4, 4, 4});
        world.set(1, 1, 1, 1);
        vk::Raymarcher marcher(validated_vulkan());
        marcher.upload_compact(world.dims(), Palette(), compact_field(world));
        marcher.set_implicit(surface);
        // The ray y = 1.95 - 0.9 (x - 1) in the plane z = 1.5, through (1.5, 1.5, 1.5).
        const D3 dir = mul(D3{1, -0.9, 0}, 1 / std::hypot(1.0, 0.9));
        vk::RenderOptions r;
        r.width = r.height = 1;
        r.camera.target = {1.5, 1.5, 1.5};
        r.camera.position = sub(r.camera.target, mul(dir, 10));
        r.surface = true;
        const vk::SurfaceHit hit = marcher.render(r).surface.at(0);
        if (c > 0) {
            EXPECT_EQ(hit.kind, float(VF_TRACE_MISS));
            continue;
        }
        ASSERT_EQ(hit.kind, float(VF_TRACE_SMOOTH));
        const double x = 0.5 - std::sqrt(0.001 / 0.225) / 2;  // the first root
        EXPECT_NEAR(hit.x, 1 + x, 1e-4);
        EXPECT_NEAR(hit.y, 1.95 - 0.9 * x, 1e-4);
        EXPECT_NEAR(hit.z, 1.5, 1e-5);
    }
}

// A grid whose arrays do not fit its tiles or point past each other is refused, and the surface
// held before stays.
TEST(ImplicitTrace, RefusesInconsistentGrids) {
    const Traced t = discretise(sphere());
    vk::Raymarcher marcher(validated_vulkan());
    marcher.set_implicit(cli::surface_of(t.grid()));
    const std::uint64_t bytes = marcher.implicit_bytes();
    auto refused = [&](const std::function<void(vk::ImplicitSurface&, ocl::ImplicitGrid&)>& spoil) {
        ocl::ImplicitGrid g = t.grid();
        vk::ImplicitSurface s = cli::surface_of(g);
        spoil(s, g);
        EXPECT_THROW(marcher.set_implicit(s), InputError);
        EXPECT_EQ(marcher.implicit_bytes(), bytes);
    };
    refused([](vk::ImplicitSurface& s, ocl::ImplicitGrid&) { s.tile_depth = 1; });
    refused([](vk::ImplicitSurface& s, ocl::ImplicitGrid&) { s.dims.x += 64; });
    refused([](vk::ImplicitSurface& s, ocl::ImplicitGrid& g) {
        g.tile_table[0] = static_cast<std::uint32_t>(g.node_count());
        s.tile_table = g.tile_table;
    });
    refused([](vk::ImplicitSurface& s, ocl::ImplicitGrid& g) {
        // A leaf with crossed voxels whose records would run past the last one.
        for (std::size_t n = 0; n < g.node_count(); ++n) {
            std::uint32_t* rec = &g.nodes[n * VF_SDF_NODE_WORDS];
            if (rec[1] != VF_SDF_NOT_LEAF && (rec[2] | rec[3]) != 0) {
                rec[0] = static_cast<std::uint32_t>(g.crossed_count());
                break;
            }
        }
        s.nodes = g.nodes;
    });
    refused([](vk::ImplicitSurface& s, ocl::ImplicitGrid& g) {
        s.vertices = std::span<const float>(g.vertices).first(g.vertices.size() - 4);
    });
    refused([](vk::ImplicitSurface& s, ocl::ImplicitGrid&) { s.voxels = s.voxels.first(1); });
}

}  // namespace
}  // namespace voxfield::test
