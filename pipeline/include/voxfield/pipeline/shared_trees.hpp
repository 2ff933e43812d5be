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
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "voxfield/cl/sparse_device_world.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/vk/shared.hpp"
#include "voxfield/vk/sparse_tracer.hpp"

namespace voxfield::pipeline {

class SharedTrees {
  public:
    // An allocation of shared memory failed (over the Vulkan device's maxBufferSize, or refused
    // by either API: over maxMemoryAllocationSize, a soft limit some drivers keep, out of
    // memory); what() says which buffer and why. The caller may fall back to path 3 (a
    // SparseField without allocator()).
    class AllocationError : public std::runtime_error {
      public:
        using std::runtime_error::runtime_error;
    };

    // Chooses the path (choose_sharing_path from `fastest`; path 3 when the Vulkan device has no
    // buffer device addresses; path 1 only when a small exported allocation imports, acquires
    // and releases in OpenCL, else path 2 or 3 with the reason in why_not()). Both contexts must
    // outlive this object, and this object the SparseField made with allocator().
    // `max_allocation_bytes`: the largest buffer allocated (0: the Vulkan device's
    // maxBufferSize; tests lower it).
    SharedTrees(ocl::Context& cl_ctx, vk::Context& vk_ctx,
                vk::SharingPath fastest = vk::SharingPath::opaque_fd,
                std::uint64_t max_allocation_bytes = 0);
    ~SharedTrees();
    SharedTrees(const SharedTrees&) = delete;
    SharedTrees& operator=(const SharedTrees&) = delete;

    vk::SharingPath path() const { return path_; }
    bool shares() const { return path_ != vk::SharingPath::copy; }
    // Why faster paths were not taken (for reports).
    const std::string& why_not() const { return why_not_; }

    // Where the device world's trees are allocated (ocl::SparseField's `allocate`): shared
    // memory on paths 1 and 2, empty (plain device buffers) on path 3. AllocationError when an
    // allocation fails. When the world drops buffers (a whole upload), the memory only they
    // used is freed at once and the tracer last synced forgets it (SparseTracer::drop_shared):
    // the world is never held twice.
    ocl::TreeAllocator allocator();

    // Brings `tracer` up to date with `world` (paths 1 and 2 only; logic_error on path 3):
    // after the OpenCL queue finished, the whole directory when the world's main buffers are new
    // (the first call, a whole upload, or after a failed sync), else the tiles `changed`
    // overlaps (their places now, or removed) and any slot memory that was replaced. Memory the
    // tracer no longer reads is freed after. `palette`: the world's (a whole directory takes it).
    // One world per object. The tracer synced last is told when memory it reads is freed (a
    // whole upload of the world: SparseTracer::drop_shared), so it must outlive every later
    // whole upload, or be forgotten first (forget).
    vk::SparseTileUpdate sync(vk::SparseTracer& tracer, const ocl::SparseDeviceWorld& world,
                              const Dims& dims, const Palette& palette, const Box& changed);
    // The same for a list of tiles (tile coordinates) that changed, such as a sand step's
    // (ocl::SparseSand::Step::tiles): only those, where the box of a scattered change would
    // take every tile between them.
    vk::SparseTileUpdate sync(vk::SparseTracer& tracer, const ocl::SparseDeviceWorld& world,
                              const Dims& dims, const Palette& palette,
                              const std::vector<Int3>& changed_tiles);

    // Brackets one trace (or several) of the tracer synced last: on path 1
    // (cl_khr_external_memory) OpenCL owns the imported memory between an acquire and a release,
    // so the scope releases every shared buffer to Vulkan and finishes the queue, and acquires
    // them back when it ends; on path 2 (CL_MEM_USE_HOST_PTR) the host, and so Vulkan, may read
    // the memory only while it is mapped, so the scope maps every buffer for reading and unmaps
    // it after. One scope at a time (logic_error otherwise); OpenCL must not touch the world
    // inside it.
    class TraceScope {
      public:
        explicit TraceScope(SharedTrees& shared);
        ~TraceScope();
        TraceScope(const TraceScope&) = delete;
        TraceScope& operator=(const TraceScope&) = delete;

      private:
        SharedTrees& shared_;
    };

    // `tracer` is going away: no later whole upload tells it anything.
    void forget(const vk::SparseTracer& tracer);

    // Bytes of shared memory allocated (live and not yet freed).
    std::uint64_t bytes() const;

  private:
    struct Allocation;
    cl::Buffer allocate(std::size_t bytes, const std::string& what);
    // The world dropped buffers: frees every allocation but those it `kept`.
    void dropped(const std::vector<cl::Buffer>& kept);
    const Allocation* allocation_of(const cl::Buffer& buffer) const;
    // Frees the allocations `drop` selects, OpenCL's hold on them given back first (path 1);
    // throws nothing.
    void free_where(const std::function<bool(const Allocation&)>& drop);
    std::vector<vk::SharedTreeSet> sets_of(const ocl::SparseDeviceWorld::TreeBuffers& b) const;
    void free_unused(const ocl::SparseDeviceWorld::TreeBuffers& b);
    vk::SparseTileUpdate sync_tiles(vk::SparseTracer& tracer, const ocl::SparseDeviceWorld& world,
                                    const Dims& dims, const Palette& palette,
                                    const std::vector<Int3>& tiles);
    void begin_trace();
    void end_trace() noexcept;

    ocl::Context& cl_;
    vk::Context& vk_;
    vk::SharingPath path_ = vk::SharingPath::copy;
    std::string why_not_;
    std::uint64_t max_allocation_ = 0;  // 0: no limit known
    std::vector<std::unique_ptr<Allocation>> allocations_;
    std::uint64_t next_serial_ = 1;
    // The serial of the main masks buffer the tracer's directory was made for (0: none), and the
    // tracer synced last.
    std::uint64_t traced_main_ = 0;
    vk::SparseTracer* tracer_ = nullptr;
    // Inside a TraceScope: the buffers released (path 1) or mapped (path 2, with their maps).
    bool tracing_ = false;
    std::vector<std::pair<cl::Buffer, void*>> held_;
};

}  // namespace voxfield::pipeline
