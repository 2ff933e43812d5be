#pragma once
// A sparse world's 64-trees on the OpenCL device (ocl::SparseDeviceWorld, inside
// ocl::SparseField) in memory the Vulkan sparse tracer reads in place (DESIGN §2's sharing
// paths, as for the dense render field): path 1 Vulkan-exported device memory imported by
// OpenCL (opaque fd), path 2 one host allocation used by both (a CPU OpenCL device). The world
// is then on the device once, not twice (the tracer's own copy of a 16384 x 1024 x 16384 city
// would be another 72.6 GB), and an edit or a sand step moves no tree through the host: the
// tracer's records are pointed at the tiles' new places (vk::SparseTracer::repoint). Path 3:
// nothing is shared; the caller uploads and updates the tracer from the host world as before.
// The glue between cl/ and vk/, part of the frame pipeline.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "voxfield/cl/sparse_device_world.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/vk/shared.hpp"
#include "voxfield/vk/sparse_tracer.hpp"

namespace voxfield::pipeline {

class SharedTrees {
  public:
    // Chooses the path (choose_sharing_path from `fastest`). Both contexts must outlive this
    // object, and this object the SparseField made with allocator().
    SharedTrees(ocl::Context& cl_ctx, vk::Context& vk_ctx,
                vk::SharingPath fastest = vk::SharingPath::opaque_fd);
    ~SharedTrees();
    SharedTrees(const SharedTrees&) = delete;
    SharedTrees& operator=(const SharedTrees&) = delete;

    vk::SharingPath path() const { return path_; }
    bool shares() const { return path_ != vk::SharingPath::copy; }
    // Why faster paths were not taken (for reports).
    const std::string& why_not() const { return why_not_; }

    // Where the device world's trees are allocated (ocl::SparseField's `allocate`): shared
    // memory on paths 1 and 2, empty (plain device buffers) on path 3.
    ocl::TreeAllocator allocator();

    // Brings `tracer` up to date with `world` (paths 1 and 2 only; logic_error on path 3):
    // after the OpenCL queue finished, the whole directory when the world's main buffers are new
    // (the first call, a whole upload), else the tiles `changed` overlaps (their places now, or
    // removed) and any slot memory that was replaced. Memory the tracer no longer reads is freed
    // after. `palette`: the world's (a whole directory takes it).
    vk::SparseTileUpdate sync(vk::SparseTracer& tracer, const ocl::SparseDeviceWorld& world,
                              const Dims& dims, const Palette& palette, const Box& changed);

    // Path 1 (cl_khr_external_memory): OpenCL owns the imported memory between an acquire and
    // a release; before_trace releases the world's buffers to Vulkan (and finishes the queue),
    // after_trace acquires them again. No-ops on path 2.
    void before_trace();
    void after_trace();

    // Bytes of shared memory allocated (live and not yet freed).
    std::uint64_t bytes() const;

  private:
    struct Allocation;
    cl::Buffer allocate(std::size_t bytes, const std::string& what);
    const vk::ExternalMemory* memory_of(const cl::Buffer& buffer) const;
    std::vector<vk::SharedTreeSet> sets_of(const ocl::SparseDeviceWorld::TreeBuffers& b) const;
    void free_unused(const ocl::SparseDeviceWorld::TreeBuffers& b);

    ocl::Context& cl_;
    vk::Context& vk_;
    vk::SharingPath path_ = vk::SharingPath::copy;
    std::string why_not_;
    std::vector<std::unique_ptr<Allocation>> allocations_;
    // The main masks buffer the tracer's directory was made for (retained in allocations_
    // until the tracer reads other memory, so no new buffer can have its handle).
    cl_mem traced_main_ = nullptr;
    std::vector<cl::Buffer> released_;  // path 1: buffers handed to Vulkan by before_trace
};

}  // namespace voxfield::pipeline
