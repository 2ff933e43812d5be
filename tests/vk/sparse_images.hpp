#pragma once
// Image checks of the sparse tracer's updates (sparse_update_test.cpp, and the shared trees of
// tests/pipeline/shared_trees_test.cpp): several views of a world, flat and lit, compared pixel
// for pixel with a tracer freshly uploaded from the host world.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "voxfield/core/palette.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/vk/sparse_tracer.hpp"

namespace voxfield::test {

// Views of the world: the default framing, one from above, one from a low corner inside.
inline std::vector<vk::RenderOptions> views(const SparseWorld& world) {
    const Dims d = world.dims();
    std::vector<vk::RenderOptions> out;
    for (int v = 0; v < 3; ++v) {
        for (const vk::Shading shading : {vk::Shading::flat, vk::Shading::lit}) {
            vk::RenderOptions r;
            r.width = 80;
            r.height = 60;
            r.shading = shading;
            r.sky = Rgba{1, 2, 3, 255};
            if (v == 0) {
                r.camera = vk::default_camera(d);
            } else if (v == 1) {
                r.camera.position = {d.x / 2.0 + 0.3, d.y * 2.5 + 40, d.z / 2.0 - 0.7};
                r.camera.target = {d.x / 2.0, 0, d.z / 2.0 + 1};
            } else {
                r.camera.position = {2.5, d.y * 0.6, 3.5};
                r.camera.target = {double(d.x), d.y * 0.2, double(d.z)};
            }
            out.push_back(r);
        }
    }
    return out;
}

// Every view of `updated` equals the same view of a tracer freshly uploaded from `world`.
inline void expect_as_fresh(vk::Context& ctx, vk::SparseTracer& updated, const SparseWorld& world,
                            const Palette& palette, const std::string& when,
                            std::uint64_t max_binding_bytes = 0) {
    vk::SparseTracer fresh(ctx, max_binding_bytes);
    fresh.upload(world, palette);
    for (const vk::RenderOptions& r : views(world)) {
        const vk::Image want = fresh.render(r);
        const vk::Image got = updated.render(r);
        ASSERT_EQ(got.rgba.size(), want.rgba.size());
        std::size_t differing = 0;
        for (std::size_t p = 0; p < got.rgba.size(); p += 4) {
            differing += !std::equal(got.rgba.begin() + static_cast<std::ptrdiff_t>(p),
                                     got.rgba.begin() + static_cast<std::ptrdiff_t>(p + 4),
                                     want.rgba.begin() + static_cast<std::ptrdiff_t>(p));
        }
        EXPECT_EQ(differing, 0u) << when << ", "
                                 << (r.shading == vk::Shading::lit ? "lit" : "flat");
    }
}

}  // namespace voxfield::test
