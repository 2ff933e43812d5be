// DESIGN §2 sharing path 2 on PoCL + lavapipe: one host allocation that OpenCL writes
// (CL_MEM_USE_HOST_PTR) and the ray marcher reads (VK_EXT_external_memory_host), with no
// copy in between; and the Vulkan half of path 1 (exporting an opaque fd) where it exists.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <memory>
#include <vector>

#include "voxfield/cl/exact.hpp"
#include "voxfield/cl/interop.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/vk/raymarcher.hpp"
#include "voxfield/vk/shared.hpp"

namespace voxfield::test {
namespace {

vk::Context& vulkan() {
    static std::unique_ptr<vk::Context> ctx = std::make_unique<vk::Context>();
    return *ctx;
}

ocl::Context& opencl() {
    static std::unique_ptr<ocl::Context> ctx =
        std::make_unique<ocl::Context>(ocl::select_device("cpu"));
    return *ctx;
}

std::vector<std::uint16_t> compact_field(const World& world) {
    const auto d = reference_manhattan(world);
    std::vector<std::uint16_t> out(world.size());
    for (std::size_t i = 0; i < out.size(); ++i) {
        out[i] = static_cast<std::uint16_t>((std::min<std::uint32_t>(d[i], 255) << 8) |
                                            world.voxels()[i]);
    }
    return out;
}

vk::RenderOptions view(Dims d) {
    vk::RenderOptions r;
    r.width = 48;
    r.height = 40;
    r.camera = vk::default_camera(d);
    r.sky = Rgba{0x33, 0x66, 0x99, 255};
    return r;
}

std::size_t count_colour(const vk::Image& img, Rgba c) {
    std::size_t n = 0;
    for (std::size_t i = 0; i < img.rgba.size(); i += 4) {
        n += img.rgba[i] == c.r && img.rgba[i + 1] == c.g && img.rgba[i + 2] == c.b;
    }
    return n;
}

// The field memory both APIs see, released in the right order (OpenCL's buffer first).
struct SharedField {
    vk::ExternalMemory memory;
    cl::Buffer buffer;
    ~SharedField() { buffer = cl::Buffer(); }
};

TEST(Share, PathTwoIsAvailableOnPoclAndLavapipe) {
    EXPECT_TRUE(vk::supports(vulkan(), vk::SharingPath::host_pointer)) << vulkan().info().name;
    EXPECT_TRUE(ocl::can_use_host_memory(opencl())) << opencl().info().name;
    EXPECT_TRUE(vk::supports(vulkan(), vk::SharingPath::copy));
}

TEST(Share, OpenClFillIsSeenByTheShaderWithNoCopy) {
    const Dims dims{16, 12, 20};
    vk::Raymarcher marcher(vulkan(), 16 * 12 * 2 * 6);  // 4 slabs inside one allocation
    const vk::FieldLayout layout = marcher.plan(dims, vk::FieldFormat::compact);
    ASSERT_EQ(layout.slabs, 4u);
    SharedField shared;
    shared.memory = vk::ExternalMemory::host_allocation(
        vulkan(), layout.total_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, "test field");
    shared.buffer = ocl::wrap_host_memory(opencl(), shared.memory.host_pointer(),
                                          static_cast<std::size_t>(shared.memory.size()));
    Palette palette;
    palette[7] = Rgba{1, 2, 3, 255};
    marcher.bind_shared(shared.memory, layout, palette);
    EXPECT_EQ(marcher.sharing(), vk::SharingPath::host_pointer);
    vk::RenderOptions r = view(dims);
    r.camera.fov_deg = 10;  // every ray enters the world

    // Marker: every voxel solid with material 7 (distance 0), written by OpenCL only.
    auto& q = opencl().queue();
    q.enqueueFillBuffer(shared.buffer, cl_ushort{7}, 0, layout.total_bytes);
    q.finish();
    std::uint16_t first = 0;
    std::memcpy(&first, shared.memory.host_pointer(), 2);
    EXPECT_EQ(first, 7u) << "PoCL did not write into the shared host allocation";
    vk::Image img = marcher.render(r);
    EXPECT_EQ(count_colour(img, palette[7]), std::size_t{r.width} * r.height);

    // Marker 2: all air at distance 1: every ray leaves the world.
    q.enqueueFillBuffer(shared.buffer, cl_ushort{1u << 8}, 0, layout.total_bytes);
    q.finish();
    img = marcher.render(r);
    EXPECT_EQ(count_colour(img, r.sky), std::size_t{r.width} * r.height);
    EXPECT_EQ(marcher.bytes_copied(), 0u);
}

TEST(Share, RegeneratedFieldShowsInTheNextRenderWithoutUpload) {
    const Dims dims{24, 20, 28};
    World world(dims);
    for (std::uint32_t x = 0; x < 24; ++x) {
        for (std::uint32_t z = 0; z < 28; ++z) {
            world.set(x, 0, z, 3);  // a floor
        }
    }
    world.set(5, 6, 7, 40);
    Palette palette;
    vk::Raymarcher marcher(vulkan(), 24 * 20 * 2 * 9 + 4);  // 4 slabs
    const vk::FieldLayout layout = marcher.plan(dims, vk::FieldFormat::compact);
    ASSERT_GE(layout.slabs, 2u);
    SharedField shared;
    shared.memory = vk::ExternalMemory::host_allocation(
        vulkan(), layout.total_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, "test field");
    shared.buffer = ocl::wrap_host_memory(opencl(), shared.memory.host_pointer(),
                                          static_cast<std::size_t>(shared.memory.size()));
    ocl::ExactManhattan exact(opencl(), world, palette, Format::u16);
    ocl::CompactWriter writer(opencl(), exact, dims, shared.buffer,
                              {layout.slab_depth, layout.slab_stride});
    exact.run();
    writer.run();
    marcher.bind_shared(shared.memory, layout, palette);
    const vk::RenderOptions r = view(dims);

    // The same world through the copy path, from the CPU reference field.
    vk::Raymarcher copy(vulkan());
    copy.upload_compact(dims, palette, compact_field(world));
    const vk::Image before = marcher.render(r);
    EXPECT_EQ(before.rgba, copy.render(r).rgba);
    EXPECT_GT(count_colour(before, palette[40]), 0u);

    // Edit the world on the OpenCL device, regenerate: the next render shows it.
    world.set(5, 6, 7, 0);
    for (std::uint32_t y = 1; y < 12; ++y) {
        world.set(18, y, 20, 77);
    }
    opencl().queue().enqueueWriteBuffer(exact.voxels_buffer(), CL_TRUE, 0, world.size(),
                                        world.voxels().data());
    exact.run();
    writer.run();
    const vk::Image after = marcher.render(r);
    copy.upload_compact(dims, palette, compact_field(world));
    EXPECT_EQ(after.rgba, copy.render(r).rgba);
    EXPECT_NE(after.rgba, before.rgba);
    EXPECT_EQ(count_colour(after, palette[40]), 0u);
    EXPECT_GT(count_colour(after, palette[77]), 0u);
    EXPECT_EQ(marcher.bytes_copied(), 0u) << "the shared field was copied";
}

TEST(Share, VulkanHalfOfPathOne) {
    // PoCL has no cl_khr_external_memory_opaque_fd, so render falls back to path 2 here.
    EXPECT_FALSE(ocl::can_import_opaque_fd(opencl()));
    if (!vk::supports(vulkan(), vk::SharingPath::opaque_fd)) {
        GTEST_SKIP() << vulkan().info().name << " lacks VK_KHR_external_memory_fd";
    }
    const vk::ExternalMemory m = vk::ExternalMemory::exportable(
        vulkan(), 1 << 16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, "test export");
    const int fd = m.export_fd();
    EXPECT_GE(fd, 0);
    close(fd);
}

}  // namespace
}  // namespace voxfield::test
