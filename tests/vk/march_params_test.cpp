// The camera the ray marcher hands its shader is core's camera model: the push constants that
// record() pushes (march_params.hpp push_constants, the only function that fills raymarch.comp's
// Params) carry core's image_basis (camera.hpp) for the options' camera and image size,
// rounded once to float, and the origin, image and field words of the options. The image
// comparisons of raymarch_test then test the shader's use of them against core's
// pixel_direction.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>

#include "march_params.hpp"
#include "voxfield/core/camera.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/layout.h"
#include "voxfield/vk/raymarcher.hpp"

namespace voxfield::test {
namespace {

void expect_floats(const float got[4], const Vec3d& want, const char* what) {
    for (int i = 0; i < 3; ++i) {
        EXPECT_EQ(got[i], static_cast<float>(want[static_cast<std::size_t>(i)]))
            << what << " component " << i;
    }
    EXPECT_EQ(got[3], 0.0f) << what;
}

vk::FieldLayout layout_of(Dims d, std::uint32_t slab_depth) {
    vk::FieldLayout l;
    l.dims = d;
    l.slab_depth = slab_depth;
    l.slabs = (d.z + slab_depth - 1) / slab_depth;
    return l;
}

TEST(MarchParams, PushConstantsCarryCoresImageBasis) {
    std::mt19937_64 rng(23);
    std::uniform_real_distribution<double> coord(-300, 300), fov(1, 179);
    std::uniform_int_distribution<std::uint32_t> size(1, 4000);
    for (int k = 0; k < 500; ++k) {
        vk::RenderOptions o;
        o.camera.position = {coord(rng), coord(rng), coord(rng)};
        o.camera.target = {coord(rng), coord(rng), coord(rng)};
        if (k % 50 == 0) {  // straight down and up, where right falls back to +x
            o.camera.target = {o.camera.position[0], o.camera.position[1] + (k % 100 ? 9 : -9),
                               o.camera.position[2]};
        }
        o.camera.fov_deg = fov(rng);
        o.width = size(rng);
        o.height = size(rng);
        const Vec3d view = {o.camera.target[0] - o.camera.position[0],
                            o.camera.target[1] - o.camera.position[1],
                            o.camera.target[2] - o.camera.position[2]};
        const ImageBasis want = image_basis(view, o.camera.fov_deg, o.width, o.height);
        const vk::PushConstants pc = vk::push_constants(o, layout_of(Dims{7, 5, 3}, 2), false);
        SCOPED_TRACE(k);
        expect_floats(pc.origin, o.camera.position, "origin");
        expect_floats(pc.forward, want.forward, "forward");
        expect_floats(pc.right, want.right, "right");
        expect_floats(pc.up, want.up, "up");
        // The renderer's public basis is the same one.
        const vk::CameraBasis b = vk::camera_basis(o.camera, o.width, o.height);
        EXPECT_EQ(b.forward, want.forward);
        EXPECT_EQ(b.right, want.right);
        EXPECT_EQ(b.up, want.up);
        // The shader's ray through a pixel centre (raymarch.comp: forward + sx right + sy up,
        // normalised) is core's pixel_direction, up to the float rounding of the vectors.
        const std::uint32_t i = o.width / 3, j = o.height - 1;
        const double sx = (i + 0.5) / o.width * 2 - 1, sy = 1 - (j + 0.5) / o.height * 2;
        Vec3d shader{};
        double norm = 0;
        for (std::size_t a = 0; a < 3; ++a) {
            shader[a] = double(pc.forward[a]) + sx * double(pc.right[a]) + sy * double(pc.up[a]);
            norm += shader[a] * shader[a];
        }
        const Vec3d core =
            pixel_direction(view, o.camera.fov_deg, o.width, o.height, i + 0.5, j + 0.5);
        // A float vector is within 2^-24 of its components; right and up are at most
        // aspect * tan(89.5 deg) ~ 460000 long here, so the sum is within ~0.06 absolute of
        // the double one before normalising (a length >= 1).
        const double scale =
            1 +
            std::abs(sx) * std::sqrt(want.right[0] * want.right[0] + want.right[1] * want.right[1] +
                                     want.right[2] * want.right[2]) +
            std::abs(sy) * std::sqrt(want.up[0] * want.up[0] + want.up[1] * want.up[1] +
                                     want.up[2] * want.up[2]);
        for (std::size_t a = 0; a < 3; ++a) {
            EXPECT_NEAR(shader[a] / std::sqrt(norm), core[a], 4e-7 * scale) << "axis " << a;
        }
    }
}

TEST(MarchParams, PushConstantsCarryTheImageAndTheField) {
    vk::RenderOptions o;
    o.width = 640;
    o.height = 360;
    o.camera.position = {-10, 20, -30};
    o.camera.target = {16, 8, 16};
    o.sky = Rgba{1, 2, 3, 4};
    o.bgra = true;
    const vk::FieldLayout l = layout_of(Dims{33, 17, 65}, 20);
    vk::PushConstants pc = vk::push_constants(o, l, true);
    EXPECT_EQ(pc.dims[0], 33u);
    EXPECT_EQ(pc.dims[1], 17u);
    EXPECT_EQ(pc.dims[2], 65u);
    EXPECT_EQ(pc.dims[3], 20u);
    EXPECT_EQ(pc.image[0], 640u);
    EXPECT_EQ(pc.image[1], 360u);
    EXPECT_EQ(pc.image[2], std::uint32_t{VF_RAYMARCH_FLAG_BLOCK_MIN | VF_RAYMARCH_FLAG_BGRA});
    EXPECT_EQ(pc.image[3], 0x04030201u);
    // The sky gradient is lit shading's only.
    o.bgra = false;
    o.sky_gradient = true;
    pc = vk::push_constants(o, l, false);
    EXPECT_EQ(pc.image[2], 0u);
    o.shading = vk::Shading::lit;
    pc = vk::push_constants(o, l, false);
    EXPECT_EQ(pc.image[2], std::uint32_t{VF_RAYMARCH_FLAG_LIT | VF_RAYMARCH_FLAG_SKY_GRADIENT});
    // An implicit surface's tile grid rides along; zeros without one.
    EXPECT_EQ(pc.implicit[0] | pc.implicit[1] | pc.implicit[2] | pc.implicit[3], 0u);
    pc = vk::push_constants(o, l, false, {3, 2, 5, 1});
    EXPECT_EQ(pc.implicit[0], 3u);
    EXPECT_EQ(pc.implicit[1], 2u);
    EXPECT_EQ(pc.implicit[2], 5u);
    EXPECT_EQ(pc.implicit[3], 1u);
    // Bad options are bad input, as for a render.
    o.camera.target = o.camera.position;
    EXPECT_THROW(vk::push_constants(o, l, false), InputError);
    o.camera.target = {0, 0, 0};
    o.width = 0;
    EXPECT_THROW(vk::push_constants(o, l, false), InputError);
}

}  // namespace
}  // namespace voxfield::test
