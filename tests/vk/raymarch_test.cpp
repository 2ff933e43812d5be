// The Vulkan ray marcher on lavapipe (or any Vulkan device) against an independent CPU ray
// caster: exact voxel traversal of the world itself (no distance field) in double precision.
// Every scene runs in both field formats (packed32 and compact) and with the field of every
// metric, whose image must also equal the manhattan field's byte for byte (the metric changes
// how far a ray walks between fetches, never which voxel it hits).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "voxfield/core/camera.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/metric.hpp"
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

// Exact Chebyshev distances by a breadth-first search over the 26 neighbours from every solid
// voxel (a king's move changes max |d_i| by at most one, and a shortest king path to the
// nearest solid stays inside the world box): O(voxels), where core's reference_distance is
// O(voxels * distance), minutes on the 520x256x256 worlds below.
std::vector<std::uint32_t> chebyshev_distances(const World& world) {
    const Dims n = world.dims();
    std::vector<std::uint32_t> d(world.size(), kInfinite);
    std::vector<std::uint32_t> queue;
    queue.reserve(world.size());
    for (std::size_t i = 0; i < d.size(); ++i) {
        if (world.voxels()[i] != 0) {
            d[i] = 0;
            queue.push_back(static_cast<std::uint32_t>(i));
        }
    }
    for (std::size_t head = 0; head < queue.size(); ++head) {
        const std::uint32_t i = queue[head];
        const std::int64_t x = i % n.x, y = i / n.x % n.y, z = i / (std::size_t{n.x} * n.y);
        for (std::int64_t dz = -1; dz <= 1; ++dz) {
            for (std::int64_t dy = -1; dy <= 1; ++dy) {
                for (std::int64_t dx = -1; dx <= 1; ++dx) {
                    if (!n.contains(x + dx, y + dy, z + dz)) {
                        continue;
                    }
                    const std::size_t j = n.index(static_cast<std::uint32_t>(x + dx),
                                                  static_cast<std::uint32_t>(y + dy),
                                                  static_cast<std::uint32_t>(z + dz));
                    if (d[j] == kInfinite) {
                        d[j] = d[i] + 1;
                        queue.push_back(static_cast<std::uint32_t>(j));
                    }
                }
            }
        }
    }
    return d;
}

// Exact Euclidean distances rounded down: the squared distance by the separable lower
// envelope of parabolas of Felzenszwalb & Huttenlocher ("Distance Transforms of Sampled
// Functions", Theory of Computing 2012) along x, y and z in integers, then its integer square
// root.
std::vector<std::uint32_t> euclidean_distances(const World& world) {
    const Dims n = world.dims();
    constexpr std::int64_t kNone = -1;  // no solid on the line so far
    std::vector<std::int64_t> g(world.size());
    for (std::size_t i = 0; i < g.size(); ++i) {
        g[i] = world.voxels()[i] != 0 ? 0 : kNone;
    }
    const std::array<std::uint32_t, 3> len = {n.x, n.y, n.z};
    const std::array<std::size_t, 3> stride = {1, n.x, std::size_t{n.x} * n.y};
    std::vector<std::int64_t> f, out;
    std::vector<std::int64_t> v;
    std::vector<double> z;
    for (std::size_t axis = 0; axis < 3; ++axis) {
        const std::int64_t m = len[axis];
        f.resize(static_cast<std::size_t>(m));
        out.resize(static_cast<std::size_t>(m));
        v.resize(static_cast<std::size_t>(m));
        z.resize(static_cast<std::size_t>(m) + 1);
        for (std::size_t start = 0; start < g.size(); ++start) {
            // Each line once: from its element with coordinate 0 on this axis.
            if (start / stride[axis] % len[axis] != 0) {
                continue;
            }
            for (std::int64_t q = 0; q < m; ++q) {
                f[static_cast<std::size_t>(q)] =
                    g[start + static_cast<std::size_t>(q) * stride[axis]];
            }
            std::int64_t k = -1;
            for (std::int64_t q = 0; q < m; ++q) {
                const std::int64_t fq = f[static_cast<std::size_t>(q)];
                if (fq == kNone) {
                    continue;
                }
                double s = -INFINITY;
                while (k >= 0) {
                    const std::int64_t p = v[static_cast<std::size_t>(k)];
                    s = double((fq + q * q) - (f[static_cast<std::size_t>(p)] + p * p)) /
                        double(2 * (q - p));
                    if (s > z[static_cast<std::size_t>(k)]) {
                        break;
                    }
                    --k;
                }
                ++k;
                v[static_cast<std::size_t>(k)] = q;
                z[static_cast<std::size_t>(k)] = k == 0 ? -INFINITY : s;
            }
            for (std::int64_t q = 0, j = 0; q < m; ++q) {
                if (k < 0) {
                    out[static_cast<std::size_t>(q)] = kNone;
                    continue;
                }
                while (j < k && z[static_cast<std::size_t>(j + 1)] < double(q)) {
                    ++j;
                }
                const std::int64_t p = v[static_cast<std::size_t>(j)];
                out[static_cast<std::size_t>(q)] =
                    f[static_cast<std::size_t>(p)] + (q - p) * (q - p);
            }
            for (std::int64_t q = 0; q < m; ++q) {
                g[start + static_cast<std::size_t>(q) * stride[axis]] =
                    out[static_cast<std::size_t>(q)];
            }
        }
    }
    std::vector<std::uint32_t> d(g.size());
    for (std::size_t i = 0; i < g.size(); ++i) {
        if (g[i] == kNone) {
            d[i] = kInfinite;
            continue;
        }
        auto r = static_cast<std::int64_t>(std::sqrt(double(g[i])));
        while (r * r > g[i]) {
            --r;
        }
        while ((r + 1) * (r + 1) <= g[i]) {
            ++r;
        }
        d[i] = static_cast<std::uint32_t>(r);
    }
    return d;
}

// The distances the ray marcher is given: the exact field of `metric` (unit spacing) rounded
// down (DESIGN §3's integer formats), kInfinite where there is no solid. Manhattan from core's
// reference, the others from the two transforms above (checked against core's reference
// below).
std::vector<std::uint32_t> distances(const World& world, Metric metric) {
    switch (metric) {
        case Metric::chebyshev:
            return chebyshev_distances(world);
        case Metric::euclidean:
            return euclidean_distances(world);
        case Metric::manhattan:
            break;
    }
    return reference_manhattan(world);
}

std::vector<std::uint32_t> packed_field(const World& world, const Palette& palette,
                                        const std::vector<std::uint32_t>& d) {
    const auto bytes = encode_field(d, world, palette, Format::packed32);
    std::vector<std::uint32_t> out(world.size());
    std::memcpy(out.data(), bytes.data(), bytes.size());
    return out;
}

