// The viewer's camera: free-fly (the dissertation's demo controls) and orbit, plus the
// DESIGN §4 pinhole rays.
#include "voxfield/core/camera.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "voxfield/core/error.hpp"

namespace voxfield {

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Vec3d add(const Vec3d& a, const Vec3d& b) {
    return {a[0] + b[0], a[1] + b[1], a[2] + b[2]};
}
Vec3d sub(const Vec3d& a, const Vec3d& b) {
    return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}
Vec3d scale(const Vec3d& a, double s) {
    return {a[0] * s, a[1] * s, a[2] * s};
}
double dot(const Vec3d& a, const Vec3d& b) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
double length(const Vec3d& a) {
    return std::sqrt(dot(a, a));
}
Vec3d cross(const Vec3d& a, const Vec3d& b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
bool finite(const Vec3d& a) {
    return std::isfinite(a[0]) && std::isfinite(a[1]) && std::isfinite(a[2]);
}

}  // namespace

Vec3d direction_from_angles(double yaw_deg, double pitch_deg) {
    const double cy = std::cos(yaw_deg * kDeg), sy = std::sin(yaw_deg * kDeg);
    const double cp = std::cos(pitch_deg * kDeg), sp = std::sin(pitch_deg * kDeg);
    return {cp * cy, sp, cp * sy};
}

ViewBasis view_basis(const Vec3d& forward) {
    ViewBasis b;
    b.forward = scale(forward, 1 / length(forward));
    Vec3d right = cross(b.forward, Vec3d{0, 1, 0});
    if (length(right) < 1e-9) {
        right = {1, 0, 0};  // looking straight along +-y: image right is +x
    }
    b.right = scale(right, 1 / length(right));
    b.up = cross(b.right, b.forward);
    return b;
}

ImageBasis image_basis(const Vec3d& forward, double fov_deg, double width, double height) {
    const ViewBasis v = view_basis(forward);
    const double half = std::tan(fov_deg * kDeg / 2);
    return ImageBasis{v.forward, scale(v.right, (width / height) * half), scale(v.up, half)};
}

Vec3d pixel_direction(const Vec3d& forward, double fov_deg, double width, double height, double px,
                      double py) {
    const ImageBasis b = image_basis(forward, fov_deg, width, height);
    const double sx = px / width * 2 - 1;
    const double sy = 1 - py / height * 2;
    const Vec3d d = add(b.forward, add(scale(b.right, sx), scale(b.up, sy)));
    return scale(d, 1 / length(d));
}

std::optional<ImagePoint> project_point(const Vec3d& eye, const Vec3d& forward, double fov_deg,
                                        double width, double height, const Vec3d& point) {
    const ViewBasis b = view_basis(forward);
    const Vec3d v = sub(point, eye);
    const double depth = dot(v, b.forward);
    if (!(depth > 1e-6)) {
        return std::nullopt;
    }
    const double half = std::tan(fov_deg * kDeg / 2);
    const double sx = dot(v, b.right) / depth / ((width / height) * half);
    const double sy = dot(v, b.up) / depth / half;
    return ImagePoint{(sx + 1) / 2 * width, (1 - sy) / 2 * height};
}

Int3 chunk_at(const Vec3d& position, Dims world, std::uint32_t chunk) {
    const std::uint32_t n[3] = {world.x, world.y, world.z};
    std::int64_t c[3];
    for (int a = 0; a < 3; ++a) {
        const double v = std::isfinite(position[a]) ? position[a] : 0.0;
        const double clamped = std::clamp(v, 0.0, static_cast<double>(n[a]) - 0.5);
        c[a] = static_cast<std::int64_t>(clamped) / chunk;
    }
    return Int3{c[0], c[1], c[2]};
}

Framing world_framing(Dims dims) {
    Framing f;
    f.centre = {dims.x / 2.0, dims.y / 2.0, dims.z / 2.0};
    f.half = f.centre;
    return f;
}

namespace {

// What a side shows: per pixel of the view along an axis, the first solid's material and depth
// (0 where the ray meets nothing); detail counts neighbouring pixels that differ.
struct SideView {
    std::uint32_t width = 0, height = 0;
    std::vector<std::uint8_t> material;
    std::vector<std::uint32_t> depth;
    SideView(std::uint32_t w, std::uint32_t h)
        : width(w), height(h), material(w * std::size_t{h}), depth(w * std::size_t{h}) {}
    void hit(std::uint32_t u, std::uint32_t v, std::uint8_t m, std::uint32_t d, bool nearest) {
        const std::size_t i = std::size_t{v} * width + u;
        if (material[i] == 0 || (nearest ? d < depth[i] : d > depth[i])) {
            material[i] = m;
            depth[i] = d;
        }
    }
    std::size_t detail() const {
        std::size_t n = 0;
        auto differ = [&](std::size_t a, std::size_t b) {
            return material[a] != material[b] || (material[a] != 0 && depth[a] != depth[b]);
        };
        for (std::uint32_t v = 0; v < height; ++v) {
            for (std::uint32_t u = 0; u < width; ++u) {
                const std::size_t i = std::size_t{v} * width + u;
                n += (u + 1 < width && differ(i, i + 1)) ? 1 : 0;
                n += (v + 1 < height && differ(i, i + width)) ? 1 : 0;
            }
        }
        return n;
    }
};

Vec3d most_detailed_side(const World& world) {
    const Dims d = world.dims();
    // Views along z (from -z and +z: pixels x, y) and along x (from -x and +x: pixels z, y).
    SideView minus_z(d.x, d.y), plus_z(d.x, d.y), minus_x(d.z, d.y), plus_x(d.z, d.y);
    const auto& v = world.voxels();
    std::size_t i = 0;
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x, ++i) {
                if (v[i] != 0) {
                    minus_z.hit(x, y, v[i], z, true);
                    plus_z.hit(x, y, v[i], z, false);
                    minus_x.hit(z, y, v[i], x, true);
                    plus_x.hit(z, y, v[i], x, false);
                }
            }
        }
    }
    const std::pair<Vec3d, std::size_t> sides[] = {{{0, 0, -1}, minus_z.detail()},
                                                   {{-1, 0, 0}, minus_x.detail()},
                                                   {{1, 0, 0}, plus_x.detail()},
                                                   {{0, 0, 1}, plus_z.detail()}};
    std::size_t best = 0;
    for (std::size_t k = 1; k < 4; ++k) {
        if (sides[k].second > sides[best].second) {
            best = k;
        }
    }
    // MagicaVoxel's front stays unless it is blank beside another side (scene_store8: its back
    // wall 1488, its shop front 4927): a character's patterned back (chr_army1: 115 against its
    // face's 111) or a car's long side (189 against 117) does not displace it.
    return sides[best].second >= 2 * sides[0].second ? sides[best].first : sides[0].first;
}

}  // namespace

