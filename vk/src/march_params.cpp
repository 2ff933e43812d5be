// The camera of a ray march and the push constants that carry it to raymarch.comp
// (raymarcher.hpp camera_basis / default_camera / validate, march_params.hpp).
#include "march_params.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "voxfield/core/camera.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/layout.h"

namespace voxfield::vk {
namespace {

Vec3 sub(const Vec3& a, const Vec3& b) {
    return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}
double length(const Vec3& a) {
    return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
}
bool finite(const Vec3& a) {
    return std::isfinite(a[0]) && std::isfinite(a[1]) && std::isfinite(a[2]);
}

void to4(float out[4], const Vec3& v) {
    for (int i = 0; i < 3; ++i) {
        out[i] = static_cast<float>(v[static_cast<std::size_t>(i)]);
    }
    out[3] = 0;
}

Camera framed(const Framing& f, double fov_deg, double aspect) {
    Camera c;
    c.position = framing_position(f, fov_deg, aspect);
    c.target = f.centre;
    c.fov_deg = fov_deg;
    return c;
}

}  // namespace

CameraBasis camera_basis(const Camera& camera, std::uint32_t width, std::uint32_t height) {
    if (!finite(camera.position) || !finite(camera.target)) {
        throw InputError("camera position and target must be finite numbers");
    }
    if (!(camera.fov_deg > 0 && camera.fov_deg < 180)) {
        throw InputError("field of view " + std::to_string(camera.fov_deg) +
                         " is outside (0, 180) degrees");
    }
    const Vec3 view = sub(camera.target, camera.position);
    if (!(length(view) > 1e-9)) {
        throw InputError("camera target equals the camera position: no view direction");
    }
    // The one camera model (core/camera.hpp image_basis, DESIGN §4).
    const ImageBasis b =
        image_basis(view, camera.fov_deg, static_cast<double>(width), static_cast<double>(height));
    return CameraBasis{b.forward, b.right, b.up};
}

Camera default_camera(Dims dims) {
    return framed(world_framing(dims), 60, 4.0 / 3.0);
}

Camera default_camera(const World& world, std::uint32_t width, std::uint32_t height,
                      double fov_deg) {
    return framed(solid_framing(world), fov_deg, double(width) / double(std::max(height, 1u)));
}

void validate(const RenderOptions& o) {
    for (const auto& [name, v] : {std::pair{"width", o.width}, std::pair{"height", o.height}}) {
        if (v < 1 || v > kMaxImageSize) {
            throw InputError(std::string("image ") + name + " " + std::to_string(v) +
                             " is outside 1.." + std::to_string(kMaxImageSize));
        }
    }
    camera_basis(o.camera, o.width, o.height);
}

std::uint32_t pack_rgba(Rgba c) {
    return std::uint32_t{c.r} | (std::uint32_t{c.g} << 8) | (std::uint32_t{c.b} << 16) |
           (std::uint32_t{c.a} << 24);
}

PushConstants push_constants(const RenderOptions& o, const FieldLayout& layout, bool block_min,
                             const std::array<std::uint32_t, 4>& implicit) {
    validate(o);
    const CameraBasis basis = camera_basis(o.camera, o.width, o.height);
    PushConstants pc{};
    to4(pc.origin, o.camera.position);
    to4(pc.forward, basis.forward);
    to4(pc.right, basis.right);
    to4(pc.up, basis.up);
    pc.dims[0] = layout.dims.x;
    pc.dims[1] = layout.dims.y;
    pc.dims[2] = layout.dims.z;
    pc.dims[3] = layout.slab_depth;
    pc.image[0] = o.width;
    pc.image[1] = o.height;
    pc.image[2] =
        (o.shading == Shading::lit ? VF_RAYMARCH_FLAG_LIT : 0u) |
        (o.shading == Shading::lit && o.sky_gradient ? VF_RAYMARCH_FLAG_SKY_GRADIENT : 0u) |
        (block_min ? VF_RAYMARCH_FLAG_BLOCK_MIN : 0u) | (o.bgra ? VF_RAYMARCH_FLAG_BGRA : 0u);
    pc.image[3] = pack_rgba(o.sky);
    for (std::size_t i = 0; i < 4; ++i) {
        pc.implicit[i] = implicit[i];
    }
    return pc;
}

}  // namespace voxfield::vk