// compact: (min(d, 255) << 8) | material.
std::vector<std::uint16_t> compact_field(const World& world, const std::vector<std::uint32_t>& d) {
    std::vector<std::uint16_t> out(world.size());
    for (std::size_t i = 0; i < out.size(); ++i) {
        out[i] = static_cast<std::uint16_t>((std::min<std::uint32_t>(d[i], 255) << 8) |
                                            world.voxels()[i]);
    }
    return out;
}

// Uploads distances `d` (in `metric`) in `format`.
void upload(vk::Raymarcher& marcher, const World& world, const Palette& palette,
            vk::FieldFormat format, Metric metric, const std::vector<std::uint32_t>& d) {
    if (format == vk::FieldFormat::packed32) {
        marcher.upload(world, palette, packed_field(world, palette, d));
    } else {
        marcher.upload_compact(world.dims(), palette, compact_field(world, d));
    }
    marcher.set_metric(metric);
}

void upload(vk::Raymarcher& marcher, const World& world, const Palette& palette,
            vk::FieldFormat format, Metric metric = Metric::manhattan) {
    upload(marcher, world, palette, format, metric, distances(world, metric));
}

// ---- The CPU reference caster (independent of vk/: its own camera and traversal). ----

Vec3 normalized(Vec3 v) {
    const double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    return {v[0] / n, v[1] / n, v[2] / n};
}

// Amanatides-Woo traversal in double precision of the cells of `dims` along o + t d.
class Traversal {
  public:
    // False when the ray misses the world.
    bool start(Dims dims, const Vec3& o, const Vec3& d) {
        size_ = {double(dims.x), double(dims.y), double(dims.z)};
        o_ = o;
        d_ = d;
        double t0 = 0, t1 = INFINITY;
        for (std::size_t a = 0; a < 3; ++a) {
            if (d[a] == 0) {
                if (o[a] < 0 || o[a] >= size_[a]) {
                    return false;
                }
                continue;
            }
            double ta = (0 - o[a]) / d[a], tb = (size_[a] - o[a]) / d[a];
            if (ta > tb) {
                std::swap(ta, tb);
            }
            t0 = std::max(t0, ta);
            t1 = std::min(t1, tb);
        }
        if (!(t0 < t1)) {
            return false;
        }
        // Start in the cell containing the midpoint of the first short stretch inside the
        // box, which is robust against the entry point lying on a face.
        const double tm = t0 + std::min(1e-9, (t1 - t0) / 2);
        for (std::size_t a = 0; a < 3; ++a) {
            const double p = o[a] + d[a] * tm;
            cell_[a] = std::clamp<std::int64_t>(static_cast<std::int64_t>(std::floor(p)), 0,
                                                static_cast<std::int64_t>(size_[a]) - 1);
            step_[a] = d[a] > 0 ? 1 : (d[a] < 0 ? -1 : 0);
            t_next_[a] = step_[a] == 0 ? INFINITY
                                       : (double(cell_[a] + (step_[a] > 0 ? 1 : 0)) - o[a]) / d[a];
        }
        return true;
    }

    // Moves to the next cell; returns the axis stepped along, or -1 when the ray left the
    // world.
    int step() {
        std::size_t a = 0;
        if (t_next_[1] < t_next_[a]) {
            a = 1;
        }
        if (t_next_[2] < t_next_[a]) {
            a = 2;
        }
        cell_[a] += step_[a];
        if (cell_[a] < 0 || cell_[a] >= static_cast<std::int64_t>(size_[a])) {
            return -1;
        }
        t_next_[a] = (double(cell_[a] + (step_[a] > 0 ? 1 : 0)) - o_[a]) / d_[a];
        return static_cast<int>(a);
    }

    std::size_t index(Dims dims) const {
        return dims.index(static_cast<std::uint32_t>(cell_[0]),
                          static_cast<std::uint32_t>(cell_[1]),
                          static_cast<std::uint32_t>(cell_[2]));
    }

  private:
    std::array<double, 3> size_{}, t_next_{};
    Vec3 o_{}, d_{};
    std::array<std::int64_t, 3> cell_{}, step_{};
};

// The palette colour of the first solid voxel along the ray, or false on a miss.
bool cast(const World& world, const Vec3& o, const Vec3& d, std::uint8_t& material) {
    Traversal t;
    if (!t.start(world.dims(), o, d)) {
        return false;
    }
    do {
        const std::uint8_t v = world.voxels()[t.index(world.dims())];
        if (v != 0) {
            material = v;
            return true;
        }
    } while (t.step() >= 0);
    return false;
}

// The pinhole camera of DESIGN §4, in double precision: core's camera model (image_basis,
// pixel_direction), which the ray marcher's host side hands the shader (vk::camera_basis), so
// every comparison below tests the shader against it.
class Pinhole {
  public:
    explicit Pinhole(const vk::RenderOptions& r) : r_(r) {}
    // The direction of pixel (i, j), j down.
    Vec3 dir(std::uint32_t i, std::uint32_t j) const { return at(i + 0.5, j + 0.5); }
    // The direction through image point (px, py) in pixels.
    Vec3 at(double px, double py) const {
        const Vec3 p = r_.camera.position, t = r_.camera.target;
        return pixel_direction({t[0] - p[0], t[1] - p[1], t[2] - p[2]}, r_.camera.fov_deg,
                               double(r_.width), double(r_.height), px, py);
    }

  private:
    vk::RenderOptions r_;
};

// RGBA8 image of flat shading: the palette colour of the hit voxel (alpha 255), else sky.
std::vector<std::uint8_t> cpu_render(const World& world, const Palette& palette,
                                     const vk::RenderOptions& r) {
    const Pinhole camera(r);
    std::vector<std::uint8_t> out(std::size_t{r.width} * r.height * 4);
    for (std::uint32_t j = 0; j < r.height; ++j) {
        for (std::uint32_t i = 0; i < r.width; ++i) {
            std::uint8_t m = 0;
            const Rgba c = cast(world, r.camera.position, camera.dir(i, j), m) ? palette[m] : r.sky;
            std::uint8_t* px = &out[(std::size_t{j} * r.width + i) * 4];
            px[0] = c.r;
            px[1] = c.g;
            px[2] = c.b;
            px[3] = 255;
        }
    }
    return out;
}

// The fetches and DDA steps of the rule raymarch.comp documents, walked on the CPU: from a
// fetch with distance d (8 bits; with `block_min`, a saturated 255 raised to the block's
// minimum) the ray steps while its per-axis step counts o stay inside the metric's empty
// region (L1: sum o < d, L-inf: max o < d, L2: sum o^2 < d^2) and fetches the first cell
// outside it.
struct Counts {
    std::uint64_t fetches = 0, steps = 0;
};

