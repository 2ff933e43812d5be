// DESIGN §2 sharing path 2 on PoCL + lavapipe: one host allocation that OpenCL writes
// (CL_MEM_USE_HOST_PTR) and the ray marcher reads (VK_EXT_external_memory_host), with no
// copy in between; and the Vulkan half of path 1 (exporting an opaque fd) where it exists.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cerrno>

#include <cstring>
#include <memory>
#include <optional>
#include <vector>

#include "voxfield/cl/exact.hpp"
#include "voxfield/cl/interop.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/vk/raymarcher.hpp"
#include "voxfield/vk/shared.hpp"
#include "vulkan_env.hpp"

namespace voxfield::test {
namespace {

vk::Context& vulkan() {
    return validated_vulkan();
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

// The writer on its own (OpenCL only): every source format, the whole field and regions.
TEST(Share, CompactWriterConvertsEveryFormatWholeAndByRegion) {
    const Dims dims{21, 18, 27};
    const World world = make_scene("random", dims, 99);
    const Palette palette;
    const std::vector<std::uint32_t> distances = reference_manhattan(world);
    const std::uint32_t depth = 5;
    const std::size_t plane = std::size_t{dims.x} * dims.y;
    const std::size_t stride = plane * depth + 6;  // elements between slab starts
    const std::size_t slabs = (dims.z + depth - 1) / depth;
    auto& q = opencl().queue();
    for (const Format format : {Format::u8, Format::u16, Format::u32, Format::packed32}) {
        SCOPED_TRACE(to_string(format));
        const std::vector<std::uint8_t> field = encode_field(distances, world, palette, format);
        cl::Buffer src(opencl().context(), CL_MEM_READ_WRITE, field.size());
        cl::Buffer vox(opencl().context(), CL_MEM_READ_WRITE, world.size());
        cl::Buffer dst(opencl().context(), CL_MEM_READ_WRITE, 2 * stride * slabs);
        q.enqueueWriteBuffer(src, CL_TRUE, 0, field.size(), field.data());
        q.enqueueWriteBuffer(vox, CL_TRUE, 0, world.size(), world.voxels().data());
        q.enqueueFillBuffer(dst, cl_ushort{0xABCD}, 0, 2 * stride * slabs);
        ocl::CompactWriter writer(opencl(), src, format, vox, dims, dst,
                                  {depth, static_cast<std::uint64_t>(2 * stride), std::nullopt});
        const auto expected = [&](std::size_t i) {
            const std::uint32_t d = std::min(decode_distance(field, format, i), 255u);
            return static_cast<std::uint16_t>((d << 8) | world.voxels()[i]);
        };
        const auto read_dst = [&] {
            std::vector<std::uint16_t> out(stride * slabs);
            q.enqueueReadBuffer(dst, CL_TRUE, 0, 2 * out.size(), out.data());
            return out;
        };
        const auto at = [&](const std::vector<std::uint16_t>& out, std::size_t x, std::size_t y,
                            std::size_t z) {
            return out[z / depth * stride + ((z % depth) * dims.y + y) * dims.x + x];
        };

        // Regions first: exactly their voxels are written.
        const std::vector<Box> regions{{{2, 3, 4}, {9, 11, 13}}, {{15, -4, 20}, {40, 5, 40}}};
        writer.run(regions);
        std::vector<std::uint16_t> out = read_dst();
        std::size_t written = 0;
        for (std::size_t z = 0; z < dims.z; ++z) {
            for (std::size_t y = 0; y < dims.y; ++y) {
                for (std::size_t x = 0; x < dims.x; ++x) {
                    const Int3 p{static_cast<std::int64_t>(x), static_cast<std::int64_t>(y),
                                 static_cast<std::int64_t>(z)};
                    bool inside = false;
                    for (const Box& b : regions) {
                        inside = inside || (p.x >= b.min.x && p.x < b.max.x && p.y >= b.min.y &&
                                            p.y < b.max.y && p.z >= b.min.z && p.z < b.max.z);
                    }
                    const std::size_t i = (z * dims.y + y) * dims.x + x;
                    if (inside) {
                        ++written;
                        ASSERT_EQ(at(out, x, y, z), expected(i)) << x << "," << y << "," << z;
                    } else {
                        ASSERT_EQ(at(out, x, y, z), 0xABCD) << x << "," << y << "," << z;
                    }
                }
            }
        }
        EXPECT_EQ(written, 7u * 8 * 9 + 6u * 5 * 7);

        // The whole field, and the block minima of every block.
        writer.run();
        out = read_dst();
        for (std::size_t z = 0; z < dims.z; ++z) {
            for (std::size_t y = 0; y < dims.y; ++y) {
                for (std::size_t x = 0; x < dims.x; ++x) {
                    ASSERT_EQ(at(out, x, y, z), expected((z * dims.y + y) * dims.x + x));
                }
            }
        }
        const std::vector<std::uint32_t> minima = writer.block_min();
        const std::size_t bx = 3, by = 3, bz = 4;  // ceil(dims / 8)
        ASSERT_EQ(minima.size(), bx * by * bz);
        for (std::size_t b = 0; b < minima.size(); ++b) {
            const std::size_t x0 = b % bx * 8, y0 = b / bx % by * 8, z0 = b / bx / by * 8;
            std::uint32_t m = 0xFFFFFFFFu;
            for (std::size_t z = z0; z < std::min<std::size_t>(z0 + 8, dims.z); ++z) {
                for (std::size_t y = y0; y < std::min<std::size_t>(y0 + 8, dims.y); ++y) {
                    for (std::size_t x = x0; x < std::min<std::size_t>(x0 + 8, dims.x); ++x) {
                        m = std::min(m,
                                     decode_distance(field, format, (z * dims.y + y) * dims.x + x));
                    }
                }
            }
            ASSERT_EQ(minima[b], m) << "block " << b;
        }
    }
}

// Paths 1/2 keep the block minima in the destination, after the slabs: a run over regions
// recomputes the blocks covering them there (changed_blocks()) and leaves every other word as
// it was; block_min(blocks) reads back just those blocks.
TEST(Share, CompactWriterRewritesOnlyTheChangedBlocksInPlace) {
    const Dims dims{21, 18, 27};  // 3 x 3 x 4 blocks
    const Dims grid{3, 3, 4};
    const World world = make_scene("random", dims, 5);
    const std::vector<std::uint8_t> field =
        encode_field(reference_manhattan(world), world, Palette(), Format::u16);
    const std::uint64_t slabs_bytes = 5 * 4096;  // one slab, rounded up like the ray marcher's
    const std::size_t table = grid.count();
    auto& q = opencl().queue();
    cl::Buffer src(opencl().context(), CL_MEM_READ_WRITE, field.size());
    cl::Buffer vox(opencl().context(), CL_MEM_READ_WRITE, world.size());
    cl::Buffer dst(opencl().context(), CL_MEM_READ_WRITE, slabs_bytes + 4 * table);
    q.enqueueWriteBuffer(src, CL_TRUE, 0, field.size(), field.data());
    q.enqueueWriteBuffer(vox, CL_TRUE, 0, world.size(), world.voxels().data());
    ASSERT_GE(slabs_bytes, 2 * dims.count());
    ocl::CompactWriter writer(opencl(), src, Format::u16, vox, dims, dst,
                              {dims.z, slabs_bytes, slabs_bytes});
    writer.run();
    const std::vector<std::uint32_t> whole = writer.block_min();
    ASSERT_EQ(whole.size(), table);
    EXPECT_EQ(writer.changed_blocks(), (std::vector<Box>{Box{{0, 0, 0}, {3, 3, 4}}}));
    const auto read_table = [&] {
        std::vector<std::uint32_t> out(table);
        q.enqueueReadBuffer(dst, CL_TRUE, slabs_bytes, 4 * table, out.data());
        return out;
    };
    EXPECT_EQ(read_table(), whole) << "the table is not in place";

    const cl_uint stale = 0xDEADBEEFu;
    q.enqueueFillBuffer(dst, stale, slabs_bytes, 4 * table);
    q.finish();
    // Voxels x 9..12, y 0..3, z 17..20 (blocks x 1, y 0, z 2) and x 15..21, y 16..18,
    // z 0..2 (blocks x 1..2, y 2, z 0; clipped to the world).
    const std::vector<Box> regions{{{9, 0, 17}, {13, 4, 21}}, {{15, 16, -3}, {30, 19, 3}}};
    writer.run(regions);
    const std::vector<Box> blocks{{{1, 0, 2}, {2, 1, 3}}, {{1, 2, 0}, {3, 3, 1}}};
    EXPECT_EQ(writer.changed_blocks(), blocks);
    const std::vector<std::uint32_t> after = read_table();
    std::size_t rewritten = 0;
    for (std::uint32_t z = 0; z < grid.z; ++z) {
        for (std::uint32_t y = 0; y < grid.y; ++y) {
            for (std::uint32_t x = 0; x < grid.x; ++x) {
                const bool changed = (x == 1 && y == 0 && z == 2) || (x >= 1 && y == 2 && z == 0);
                const std::size_t i = grid.index(x, y, z);
                rewritten += changed;
                EXPECT_EQ(after[i], changed ? whole[i] : stale) << x << "," << y << "," << z;
            }
        }
    }
    EXPECT_EQ(rewritten, 3u);
    const std::size_t first = grid.index(1, 0, 2), second = grid.index(1, 2, 0);
    EXPECT_EQ(writer.block_min(blocks),
              (std::vector<std::uint32_t>{whole[first], whole[second], whole[second + 1]}));
    EXPECT_THROW(writer.block_min({Box{{2, 0, 0}, {4, 1, 1}}}), std::invalid_argument);
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
    ocl::CompactWriter writer(
        opencl(), exact.field_buffer(), Format::u16, exact.voxels_buffer(), dims, shared.buffer,
        {layout.slab_depth, layout.slab_stride, std::nullopt}, ocl::DstMemory::host);
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

cl_uint map_count(const cl::Buffer& b) {
    return b.getInfo<CL_MEM_MAP_COUNT>();
}

// Path 2 by OpenCL's rules: the host (here Vulkan's import of the same pages) may read a
// CL_MEM_USE_HOST_PTR buffer only while it is mapped, and the kernels may write it only while it
// is not. The writer keeps it mapped between runs, at the host pointer itself, and unmaps it
// when it goes.
TEST(Share, PathTwoReadsTheHostPointerOnlyWhileMapped) {
    const Dims dims{12, 10, 14};
    const World world = make_scene("random", dims, 5);
    const Palette palette;
    vk::Raymarcher marcher(vulkan());
    const vk::FieldLayout layout = marcher.plan(dims, vk::FieldFormat::compact);
    SharedField shared;
    shared.memory = vk::ExternalMemory::host_allocation(
        vulkan(), layout.total_bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, "test field");
    shared.buffer = ocl::wrap_host_memory(opencl(), shared.memory.host_pointer(),
                                          static_cast<std::size_t>(shared.memory.size()));
    ocl::ExactManhattan exact(opencl(), world, palette, Format::u16);
    exact.run();
    {
        ocl::CompactWriter writer(
            opencl(), exact.field_buffer(), Format::u16, exact.voxels_buffer(), dims, shared.buffer,
            {layout.slab_depth, layout.slab_stride, std::nullopt}, ocl::DstMemory::host);
        EXPECT_EQ(map_count(shared.buffer), 0u);
        writer.run();
        EXPECT_EQ(map_count(shared.buffer), 1u) << "Vulkan would read an unmapped buffer";
        marcher.bind_shared(shared.memory, layout, palette);
        vk::Raymarcher copy(vulkan());
        copy.upload_compact(dims, palette, compact_field(world));
        EXPECT_EQ(marcher.render(view(dims)).rgba, copy.render(view(dims)).rgba);
        writer.run({Box{{1, 2, 3}, {5, 6, 7}}});
        EXPECT_EQ(map_count(shared.buffer), 1u) << "mapped again, once";
        EXPECT_EQ(marcher.render(view(dims)).rgba, copy.render(view(dims)).rgba);
    }
    EXPECT_EQ(map_count(shared.buffer), 0u) << "the writer left the buffer mapped";
    // Without the host protocol (path 3's own memory) nothing is mapped.
    ocl::CompactWriter plain(opencl(), exact.field_buffer(), Format::u16, exact.voxels_buffer(),
                             dims, shared.buffer,
                             {layout.slab_depth, layout.slab_stride, std::nullopt});
    plain.run();
    EXPECT_EQ(map_count(shared.buffer), 0u);
}

// cl_khr_external_memory: a successful import owns the fd, so the caller never closes it; a
// failed one (PoCL has no opaque-fd import) closes it, so that no way out leaks or double-closes.
TEST(Share, OpaqueFdImportTakesTheFdOnEveryWayOut) {
    int fds[2] = {-1, -1};
    ASSERT_EQ(pipe(fds), 0);
    close(fds[1]);
    ASSERT_FALSE(ocl::can_import_opaque_fd(opencl()));
    EXPECT_THROW(ocl::import_opaque_fd(opencl(), fds[0], 4096), ocl::ClError);
    errno = 0;
    EXPECT_EQ(fcntl(fds[0], F_GETFD), -1) << "the failed import left the fd open";
    EXPECT_EQ(errno, EBADF);
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