Framing solid_framing(const World& world) {
    const Dims d = world.dims();
    std::uint32_t lo[3] = {d.x, d.y, d.z}, hi[3] = {0, 0, 0};
    const auto& v = world.voxels();
    std::size_t i = 0;
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x, ++i) {
                if (v[i] != 0) {
                    const std::uint32_t c[3] = {x, y, z};
                    for (int a = 0; a < 3; ++a) {
                        lo[a] = std::min(lo[a], c[a]);
                        hi[a] = std::max(hi[a], c[a] + 1);
                    }
                }
            }
        }
    }
    if (hi[0] == 0) {
        return world_framing(d);
    }
    Framing f;
    for (int a = 0; a < 3; ++a) {
        f.centre[a] = (lo[a] + hi[a]) / 2.0;
        f.half[a] = (hi[a] - lo[a]) / 2.0;
    }
    f.front = most_detailed_side(world);
    return f;
}

Vec3d framing_position(const Framing& f, double fov_deg, double aspect) {
    // Front-left and above: for the -z front (-0.6, 0.5, -0.75); left of a front n is
    // (n.z, 0, -n.x).
    const Vec3d n = scale(f.front, 1 / length(f.front));
    const Vec3d side = {0.75 * n[0] + 0.6 * n[2], 0.5, 0.75 * n[2] - 0.6 * n[0]};
    const Vec3d from = scale(side, 1 / length(side));
    const ViewBasis b = view_basis(scale(from, -1));
    const double tan_v = std::tan(0.5 * fov_deg * kDeg) / 1.05;
    const double tan_h = aspect * tan_v;
    // A corner at offset c from the centre lies at depth distance + dot(c, forward) and
    // appears at dot(c, right), dot(c, up): inside the image when both are within the depth
    // times the half-image tangents.
    double distance = 0;
    for (int k = 0; k < 8; ++k) {
        const Vec3d c = {k & 1 ? f.half[0] : -f.half[0], k & 2 ? f.half[1] : -f.half[1],
                         k & 4 ? f.half[2] : -f.half[2]};
        const double depth = dot(c, b.forward);
        distance = std::max({distance, std::abs(dot(c, b.right)) / tan_h - depth,
                             std::abs(dot(c, b.up)) / tan_v - depth});
    }
    // Never inside the box: at least its bounding sphere's radius away.
    distance = std::max(distance, length(f.half) + 1);
    return add(f.centre, scale(from, distance));
}