Counts model_counts(const World& world, const std::vector<std::uint32_t>& d, Metric metric,
                    const std::vector<std::uint32_t>* block_min, const vk::RenderOptions& r) {
    const Dims dims = world.dims();
    const std::uint32_t b = VF_RAYMARCH_BLOCK;
    const Dims nb{(dims.x + b - 1) / b, (dims.y + b - 1) / b, (dims.z + b - 1) / b};
    const Pinhole camera(r);
    Counts c;
    for (std::uint32_t j = 0; j < r.height; ++j) {
        for (std::uint32_t i = 0; i < r.width; ++i) {
            Traversal t;
            bool walking = t.start(dims, r.camera.position, camera.dir(i, j));
            while (walking) {
                const std::size_t at = t.index(dims);
                std::uint64_t dist = std::min<std::uint32_t>(d[at], 255);
                ++c.fetches;
                if (dist == 0) {
                    break;
                }
                if (block_min != nullptr && dist == 255) {
                    const std::size_t x = at % dims.x, y = at / dims.x % dims.y,
                                      z = at / (std::size_t{dims.x} * dims.y);
                    dist = std::max<std::uint64_t>(
                        dist, (*block_min)[nb.index(static_cast<std::uint32_t>(x / b),
                                                    static_cast<std::uint32_t>(y / b),
                                                    static_cast<std::uint32_t>(z / b))]);
                }
                std::array<std::uint64_t, 3> o{};
                for (;;) {
                    const int a = t.step();
                    ++c.steps;
                    if (a < 0) {
                        walking = false;
                        break;
                    }
                    ++o[static_cast<std::size_t>(a)];
                    const bool inside = metric == Metric::manhattan ? o[0] + o[1] + o[2] < dist
                                        : metric == Metric::chebyshev
                                            ? std::max({o[0], o[1], o[2]}) < dist
                                            : o[0] * o[0] + o[1] * o[1] + o[2] * o[2] < dist * dist;
                    if (!inside) {
                        break;
                    }
                }
            }
        }
    }
    return c;
}

