// The compact render field shared between OpenCL and Vulkan (see render_field.hpp).
#include "voxfield/pipeline/render_field.hpp"

#include "voxfield/layout.h"

#include <algorithm>
#include <cstddef>
#include <cstdlib>
#include <exception>

#include "field_semaphores.hpp"

namespace voxfield::pipeline {

namespace {

// The elements of `boxes` (inside `dims`) of a dense buffer (x fastest) of T, box after box and
// x fastest in each: one rectangle read per box, one wait for them all.
template <class T>
std::vector<T> read_dense_boxes(ocl::Context& cl, const cl::Buffer& buffer, Dims dims,
                                const std::vector<Box>& boxes, const char* what) {
    std::size_t voxels = 0;
    for (const Box& b : boxes) {
        voxels += static_cast<std::size_t>(b.volume());
    }
    std::vector<T> out(voxels);
    ocl::cl_call(what, [&] {
        std::size_t next = 0;
        const std::size_t e = sizeof(T), row = e * dims.x, slice = row * dims.y;
        for (const Box& b : boxes) {
            const auto w = static_cast<std::size_t>(b.max.x - b.min.x);
            const auto h = static_cast<std::size_t>(b.max.y - b.min.y);
            const auto d = static_cast<std::size_t>(b.max.z - b.min.z);
            const cl::array<cl::size_type, 3> origin{e * static_cast<std::size_t>(b.min.x),
                                                     static_cast<std::size_t>(b.min.y),
                                                     static_cast<std::size_t>(b.min.z)};
            const cl::array<cl::size_type, 3> host{0, 0, 0};
            const cl::array<cl::size_type, 3> region{e * w, h, d};
            cl.queue().enqueueReadBufferRect(buffer, CL_FALSE, origin, host, region, row, slice,
                                             e * w, e * w * h, out.data() + next);
            next += w * h * d;
        }
        cl.queue().finish();
    });
    return out;
}

// `regions` clipped to the world of `dims`, the empty ones dropped.
std::vector<Box> clipped(const std::vector<Box>& regions, Dims dims) {
    const Box world{{0, 0, 0}, {dims.x, dims.y, dims.z}};
    std::vector<Box> boxes;
    for (const Box& r : regions) {
        if (const Box b = intersect(r, world); !b.empty()) {
            boxes.push_back(b);
        }
    }
    return boxes;
}

}  // namespace

vk::SharingPath choose_sharing_path(const ocl::Context& cl_ctx, const vk::Context& vk_ctx,
                                    std::string& why_not, vk::SharingPath fastest) {
    why_not.clear();
    if (fastest != vk::SharingPath::opaque_fd) {
        why_not += "path 1: not tried (a slower path was asked for); ";
    } else if (!vk::supports(vk_ctx, vk::SharingPath::opaque_fd)) {
        why_not += "path 1: Vulkan device lacks VK_KHR_external_memory_fd; ";
    } else if (!ocl::can_import_opaque_fd(cl_ctx)) {
        why_not += "path 1: OpenCL device lacks cl_khr_external_memory_opaque_fd (OpenCL 3.0); ";
    } else if (const auto uuid = ocl::device_uuid(cl_ctx); !uuid || *uuid != vk_ctx.info().uuid) {
        why_not += uuid ? "path 1: the OpenCL and Vulkan devices differ (UUID); "
                        : "path 1: OpenCL device lacks cl_khr_device_uuid; ";
    } else {
        return vk::SharingPath::opaque_fd;
    }
    if (fastest == vk::SharingPath::copy) {
        why_not += "path 2: not tried (path 3 was asked for); ";
    } else if (!vk::supports(vk_ctx, vk::SharingPath::host_pointer)) {
        why_not += "path 2: Vulkan device lacks VK_EXT_external_memory_host; ";
    } else if (!ocl::can_use_host_memory(cl_ctx)) {
        why_not += "path 2: the OpenCL device is not a CPU; ";
    } else {
        return vk::SharingPath::host_pointer;
    }
    return vk::SharingPath::copy;
}

std::string to_string(FieldSync sync) {
    switch (sync) {
        case FieldSync::semaphore:
            return "semaphore";
        case FieldSync::fence:
            return "fence";
        case FieldSync::queue:
            break;
    }
    return "queue";
}

FieldSync choose_field_sync(const ocl::Context& cl_ctx, const vk::Context& vk_ctx,
                            vk::SharingPath path, std::string& why_not) {
    why_not.clear();
    if (path == vk::SharingPath::copy) {
        why_not = "path 3 copies in the Vulkan queue's order";
        return FieldSync::queue;
    }
    const char* off = std::getenv("VOXFIELD_NO_CL_SEMAPHORE");
    if (path != vk::SharingPath::opaque_fd) {
        why_not = "semaphores order path 1 only";
    } else if (off != nullptr && *off != '\0' && std::string(off) != "0") {
        why_not = "$VOXFIELD_NO_CL_SEMAPHORE is set";
    } else if (!vk::can_export_semaphore_fd(vk_ctx)) {
        why_not = "the Vulkan device cannot export semaphores (VK_KHR_external_semaphore_fd)";
    } else if (!ocl::can_import_semaphore_fd(cl_ctx)) {
        why_not = "the OpenCL device lacks cl_khr_external_semaphore_opaque_fd";
    } else {
        return FieldSync::semaphore;
    }
    return FieldSync::fence;
}

RenderField::RenderField(ocl::Context& cl_ctx, vk::Context& vk_ctx, const vk::Raymarcher& marcher,
                         Dims dims, vk::SharingPath fastest)
    : cl_(cl_ctx), dims_(dims), layout_(marcher.plan(dims, vk::FieldFormat::compact)) {
    path_ = choose_sharing_path(cl_ctx, vk_ctx, why_not_, fastest);
    const VkBufferUsageFlags usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
    // Paths 1/2: the slabs, then the block-minimum table (at a multiple of VF_FIELD_SLAB_ALIGN).
    const std::uint32_t b = VF_RAYMARCH_BLOCK;
    const std::uint64_t shared_bytes =
        layout_.total_bytes +
        std::uint64_t{4} * ((dims.x + b - 1) / b) * ((dims.y + b - 1) / b) * ((dims.z + b - 1) / b);
    if (path_ == vk::SharingPath::opaque_fd) {
        try {
            shared_ = vk::ExternalMemory::exportable(vk_ctx, shared_bytes, usage, "shared field");
            // The import takes the fd (OpenCL owns it after a successful import, and closes it
            // after a failed one): never closed here.
            cl_field_ = ocl::import_opaque_fd(cl_ctx, shared_.export_fd(),
                                              static_cast<std::size_t>(shared_bytes));
        } catch (const std::exception& e) {
            why_not_ += std::string("path 1 failed: ") + e.what() + "; ";
            cl_field_ = cl::Buffer();
            shared_ = vk::ExternalMemory();
            path_ = vk::supports(vk_ctx, vk::SharingPath::host_pointer) &&
                            ocl::can_use_host_memory(cl_ctx)
                        ? vk::SharingPath::host_pointer
                        : vk::SharingPath::copy;
        }
    }
    if (path_ == vk::SharingPath::host_pointer) {
        shared_ = vk::ExternalMemory::host_allocation(vk_ctx, shared_bytes, usage, "shared field");
        cl_field_ = ocl::wrap_host_memory(cl_ctx, shared_.host_pointer(),
                                          static_cast<std::size_t>(shared_.size()));
    } else if (path_ == vk::SharingPath::copy) {
        // Dense (one slab, x fastest): boxes of it are read back with one rectangle read each.
        cl_field_ = ocl::cl_call("the compact field buffer", [&] {
            return cl::Buffer(cl_ctx.context(), CL_MEM_READ_WRITE, 2 * dims.count());
        });
    }
    if (why_not_.size() >= 2) {
        why_not_.resize(why_not_.size() - 2);
    }
    sync_ = choose_field_sync(cl_ctx, vk_ctx, path_, sync_why_not_);
    if (sync_ == FieldSync::semaphore) {
        try {
            semaphores_ = std::make_unique<FieldSemaphores>(cl_ctx, vk_ctx);
        } catch (const std::exception& e) {
            sync_ = FieldSync::fence;
            sync_why_not_ = std::string("the semaphores failed: ") + e.what();
        }
    }
}

RenderField::~RenderField() {
    semaphores_.reset();
    writer_.reset();
    cl_field_ = cl::Buffer();
}

double RenderField::attach(vk::Raymarcher& marcher, const cl::Buffer& field, Format format,
                           Metric metric, const cl::Buffer& voxels, const Palette& palette,
                           double step) {
    wait_for_readers(marcher);
    writer_.reset();
    const bool copy = path_ == vk::SharingPath::copy;
    writer_.emplace(cl_, field, format, voxels, dims_, cl_field_,
                    copy ? ocl::SlabLayout{dims_.z, 2 * dims_.count(), std::nullopt}
                         : ocl::SlabLayout{layout_.slab_depth, layout_.slab_stride,
                                           std::optional{layout_.total_bytes}},
                    path_ == vk::SharingPath::opaque_fd      ? ocl::DstMemory::external
                    : path_ == vk::SharingPath::host_pointer ? ocl::DstMemory::host
                                                             : ocl::DstMemory::device,
                    step);
    const double ms = writer_->run();
    if (copy) {
        const Box whole{{0, 0, 0}, {dims_.x, dims_.y, dims_.z}};
        marcher.upload_compact(dims_, palette, read_boxes({whole}));
        marcher.set_block_min(writer_->block_min());
    } else {
        marcher.bind_shared(shared_, layout_, palette);
        marcher.bind_shared_block_min(shared_, layout_.total_bytes);
    }
    marcher.set_metric(metric);  // after the field (a new one resets it)
    return ms;
}

double RenderField::update(vk::Raymarcher& marcher, const std::vector<Box>& regions) {
    if (semaphores_ && !semaphores_->broken()) {
        try {
            return semaphores_->update(*writer_, regions);
        } catch (const std::exception& e) {
            if (!semaphores_->broken()) {
                throw;  // nothing was enqueued: a Vulkan submission failed
            }
            // A driver refused part way (OpenCL finished what it had enqueued): this update and
            // every later one take the fence path below, and sync() says so.
            sync_ = FieldSync::fence;
            sync_why_not_ = std::string("the semaphores failed: ") + e.what();
        }
    }
    if (path_ != vk::SharingPath::copy) {
        // OpenCL overwrites memory the frames in flight read: no Vulkan-side copy can order
        // that without semaphores (PoCL has none), so the CPU waits for the fence of the
        // latest frame that reads the field, not for the device to idle.
        marcher.wait_for_readers();
    }
    const double ms = writer_->run(regions);
    if (path_ == vk::SharingPath::copy) {
        // Only the changed voxels and blocks move, copied in place behind the frames in flight.
        const std::vector<Box> boxes = clipped(regions, dims_);
        marcher.update_compact(boxes, read_boxes(boxes));
        marcher.update_block_min(writer_->changed_blocks(),
                                 writer_->block_min(writer_->changed_blocks()));
    }
    return ms;
}

void RenderField::wait_for_readers(vk::Raymarcher& marcher) {
    if (path_ != vk::SharingPath::copy) {
        marcher.wait_for_readers();
    }
}

std::vector<std::uint16_t> RenderField::read_boxes(const std::vector<Box>& boxes) {
    return read_dense_boxes<std::uint16_t>(cl_, cl_field_, dims_, boxes,
                                           "reading the changed boxes of the compact field");
}

void update_packed32(ocl::Context& cl, vk::Raymarcher& marcher, const cl::Buffer& field,
                     const cl::Buffer& voxels, Dims dims, const std::vector<Box>& regions) {
    const std::vector<Box> boxes = clipped(regions, dims);
    const std::vector<std::uint32_t> words = read_dense_boxes<std::uint32_t>(
        cl, field, dims, boxes, "reading the changed boxes of the packed32 field");
    const std::vector<std::uint8_t> materials = read_dense_boxes<std::uint8_t>(
        cl, voxels, dims, boxes, "reading the changed boxes of the world's voxels");
    marcher.update_packed32(boxes, words, materials);
}

}  // namespace voxfield::pipeline