ViewCamera::ViewCamera(Dims world) : ViewCamera(world, world_framing(world), 4.0 / 3.0) {}

ViewCamera::ViewCamera(Dims world, const Framing& view, double aspect)
    : dims_(world), centre_(view.centre), framing_(view), aspect_(aspect) {
    reset();
}

void ViewCamera::reset() {
    mode_ = Mode::fly;
    look_at(framing_position(framing_, settings.fov_deg, aspect_), centre_);
}

void ViewCamera::dissertation_start() {
    mode_ = Mode::fly;
    position_ = {-double(dims_.x), dims_.y / 2.0, dims_.z / 2.0};
    set_angles(0, 0);
}

void ViewCamera::look_at(const Vec3d& position, const Vec3d& target) {
    const Vec3d d = sub(target, position);
    if (!finite(position) || !finite(target) || !(length(d) > 1e-9)) {
        throw InputError("camera position and target must be finite and distinct");
    }
    position_ = position;
    const double horizontal = std::hypot(d[0], d[2]);
    set_angles(std::atan2(d[2], d[0]) / kDeg, std::atan2(d[1], horizontal) / kDeg);
    if (mode_ == Mode::orbit) {
        distance_ = std::max(1.0, length(sub(centre_, position_)));
        set_mode(Mode::orbit);
    }
}

void ViewCamera::set_angles(double yaw, double pitch) {
    yaw_ = std::remainder(yaw, 360.0);
    const double limit = std::clamp(settings.max_pitch, 0.0, 89.999);
    pitch_ = std::clamp(pitch, -limit, limit);
}

void ViewCamera::place_on_orbit() {
    position_ = sub(centre_, scale(forward(), distance_));
}

void ViewCamera::set_mode(Mode mode) {
    mode_ = mode;
    if (mode == Mode::orbit) {
        const Vec3d to_centre = sub(centre_, position_);
        distance_ = std::max(1.0, length(to_centre));
        if (length(to_centre) > 1e-9) {
            const double horizontal = std::hypot(to_centre[0], to_centre[2]);
            set_angles(std::atan2(to_centre[2], to_centre[0]) / kDeg,
                       std::atan2(to_centre[1], horizontal) / kDeg);
        }
        place_on_orbit();
    }
}

Vec3d ViewCamera::target() const {
    return add(position_, forward());
}

void ViewCamera::update(const CameraInput& in, double dt) {
    if (!(dt > 0) || !std::isfinite(dt)) {
        dt = 0;
    }
    const double speed = settings.speed * (in.fast ? settings.fast_factor : 1.0);
    const double s = settings.sensitivity;
    if (mode_ == Mode::fly) {
        set_angles(yaw_ + in.look_dx * s, pitch_ - in.look_dy * s);
        const ViewBasis b = view_basis(forward());
        Vec3d move{0, 0, 0};
        auto axis = [&](bool plus, bool minus, const Vec3d& v) {
            if (plus != minus) {
                move = add(move, scale(v, plus ? 1.0 : -1.0));
            }
        };
        axis(in.forward, in.back, b.forward);
        axis(in.right, in.left, b.right);
        axis(in.up, in.down, Vec3d{0, 1, 0});
        const double len = length(move);
        if (len > 1e-12) {
            position_ = add(position_, scale(move, speed * dt / len));
        }
        return;
    }
    // Orbit: turn around the centre; forward/back zoom.
    const double turn = settings.orbit_turn_speed * dt * (in.fast ? settings.fast_factor : 1.0);
    double yaw = yaw_ + in.look_dx * s, pitch = pitch_ - in.look_dy * s;
    yaw += (in.left ? turn : 0) - (in.right ? turn : 0);
    pitch += (in.up ? turn : 0) - (in.down ? turn : 0);
    set_angles(yaw, pitch);
    if (in.forward != in.back) {
        distance_ = std::max(1.0, distance_ + (in.forward ? -speed * dt : speed * dt));
    }
    place_on_orbit();
}

}  // namespace voxfield