struct Comparison {
    std::size_t differing = 0, sky = 0, pixels = 0;
    // Of the differing pixels, those that no tie explains (flat_comparison).
    std::size_t unexplained = 0;
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

// A flat-shaded image against the exact caster, pixel by pixel. Where they differ, the pixel
// must be a tie that the shader's float arithmetic decided and the caster's double did not: the
// image's colour is what the caster finds along a ray through a point within kTieRadius pixels
// of the pixel's centre (at a voxel edge or corner the ray passes within that of a neighbour:
// rounding of the float ray and of its DDA's accumulated crossings, at most ~1e-6 of the
// distance travelled, about 0.003 pixels for the farthest walls of these scenes). Any other
// difference (a skipped solid, a wrong material, a wrong ray) is "unexplained" and fails.
// An exact comparison cannot be promised for every driver: GLSL lets normalize() be off by
// 2 ULP and lets a driver contract a * b + c into an FMA, so which of two crossings a float DDA
// takes first at a corner is the driver's. On lavapipe (2026-12-03) no tie occurs at all: the
// 129 images this suite requires to be exact (806112 pixels) differ from the caster in none.
constexpr double kTieRadius = 0.01;

Rgba cast_colour(const World& world, const Palette& palette, const vk::RenderOptions& r,
                 const Vec3& dir) {
    std::uint8_t m = 0;
    return cast(world, r.camera.position, dir, m) ? palette[m] : r.sky;
}

Comparison flat_comparison(const std::vector<std::uint8_t>& got, const World& world,
                           const Palette& palette, const vk::RenderOptions& r) {
    const std::vector<std::uint8_t> want = cpu_render(world, palette, r);
    Comparison c = compare(got, want, r.sky);
    const Pinhole camera(r);
    for (std::uint32_t j = 0; j < r.height; ++j) {
        for (std::uint32_t i = 0; i < r.width; ++i) {
            const std::size_t at = (std::size_t{j} * r.width + i) * 4;
            if (std::memcmp(&got[at], &want[at], 4) == 0) {
                continue;
            }
            bool tie = false;
            for (const double radius : {kTieRadius / 16, kTieRadius / 4, kTieRadius}) {
                for (int k = 0; k < 8 && !tie; ++k) {
                    const double a = k * M_PI / 4;
                    const Rgba n = cast_colour(
                        world, palette, r,
                        camera.at(i + 0.5 + radius * std::cos(a), j + 0.5 + radius * std::sin(a)));
                    tie = got[at] == n.r && got[at + 1] == n.g && got[at + 2] == n.b &&
                          got[at + 3] == 255;
                }
            }
            c.unexplained += tie ? 0 : 1;
        }
    }
    return c;
}

// Renders the field of `metric` in `format` on the GPU and the world on the CPU and requires
// every pixel to be equal or a tie at a voxel edge (flat_comparison); also that the image is not
// trivial (some hits, and some sky when `want_sky`), and, for a metric other than manhattan, that
// it equals the manhattan field's image exactly (a solid skipped in a single pixel shows).
void expect_matches(vk::FieldFormat format, Metric metric, const World& world,
                    const Palette& palette, const vk::RenderOptions& r,
                    std::uint64_t max_binding_bytes = 0, bool want_sky = true,
                    std::uint32_t* bindings = nullptr) {
    vk::Raymarcher marcher(vulkan(), max_binding_bytes);
    upload(marcher, world, palette, format, metric);
    if (bindings != nullptr) {
        *bindings = marcher.field_bindings();
    }
    const vk::Image img = marcher.render(r);
    ASSERT_EQ(img.rgba.size(), std::size_t{r.width} * r.height * 4);
    const Comparison c = flat_comparison(img.rgba, world, palette, r);
    EXPECT_EQ(c.unexplained, 0u) << c.unexplained << " of " << c.pixels << " pixels differ ("
                                 << to_string(metric) << ") where no tie explains it";
    EXPECT_LT(c.sky, c.pixels) << "nothing was hit: the test would prove nothing";
    if (want_sky) {
        EXPECT_GT(c.sky, 0u) << "no ray missed";
    }
    if (metric != Metric::manhattan) {
        upload(marcher, world, palette, format);
        const vk::Image l1 = marcher.render(r);
        EXPECT_EQ(compare(img.rgba, l1.rgba, r.sky).differing, 0u)
            << "the " << to_string(metric) << " field's image differs from manhattan's";
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

// Every scene in both field formats, with the field of every metric.
class Raymarch : public ::testing::TestWithParam<std::tuple<vk::FieldFormat, Metric>> {
  protected:
    static vk::FieldFormat format() { return std::get<0>(GetParam()); }
    static Metric metric() { return std::get<1>(GetParam()); }
};

TEST_P(Raymarch, SingleVoxelIncludingABlackMaterial) {
    World world(Dims{8, 8, 8});
    world.set(3, 4, 5, 5);
    Palette palette;
    palette[5] = Rgba{0, 0, 0, 255};  // solid and black: distance 0 marks solids, not colour
    expect_matches(format(), metric(), world, palette,
                   options(64, 48, {-6, 9, -4}, {3.5, 4.5, 5.5}, 30));
    world.set(3, 4, 5, 79);
    expect_matches(format(), metric(), world, palette,
                   options(64, 48, {12, -3, 14}, {3.5, 4.5, 5.5}, 25));
}

TEST_P(Raymarch, FloorAndSpheres) {
    const World world = scene_floor_spheres(Dims{64, 64, 64}, 6683787);
    vk::RenderOptions r = options(128, 96, {}, {});
    r.camera = vk::default_camera(world.dims());
    expect_matches(format(), metric(), world, Palette(), r);
}

TEST_P(Raymarch, MengerSpongeThroughTunnels) {
    const World world = scene_menger(Dims{81, 81, 81});
    ASSERT_GT(world.solid_count(), 0u);
    // Down the z tunnels, slightly off axis so that rays travel far through them.
    expect_matches(format(), metric(), world, Palette(),
                   options(96, 96, {40.3, 40.6, -50}, {40.5, 40.5, 81}, 50), 0, false);
    // Oblique, from a corner.
    expect_matches(format(), metric(), world, Palette(),
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
    expect_matches(format(), metric(), world, Palette(),
                   options(96, 72, {31.2, 1.3, -80}, {33.4, 0.8, 64}, 40));
    expect_matches(format(), metric(), world, Palette(),
                   options(96, 72, {20, 30, -10}, {36, 28, 70}, 70));
}

TEST_P(Raymarch, CameraInsideTheWorld) {
    const World world = scene_floor_spheres(Dims{64, 64, 64}, 6683787);
    expect_matches(format(), metric(), world, Palette(),
                   options(96, 72, {10, 20, 12}, {40, 10, 50}, 90), 0, false);
    // Inside a solid voxel: every ray hits it at once.
    World filled(Dims{16, 16, 16});
    filled.set(5, 6, 7, 42);
    expect_matches(format(), metric(), filled, Palette(),
                   options(16, 16, {5.5, 6.5, 7.5}, {9, 9, 9}), 0, false);
}

TEST_P(Raymarch, CameraOutsideLookingPast) {
    const World world = scene_floor_spheres(Dims{64, 64, 64}, 6683787);
    // The world is at the right edge of the view; most rays miss it.
    expect_matches(format(), metric(), world, Palette(),
                   options(96, 72, {-20, 30, -20}, {-25, 28, 60}));
    // Looking straight away from it: nothing is hit.
    vk::Raymarcher marcher(vulkan());
    upload(marcher, world, Palette(), format(), metric());
    const auto r = options(32, 24, {-20, 30, -20}, {-60, 30, -60});
    const auto img = marcher.render(r);
    EXPECT_EQ(compare(img.rgba, cpu_render(world, Palette(), r), r.sky).differing, 0u);
    EXPECT_EQ(compare(img.rgba, cpu_render(world, Palette(), r), r.sky).sky, 32u * 24u);
}

TEST_P(Raymarch, DistantCamera) {
    const World world = scene_floor_spheres(Dims{64, 64, 64}, 6683787);
    // About 5000 voxels away with a narrow field of view: float must not lose the voxels.
    expect_matches(format(), metric(), world, Palette(),
                   options(96, 72, {-2900, 2400, -3300}, {32, 20, 32}, 1.2));
}

TEST_P(Raymarch, StraightDownAlongY) {
    const World world = scene_floor_spheres(Dims{48, 40, 32}, 3);
    expect_matches(format(), metric(), world, Palette(),
                   options(64, 64, {20.3, 90, 15.2}, {20.3, 0, 15.2}), 0, false);
}

TEST_P(Raymarch, FieldSplitAcrossBindings) {
    const World world = scene_floor_spheres(Dims{64, 64, 64}, 6683787);
    vk::RenderOptions r = options(96, 72, {}, {});
    r.camera = vk::default_camera(world.dims());
    std::uint32_t bindings = 0;
    // Ten z-slices per binding: 7 bindings, the last one shorter.
    expect_matches(format(), metric(), world, Palette(), r,
                   64 * 64 * vk::element_size(format()) * 10, true, &bindings);
    EXPECT_EQ(bindings, 7u);
}

TEST_P(Raymarch, RefusesMoreBindingsThanItHas) {
    const World world = scene_floor_spheres(Dims{16, 16, 64}, 1);
    // One slice per binding: 64 > 8.
    vk::Raymarcher marcher(vulkan(), 16 * 16 * vk::element_size(format()));
    EXPECT_THROW(upload(marcher, world, Palette(), format(), metric()), InputError);
}

// 520x256x256 packed32 = 136 MiB, more than lavapipe's 128 MiB maxStorageBufferRange.
TEST_P(Raymarch, WorldLargerThanOneBinding) {
    const World world = scene_floor_spheres(Dims{520, 256, 256}, 6683787);
    vk::RenderOptions r = options(64, 48, {}, {});
    r.camera = vk::default_camera(world.dims());
    std::uint32_t bindings = 0;
    expect_matches(format(), metric(), world, Palette(), r, 0, true, &bindings);
    const std::uint64_t field_bytes = world.size() * vk::element_size(format());
    if (vulkan().info().max_storage_buffer_range < field_bytes) {
        EXPECT_GE(bindings, 2u);
    }
    // A second view from inside, along the long axis.
    expect_matches(format(), metric(), world, Palette(),
                   options(48, 32, {5, 40, 128}, {515, 20, 120}, 70), 0, false);
}

TEST_P(Raymarch, LitShadingHitsWhatFlatHits) {
    const World world = scene_floor_spheres(Dims{64, 64, 64}, 6683787);
    vk::Raymarcher marcher(vulkan());
    upload(marcher, world, Palette(), format(), metric());
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
        if (cpu_sky != gpu_sky) {
            // Hit or miss decided by float rounding: a ray within kTieRadius pixels agrees.
            const Pinhole camera(r);
            const std::uint32_t pi = static_cast<std::uint32_t>(i % r.width);
            const std::uint32_t pj = static_cast<std::uint32_t>(i / r.width);
            bool tie = false;
            for (int k = 0; k < 8 && !tie; ++k) {
                std::uint8_t m = 0;
                const double a = k * M_PI / 4;
                tie = cast(world, r.camera.position,
                           camera.at(pi + 0.5 + kTieRadius * std::cos(a),
                                     pj + 0.5 + kTieRadius * std::sin(a)),
                           m) != gpu_sky;
            }
            mask_differs += tie ? 0 : 1;
        }
        hits += !cpu_sky;
        std::uint32_t c = 0;
        std::memcpy(&c, &lit.rgba[i * 4], 4);
        colours.push_back(c);
        EXPECT_EQ(lit.rgba[i * 4 + 3], 255);
    }
    std::sort(colours.begin(), colours.end());
    EXPECT_GT(hits, 0u);
    EXPECT_EQ(mask_differs, 0u) << "hit or miss differs from flat shading's beyond a tie";
    EXPECT_GT(std::unique(colours.begin(), colours.end()) - colours.begin(), 10);
    // The gradient sky is not flat.
    r.sky_gradient = true;
    const auto sky = marcher.render(r);
    EXPECT_NE(std::memcmp(&sky.rgba[0], &sky.rgba[(std::size_t{r.height} - 1) * r.width * 4], 3),
              0);
}

// A floor (material 1), a thin roof slab high above part of it and a wall (material 2), all
// white, seen straight from above: the sun, normalize(1, 1, 1), casts the roof's and the wall's
// shadows on the floor toward -x, -z.
World shadow_scene() {
    World w(Dims{48, 24, 48});
    for (std::uint32_t z = 0; z < 48; ++z) {
        for (std::uint32_t x = 0; x < 48; ++x) {
            w.set(x, 0, z, 1);
            for (std::uint32_t y = 1; y < 12 && x >= 32 && x < 34; ++y) {
                w.set(x, y, z, 2);
            }
            if (x >= 8 && x < 26 && z >= 8 && z < 26) {
                w.set(x, 9, z, 2);  // one voxel thick: a shadow ray must not skip it
            }
        }
    }
    return w;
}

Palette white_palette() {
    Palette p;
    p[1] = Rgba{255, 255, 255, 255};
    p[2] = Rgba{255, 255, 255, 255};
    return p;
}

TEST_P(Raymarch, LitShadingCastsShadowsTowardTheSun) {
    const World world = shadow_scene();
    const Palette palette = white_palette();
    vk::Raymarcher marcher(vulkan());
    upload(marcher, world, palette, format(), metric());
    vk::RenderOptions r = options(160, 160, {24, 80, 24}, {24, 0, 24}, 40);
    r.shading = vk::Shading::lit;
    const auto img = marcher.render(r);
    const Pinhole camera(r);
    const Vec3 sun = normalized({1, 1, 1});
    // Whether the floor point p (on its top face, y = 1) sees the sun, by the CPU traversal.
    auto sunlit = [&](double x, double z) {
        std::uint8_t m = 0;
        return !cast(world, {x, 1.0 + 1e-6, z}, sun, m);
    };
    std::size_t shadowed = 0, lit = 0, wrong = 0;
    for (std::uint32_t j = 0; j < r.height; ++j) {
        for (std::uint32_t i = 0; i < r.width; ++i) {
            const Vec3 d = camera.dir(i, j);
            std::uint8_t m = 0;
            if (!cast(world, r.camera.position, d, m) || m != 1) {
                continue;  // the roof or the wall
            }
            const double t = (1.0 - r.camera.position[1]) / d[1];
            const double x = r.camera.position[0] + t * d[0], z = r.camera.position[2] + t * d[2];
            const bool want = sunlit(x, z);
            // Points within a twentieth of a voxel of a shadow's edge may go either way.
            if (sunlit(x + 0.05, z) != want || sunlit(x - 0.05, z) != want ||
                sunlit(x, z + 0.05) != want || sunlit(x, z - 0.05) != want) {
                continue;
            }
            // Lit white floor: (ambient * ao + 0.8 * 0.577) >= 0.58 linear; shadowed: <= 0.30.
            const bool got = img.rgba[(std::size_t{j} * r.width + i) * 4] > 175;
            (want ? lit : shadowed) += 1;
            wrong += got != want;
        }
    }
    EXPECT_GT(shadowed, 1000u);
    EXPECT_GT(lit, 1000u);
    EXPECT_EQ(wrong, 0u) << "of " << shadowed << " shadowed and " << lit << " lit floor pixels";
}

TEST_P(Raymarch, AmbientOcclusionDarkensEnclosedFaces) {
    const World world = shadow_scene();
    vk::Raymarcher marcher(vulkan());
    upload(marcher, world, white_palette(), format(), metric());
    // From above the floor east of the wall, so that the wall hides none of it.
    vk::RenderOptions r = options(160, 160, {40, 80, 24}, {40, 0, 24}, 40);
    r.shading = vk::Shading::lit;
    // The red byte of the floor point (x, 1, z) in image `img`.
    auto red_at = [&](const vk::Image& img, double x, double z) {
        const auto p = project_point(r.camera.position, Vec3d{0, -1, 0}, r.camera.fov_deg, r.width,
                                     r.height, Vec3d{x, 1.0, z});
        EXPECT_TRUE(p.has_value());
        const auto i = static_cast<std::size_t>(p->x), j = static_cast<std::size_t>(p->y);
        return int(img.rgba[(j * r.width + i) * 4]);
    };
    const auto lit = marcher.render(r);
    // Sunlit floor beside the wall's sunny face (the cells above it have the wall one voxel
    // away) and in the open, at the same z.
    const int enclosed = red_at(lit, 34.5, 40.5), open = red_at(lit, 44.5, 40.5);
    EXPECT_GT(enclosed, 175) << "sunlit";
    EXPECT_LT(enclosed + 10, open) << "occlusion beside the wall";
    // Flat shading has none: both are the palette's white.
    r.shading = vk::Shading::flat;
    const auto flat = marcher.render(r);
    EXPECT_EQ(red_at(flat, 34.5, 40.5), 255);
    EXPECT_EQ(red_at(flat, 44.5, 40.5), 255);
}

TEST_P(Raymarch, GpuTimestamps) {
    if (!vulkan().info().timestamps) {
        GTEST_SKIP() << vulkan().info().name << " has no compute timestamps";
    }
    const World world = scene_floor_spheres(Dims{32, 32, 32}, 1);
    vk::Raymarcher marcher(vulkan());
    upload(marcher, world, Palette(), format(), metric());
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
// packed32 test world above is only 68 MiB compact); the field of every metric.
TEST(RaymarchCompact, WorldLargerThanOneBinding) {
    const World world = scene_floor_spheres(Dims{520, 256, 512}, 6683787);
    vk::RenderOptions r = options(64, 48, {}, {});
    r.camera = vk::default_camera(world.dims());
    for (const Metric metric : {Metric::manhattan, Metric::chebyshev, Metric::euclidean}) {
        std::uint32_t bindings = 0;
        expect_matches(vk::FieldFormat::compact, metric, world, Palette(), r, 0, true, &bindings);
        if (vulkan().info().max_storage_buffer_range < world.size() * 2) {
            EXPECT_GE(bindings, 2u);
        }
    }
}

// Per-8^3-block minima of unsaturated distances (layout.h VF_RAYMARCH_BLOCK).
std::vector<std::uint32_t> block_minima(const World& world, const std::vector<std::uint32_t>& d) {
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

// Solids hundreds of voxels apart: the 8-bit field saturates at 255 around x = 300, where the
// block minima let rays take longer strides.
World far_apart_world() {
    World world(Dims{700, 24, 24});
    world.set(690, 12, 12, 9);
    world.set(5, 20, 2, 33);
    for (std::uint32_t z = 0; z < 24; ++z) {
        for (std::uint32_t y = 0; y < 24; ++y) {
            world.set(600, y, z, 44);  // a wall across the world
        }
    }
    return world;
}

std::vector<vk::RenderOptions> far_apart_views() {
    return {options(160, 60, {-30, 12, 12}, {700, 12, 12}, 20),
            options(120, 80, {300, 60, -200}, {600, 12, 12}, 30),
            options(100, 100, {699.5, 23.5, 23.5}, {0, 0, 0}, 40),
            // From inside the saturated stretch, towards the wall.
            options(80, 60, {300.5, 12.5, 12.5}, {600, 11, 13}, 4)};
}

// 400 voxels at pseudo-random places in 40^3, nearly all of them isolated.
World isolated_voxels() {
    World world(Dims{40, 40, 40});
    std::uint64_t state = 6683787;
    for (std::uint32_t i = 0; i < 400; ++i) {
        std::array<std::uint32_t, 3> p{};
        for (std::uint32_t& v : p) {
            state = state * 6364136223846793005ull + 1442695040888963407ull;
            v = static_cast<std::uint32_t>(state >> 33) % 40;
        }
        world.set(p[0], p[1], p[2], static_cast<std::uint8_t>(1 + i % 250));
    }
    return world;
}

// The fast transforms the tests use agree with core's reference (rounded down) on these
// tests' worlds, and on one without any solid.
TEST(RaymarchFields, FastTransformsEqualTheReference) {
    for (const World& world :
         {scene_floor_spheres(Dims{64, 64, 64}, 6683787), scene_menger(Dims{81, 81, 81}),
          isolated_voxels(), far_apart_world(), World(Dims{5, 6, 7})}) {
        for (const Metric metric : {Metric::chebyshev, Metric::euclidean}) {
            const std::vector<double> real = reference_distance(world, metric, Spacing{});
            std::vector<std::uint32_t> want(real.size());
            for (std::size_t i = 0; i < want.size(); ++i) {
                want[i] = std::isinf(real[i]) ? kInfinite
                                              : static_cast<std::uint32_t>(std::floor(real[i]));
            }
            EXPECT_TRUE(distances(world, metric) == want)
                << to_string(metric) << " on " << world.dims().to_string();
        }
    }
}

class RaymarchMetric : public ::testing::TestWithParam<Metric> {};

TEST_P(RaymarchMetric, CoarseSkippingBeyondSaturatedDistances) {
    // Images must not change with the block minima of the metric's field.
    const World world = far_apart_world();
    const auto d = distances(world, GetParam());
    const Palette palette;
    for (const vk::RenderOptions& r : far_apart_views()) {
        vk::Raymarcher marcher(vulkan());
        upload(marcher, world, palette, vk::FieldFormat::compact, GetParam(), d);
        const auto plain = marcher.render(r);
        marcher.set_block_min(block_minima(world, d));
        const auto coarse = marcher.render(r);
        const Comparison c = flat_comparison(coarse.rgba, world, palette, r);
        EXPECT_EQ(c.unexplained, 0u) << c.differing << " pixels differ";
        EXPECT_LT(c.sky, c.pixels) << "nothing was hit: the test would prove nothing";
        EXPECT_EQ(compare(coarse.rgba, plain.rgba, r.sky).differing, 0u)
            << "coarse skipping changed the image";
    }
    vk::Raymarcher marcher(vulkan());
    upload(marcher, world, palette, vk::FieldFormat::compact, GetParam(), d);
    EXPECT_THROW(marcher.set_block_min(std::vector<std::uint32_t>(3, 0)), InputError);
}

TEST_P(RaymarchMetric, InflatedBlockMinimaSkipTheWall) {
    // The comparison above has teeth: doubled minima carry rays through the wall at x = 600.
    const World world = far_apart_world();
    const auto d = distances(world, GetParam());
    std::vector<std::uint32_t> inflated = block_minima(world, d);
    for (std::uint32_t& m : inflated) {
        m *= 2;
    }
    const Palette palette;
    const vk::RenderOptions r = far_apart_views()[3];
    vk::Raymarcher marcher(vulkan());
    upload(marcher, world, palette, vk::FieldFormat::compact, GetParam(), d);
    marcher.set_block_min(inflated);
    const Comparison c = flat_comparison(marcher.render(r).rgba, world, palette, r);
    EXPECT_GT(double(c.unexplained), 0.005 * double(c.pixels))
        << "inflated minima left the image intact: the coarse test would not notice";
}

// The words of `boxes` (block boxes) in `table`, box after box and x fastest in each, as
// update_block_min takes them.
std::vector<std::uint32_t> box_words(const std::vector<std::uint32_t>& table, Dims grid,
                                     const std::vector<Box>& boxes) {
    std::vector<std::uint32_t> out;
    for (const Box& b : boxes) {
        for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
            for (std::int64_t y = b.min.y; y < b.max.y; ++y) {
                for (std::int64_t x = b.min.x; x < b.max.x; ++x) {
                    out.push_back(table[grid.index(static_cast<std::uint32_t>(x),
                                                   static_cast<std::uint32_t>(y),
                                                   static_cast<std::uint32_t>(z))]);
                }
            }
        }
    }
    return out;
}

TEST_P(RaymarchMetric, UpdatedBlockMinimaReachOnlyTheirBlocks) {
    // Inflated minima carry rays through the wall (above). Rewriting every block from the true
    // minima, in boxes of several shapes, restores the image; then inflating only the blocks
    // of the saturated stretch breaks it again and rewriting just those mends it: each update
    // reaches its own blocks and no others, and copies only their words.
    const World world = far_apart_world();
    const Dims grid{88, 3, 3};  // ceil(700x24x24 / 8)
    const auto d = distances(world, GetParam());
    const std::vector<std::uint32_t> minima = block_minima(world, d);
    ASSERT_EQ(minima.size(), grid.count());
    std::vector<std::uint32_t> inflated = minima;
    for (std::uint32_t& m : inflated) {
        m *= 2;
    }
    const vk::RenderOptions r = far_apart_views()[3];
    vk::Raymarcher marcher(vulkan());
    upload(marcher, world, Palette(), vk::FieldFormat::compact, GetParam(), d);
    marcher.set_block_min(minima);
    const std::vector<std::uint8_t> want = marcher.render(r).rgba;
    marcher.set_block_min(inflated);
    ASSERT_NE(marcher.render(r).rgba, want);
    EXPECT_EQ(marcher.block_min_bytes_copied(), 2 * 4 * grid.count());

    const std::vector<Box> everything = {Box{{0, 0, 0}, {88, 3, 1}}, Box{{0, 0, 1}, {40, 2, 3}},
                                         Box{{0, 2, 1}, {40, 3, 3}}, Box{{40, 0, 1}, {88, 3, 3}},
                                         Box{{5, 1, 1}, {5, 2, 2}}};  // empty
    std::uint64_t copied = marcher.block_min_bytes_copied();
    marcher.update_block_min(everything, box_words(minima, grid, everything));
    EXPECT_EQ(marcher.block_min_bytes_copied() - copied, 4 * grid.count());
    EXPECT_EQ(marcher.render(r).rgba, want);

    const std::vector<Box> stretch = {Box{{30, 0, 0}, {46, 3, 3}}};  // x 240..368
    marcher.update_block_min(stretch, box_words(inflated, grid, stretch));
    EXPECT_NE(marcher.render(r).rgba, want);
    copied = marcher.block_min_bytes_copied();
    marcher.update_block_min(stretch, box_words(minima, grid, stretch));
    EXPECT_EQ(marcher.block_min_bytes_copied() - copied, 4u * 16 * 3 * 3);
    EXPECT_EQ(marcher.render(r).rgba, want);

    EXPECT_THROW(
        marcher.update_block_min({{Box{{80, 0, 0}, {89, 1, 1}}}}, std::vector<std::uint32_t>(9, 0)),
        InputError);
    EXPECT_THROW(marcher.update_block_min(stretch, std::vector<std::uint32_t>(3, 0)), InputError);
    // A new field has no table to update.
    upload(marcher, world, Palette(), vk::FieldFormat::compact, GetParam(), d);
    EXPECT_THROW(marcher.update_block_min(stretch, box_words(minima, grid, stretch)),
                 std::logic_error);
}

// update_compact copies the edited field but keeps the palette, the metric and the table.
TEST_P(RaymarchMetric, UpdatedCompactFieldKeepsPaletteMetricAndTable) {
    World world = far_apart_world();
    const auto d = distances(world, GetParam());
    Palette palette;
    palette[44] = Rgba{200, 10, 20, 255};
    vk::Raymarcher marcher(vulkan());
    upload(marcher, world, palette, vk::FieldFormat::compact, GetParam(), d);
    marcher.set_block_min(block_minima(world, d));
    const std::uint64_t copied = marcher.block_min_bytes_copied();
    // Recolour the wall: the distances stay, so do the minima.
    for (std::uint32_t z = 0; z < 24; ++z) {
        for (std::uint32_t y = 0; y < 24; ++y) {
            world.set(600, y, z, 9);
        }
    }
    marcher.update_compact(compact_field(world, d));
    EXPECT_EQ(marcher.metric(), GetParam());
    EXPECT_EQ(marcher.block_min_bytes_copied(), copied);
    for (const vk::RenderOptions& r : far_apart_views()) {
        const Comparison c = flat_comparison(marcher.render(r).rgba, world, palette, r);
        EXPECT_EQ(c.unexplained, 0u) << c.differing << " pixels differ";
    }
    EXPECT_THROW(marcher.update_compact(std::vector<std::uint16_t>(5, 0)), InputError);
    marcher.upload(world, palette, packed_field(world, palette, d));
    EXPECT_THROW(marcher.update_compact(compact_field(world, d)), std::logic_error);
}

// A field inflated by one (every empty voxel's distance + 1) is what a step one cell too long
// in each metric's rule would amount to. A ray always reaches the voxel it hits as the first
// cell outside the last fetch's empty region, so such a step walks past that voxel: into the
// next voxel of a thick solid (same colour, which is why the scenes above barely notice), but
// past an isolated voxel entirely. Among isolated voxels the image must change well beyond
// the comparisons' tolerance.
TEST_P(RaymarchMetric, StepOneTooLongIsCaught) {
    const World world = isolated_voxels();
    vk::RenderOptions around = options(96, 72, {}, {});
    around.camera = vk::default_camera(world.dims());
    for (const vk::FieldFormat format : {vk::FieldFormat::packed32, vk::FieldFormat::compact}) {
        for (const vk::RenderOptions& r : {around, options(96, 72, {3, 30, 5}, {30, 10, 35}, 80)}) {
            std::vector<std::uint32_t> d = distances(world, GetParam());
            vk::Raymarcher marcher(vulkan());
            upload(marcher, world, Palette(), format, GetParam(), d);
            const Comparison exact = flat_comparison(marcher.render(r).rgba, world, Palette(), r);
            EXPECT_EQ(exact.unexplained, 0u) << exact.differing << " pixels differ";
            for (std::uint32_t& v : d) {
                v = v == 0 || v == kInfinite ? v : v + 1;
            }
            upload(marcher, world, Palette(), format, GetParam(), d);
            const Comparison c = flat_comparison(marcher.render(r).rgba, world, Palette(), r);
            EXPECT_GT(double(c.unexplained), 0.005 * double(c.pixels))
                << vk::to_string(format) << ": only " << c.unexplained << " of " << c.pixels
                << " pixels changed";
        }
    }
}

// The counters report exactly the documented rule's fetches and steps (up to rays whose
// float traversal resolves a tie at a voxel edge differently from the double one), so a step
// longer or shorter than the rule shows as a count that disagrees; and the metric's own step
// needs fewer fetches than manhattan's (the rule safe for every field) on the same field,
// for the same image.
TEST_P(RaymarchMetric, CountsFollowTheMetricsRule) {
    const World spheres = scene_floor_spheres(Dims{64, 64, 64}, 6683787);
    const World menger = scene_menger(Dims{81, 81, 81});
    vk::RenderOptions around = options(96, 72, {}, {});
    around.camera = vk::default_camera(spheres.dims());
    const std::vector<std::pair<const World*, vk::RenderOptions>> views = {
        {&spheres, around},
        {&menger, options(96, 72, {-30, 95, -40}, {40.5, 40.5, 40.5})},
        {&menger, options(96, 96, {40.3, 40.6, -50}, {40.5, 40.5, 81}, 50)}};
    for (const vk::FieldFormat format : {vk::FieldFormat::packed32, vk::FieldFormat::compact}) {
        for (const auto& [world, view] : views) {
            vk::RenderOptions r = view;
            r.count = true;
            const auto d = distances(*world, GetParam());
            vk::Raymarcher marcher(vulkan());
            upload(marcher, *world, Palette(), format, GetParam(), d);
            const vk::Image img = marcher.render(r);
            const Counts want = model_counts(*world, d, GetParam(), nullptr, r);
            ASSERT_GT(want.fetches, 0u);
            EXPECT_NEAR(double(img.fetches), double(want.fetches), 0.002 * double(want.fetches))
                << vk::to_string(format);
            EXPECT_NEAR(double(img.steps), double(want.steps), 0.002 * double(want.steps))
                << vk::to_string(format);
            // Counting does not change the image.
            vk::RenderOptions plain = r;
            plain.count = false;
            EXPECT_EQ(compare(marcher.render(plain).rgba, img.rgba, r.sky).differing, 0u);
            if (GetParam() != Metric::manhattan) {
                marcher.set_metric(Metric::manhattan);
                const vk::Image l1_rule = marcher.render(r);
                EXPECT_EQ(compare(l1_rule.rgba, img.rgba, r.sky).differing, 0u);
                EXPECT_LT(img.fetches, l1_rule.fetches) << vk::to_string(format);
                const Counts l1_model = model_counts(*world, d, Metric::manhattan, nullptr, r);
                EXPECT_NEAR(double(l1_rule.fetches), double(l1_model.fetches),
                            0.002 * double(l1_model.fetches));
            }
        }
    }
    // With coarse skipping, where the block minima raise saturated distances.
    const World world = far_apart_world();
    const auto d = distances(world, GetParam());
    const auto minima = block_minima(world, d);
    vk::Raymarcher marcher(vulkan());
    upload(marcher, world, Palette(), vk::FieldFormat::compact, GetParam(), d);
    marcher.set_block_min(minima);
    for (vk::RenderOptions r : far_apart_views()) {
        r.count = true;
        const vk::Image img = marcher.render(r);
        const Counts want = model_counts(world, d, GetParam(), &minima, r);
        EXPECT_NEAR(double(img.fetches), double(want.fetches), 0.002 * double(want.fetches));
        EXPECT_NEAR(double(img.steps), double(want.steps), 0.002 * double(want.steps));
    }
}

TEST_P(RaymarchMetric, NewFieldResetsTheMetric) {
    const World world = scene_floor_spheres(Dims{16, 16, 16}, 1);
    vk::Raymarcher marcher(vulkan());
    upload(marcher, world, Palette(), vk::FieldFormat::compact, GetParam());
    EXPECT_EQ(marcher.metric(), GetParam());
    marcher.upload_compact(world.dims(), Palette(),
                           compact_field(world, distances(world, Metric::manhattan)));
    EXPECT_EQ(marcher.metric(), Metric::manhattan);
    marcher.set_metric(GetParam());
    marcher.upload(world, Palette(),
                   packed_field(world, Palette(), distances(world, Metric::manhattan)));
    EXPECT_EQ(marcher.metric(), Metric::manhattan);
    // Counting is for render(); render_to refuses it.
    vk::RenderOptions r = options(8, 8, {-5, 20, -5}, {8, 8, 8});
    r.count = true;
    EXPECT_THROW(marcher.render_to(r, vk::ExternalMemory()), std::logic_error);
}

TEST(RaymarchFrames, ReplacedResourcesAreRetiredUntilTheFrameFinished) {
    // A recorded frame waits behind a submission that waits for the host (an event): a new
    // field, palette and image size meanwhile must not free what the frame reads (validation
    // reports destroying it in use) but retire it until the frame's fence signalled.
    vk::Context& ctx = vulkan();
    const World world = make_scene("spheres", Dims{16, 16, 16}, 5);
    const auto field = compact_field(world, distances(world, Metric::manhattan));
    vk::Raymarcher marcher(ctx);
    marcher.upload_compact(world.dims(), Palette(), field);
    const vk::RenderOptions r = options(32, 24, {-5, 20, -5}, {8, 8, 8});
    const vk::Image want = marcher.render(r);
    ctx.wait_frames_in_flight();
    ASSERT_EQ(ctx.retired_in_flight(), 0u);

    HostGate gate(ctx, 3);
    const std::vector<VkCommandBuffer>& cmd = gate.cmd;
    const std::vector<VkFence>& fence = gate.fence;
    const vk::Buffer out =
        ctx.make_buffer(VkDeviceSize{r.width} * r.height * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                        vk::MemoryIntent::readback, "frame");
    VkCommandBufferBeginInfo bi{};
    bi.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
    ASSERT_EQ(vkBeginCommandBuffer(cmd[0], &bi), VK_SUCCESS);
    gate.record_wait(cmd[0], VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
    ASSERT_EQ(vkEndCommandBuffer(cmd[0]), VK_SUCCESS);
    ASSERT_EQ(vkBeginCommandBuffer(cmd[1], &bi), VK_SUCCESS);
    const VkImage image = marcher.record(cmd[1], r);
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {r.width, r.height, 1};
    vkCmdCopyImageToBuffer(cmd[1], image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, out.get(), 1,
                           &region);
    VkMemoryBarrier to_host{};
    to_host.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
    to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
    to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
    vkCmdPipelineBarrier(cmd[1], VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1,
                         &to_host, 0, nullptr, 0, nullptr);
    ASSERT_EQ(vkEndCommandBuffer(cmd[1]), VK_SUCCESS);
    for (std::size_t i = 0; i < 2; ++i) {
        VkSubmitInfo si{};
        si.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
        si.commandBufferCount = 1;
        si.pCommandBuffers = &cmd[i];
        ctx.submit(si, fence[i], "frame " + std::to_string(i));
    }
    // While the frame waits: another field (and palette) and another image size.
    marcher.upload_compact(world.dims(), Palette::dissertation(), field);
    const std::size_t retired = ctx.retired_in_flight();
    EXPECT_GE(retired, 2u) << "the old field and palette (and descriptor set) were not retired";
    // A second frame at another size (a new offscreen image; the old one is retired too).
    vk::RenderOptions smaller = r;
    smaller.width = 16;
    ASSERT_EQ(vkBeginCommandBuffer(cmd[2], &bi), VK_SUCCESS);
    marcher.record(cmd[2], smaller);
    ASSERT_EQ(vkEndCommandBuffer(cmd[2]), VK_SUCCESS);
    VkSubmitInfo si{};
    si.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    si.commandBufferCount = 1;
    si.pCommandBuffers = &cmd[2];
    ctx.submit(si, fence[2], "frame 2");
    EXPECT_GT(ctx.retired_in_flight(), retired) << "the old image was not retired";
    EXPECT_TRUE(ctx.busy());
    gate.open();
    ctx.wait(fence[2], "frame 2");
    EXPECT_EQ(ctx.retired_in_flight(), 0u);
    EXPECT_FALSE(ctx.busy());
    EXPECT_EQ(std::memcmp(out.data(), want.rgba.data(), want.rgba.size()), 0)
        << "the frame did not read the field it was recorded with";
    if (ctx.info().timestamps) {
        EXPECT_GE(marcher.finished_raymarch_ms(), 0.0);
    }
    // The new field and palette, at another size, after the wait.
    EXPECT_EQ(marcher.render(smaller).width, 16u);
}

INSTANTIATE_TEST_SUITE_P(Metrics, RaymarchMetric,
                         ::testing::Values(Metric::manhattan, Metric::chebyshev, Metric::euclidean),
                         [](const auto& p) { return to_string(p.param); });

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

INSTANTIATE_TEST_SUITE_P(
    FormatsAndMetrics, Raymarch,
    ::testing::Combine(::testing::Values(vk::FieldFormat::packed32, vk::FieldFormat::compact),
                       ::testing::Values(Metric::manhattan, Metric::chebyshev, Metric::euclidean)),
    [](const auto& p) {
        return vk::to_string(std::get<0>(p.param)) + "_" + to_string(std::get<1>(p.param));
    });

}  // namespace
}  // namespace voxfield::test
