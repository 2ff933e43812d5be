// The compact render field shared between OpenCL and Vulkan (see render_field.hpp).
#include "voxfield/pipeline/render_field.hpp"

#include "voxfield/layout.h"

#include <algorithm>
#include <cstddef>
#include <exception>

namespace voxfield::pipeline {

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

RenderField::RenderField(ocl::Context& cl_ctx, vk::Context& vk_ctx, const vk::Raymarcher& marcher,
                         Dims dims, vk::SharingPath fastest)
    : cl_(cl_ctx), vk_(vk_ctx), dims_(dims), layout_(marcher.plan(dims, vk::FieldFormat::compact)) {
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
        cl_field_ = ocl::cl_call("the compact field buffer", [&] {
            return cl::Buffer(cl_ctx.context(), CL_MEM_READ_WRITE,
                              static_cast<std::size_t>(layout_.total_bytes));
        });
    }
    if (why_not_.size() >= 2) {
        why_not_.resize(why_not_.size() - 2);
    }
}

RenderField::~RenderField() {
    writer_.reset();
    cl_field_ = cl::Buffer();
}

double RenderField::attach(vk::Raymarcher& marcher, const cl::Buffer& field, Format format,
                           Metric metric, const cl::Buffer& voxels, const Palette& palette,
                           double step) {
    wait_for_readers();
    writer_.reset();
    const bool copy = path_ == vk::SharingPath::copy;
    writer_.emplace(cl_, field, format, voxels, dims_, cl_field_,
                    ocl::SlabLayout{layout_.slab_depth, layout_.slab_stride,
                                    copy ? std::nullopt : std::optional{layout_.total_bytes}},
                    path_ == vk::SharingPath::opaque_fd      ? ocl::DstMemory::external
                    : path_ == vk::SharingPath::host_pointer ? ocl::DstMemory::host
                                                             : ocl::DstMemory::device,
                    step);
    const double ms = writer_->run();
    if (copy) {
        marcher.upload_compact(dims_, palette, read_compact());
        marcher.set_block_min(writer_->block_min());
    } else {
        marcher.bind_shared(shared_, layout_, palette);
        marcher.bind_shared_block_min(shared_, layout_.total_bytes);
    }
    marcher.set_metric(metric);  // after the field (a new one resets it)
    return ms;
}

double RenderField::update(vk::Raymarcher& marcher, const std::vector<Box>& regions) {
    wait_for_readers();
    const double ms = writer_->run(regions);
    if (path_ == vk::SharingPath::copy) {
        marcher.update_compact(read_compact());
        marcher.update_block_min(writer_->changed_blocks(),
                                 writer_->block_min(writer_->changed_blocks()));
    }
    return ms;
}

void RenderField::wait_for_readers() {
    if (path_ != vk::SharingPath::copy) {
        vk_.wait_frames_in_flight();
    }
}

std::vector<std::uint16_t> RenderField::read_compact() {
    // Path 3: read the slabs back (each slab's voxels are contiguous).
    std::vector<std::uint16_t> compact(dims_.count());
    const std::size_t plane = std::size_t{dims_.x} * dims_.y;
    for (std::uint32_t s = 0; s < layout_.slabs; ++s) {
        const std::size_t z0 = std::size_t{s} * layout_.slab_depth;
        const std::size_t voxels = plane * std::min<std::size_t>(layout_.slab_depth, dims_.z - z0);
        ocl::cl_call("reading the compact field", [&] {
            cl_.queue().enqueueReadBuffer(cl_field_, CL_TRUE, s * layout_.slab_stride, voxels * 2,
                                          compact.data() + plane * z0);
        });
    }
    return compact;
}

}  // namespace voxfield::pipeline
