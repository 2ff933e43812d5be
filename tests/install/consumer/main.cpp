// Uses the installed voxfield package: computes the exact Manhattan field of a tiny world on
// PoCL through the public API and compares every voxel with core's CPU reference; exits 0 only
// if all are equal.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <string>
#include <vector>

#include "voxfield/cl/generator.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/vk/context.hpp"

namespace {

// PoCL, chosen by its platform name as the kernel tests choose it.
voxfield::ocl::DeviceInfo pocl() {
    for (const auto& d : voxfield::ocl::list_devices()) {
        if (d.platform.find("Portable Computing Language") != std::string::npos) {
            return d;
        }
    }
    throw std::runtime_error("PoCL (pocl-opencl-icd) is not installed: no device to run on");
}

}  // namespace

int main() {
    try {
        // voxfield::vk links (with Vulkan) and answers without a device.
        if (std::strcmp(voxfield::vk::result_name(VK_SUCCESS), "VK_SUCCESS") != 0) {
            std::fprintf(stderr, "vk::result_name(VK_SUCCESS) is %s\n",
                         voxfield::vk::result_name(VK_SUCCESS));
            return 1;
        }

        voxfield::World world(voxfield::Dims{5, 4, 3});
        world.set(0, 0, 0, 1);
        world.set(4, 3, 2, 7);
        world.set(2, 1, 1, 3);

        voxfield::ocl::Context ctx(pocl());
        voxfield::ocl::GeneratorOptions options;  // exact, global semantics
        options.format = voxfield::Format::u32;
        const voxfield::ocl::FieldResult field = voxfield::ocl::generate(
            ctx, world, voxfield::Palette(), voxfield::ocl::resolve_options(options, world.dims()));
        const std::vector<std::uint32_t> want = voxfield::reference_manhattan(world);

        if (field.bytes.size() != want.size() * voxfield::element_size(options.format)) {
            std::fprintf(stderr, "field has %zu bytes for %zu voxels\n", field.bytes.size(),
                         want.size());
            return 1;
        }
        for (std::size_t i = 0; i < want.size(); ++i) {
            const std::uint32_t got = voxfield::decode_distance(field.bytes, options.format, i);
            if (got != want[i]) {
                std::fprintf(stderr, "voxel %zu: got %u, want %u\n", i, got, want[i]);
                return 1;
            }
        }
        std::printf("%zu voxels on %s equal the reference\n", want.size(), ctx.info().name.c_str());
        return 0;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "voxfield consumer: %s\n", e.what());
        return 1;
    }
}
