#pragma once
// The ray marcher's compact field, written by OpenCL where Vulkan reads it (DESIGN §2): the
// first sharing path both devices support (1 opaque fd -> 2 host pointer -> 3 copy), with the
// conversion from any distance field on the OpenCL device (ocl::CompactWriter) and the coarse
// table the ray marcher skips with (its block minima). On paths 1/2 the table lies in the
// shared allocation after the slabs and OpenCL writes it in place; on path 3 an edit copies
// only the minima of the blocks it changed. The glue between cl/ and vk/, part of the frame
// pipeline.
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "voxfield/cl/interop.hpp"
#include "voxfield/vk/raymarcher.hpp"
#include "voxfield/vk/shared.hpp"

namespace voxfield::pipeline {

// DESIGN §2: the first sharing path both devices support, 1 -> 2 -> 3, starting at `fastest`,
// and why the earlier ones are not (for reports).
vk::SharingPath choose_sharing_path(const ocl::Context& cl_ctx, const vk::Context& vk_ctx,
                                    std::string& why_not,
                                    vk::SharingPath fastest = vk::SharingPath::opaque_fd);

// How OpenCL's writes into the render field are ordered against the frames that read it
// (DESIGN §2 "Synchronisation"). semaphore: path 1 with OpenCL <-> Vulkan semaphores, no CPU
// wait; fence: paths 1/2, the CPU waits for the fence of the latest frame that reads the field
// and OpenCL finishes before the update returns; queue: path 3 (and packed32), copies ordered
// by the Vulkan queue.
enum class FieldSync { semaphore, fence, queue };
std::string to_string(FieldSync sync);  // "semaphore", "fence", "queue"

// The ordering `path` gets between these devices: semaphore where the path is 1, the Vulkan
// device exports semaphores as opaque fds (vk::can_export_semaphore_fd), the OpenCL device
// imports them (ocl::can_import_semaphore_fd) and $VOXFIELD_NO_CL_SEMAPHORE is unset (or empty
// or 0); else fence (paths 1/2) or queue (path 3), with why not semaphores in `why_not`.
FieldSync choose_field_sync(const ocl::Context& cl_ctx, const vk::Context& vk_ctx,
                            vk::SharingPath path, std::string& why_not);

class FieldSemaphores;

// The packed32 render format (always copied, path 3) after an edit: reads back only the
// voxels of `regions` (clipped to the world of `dims`) of `field` (the packed32 field on the
// OpenCL device, x fastest) and of `voxels` (the world's voxels there, one byte each), and
// copies both into `marcher` in place, ordered behind its frames in flight
// (vk::Raymarcher::update_packed32): 5 bytes per changed voxel instead of the whole field.
// `marcher` holds the packed32 field of a world of `dims` (vk::Raymarcher::upload).
void update_packed32(ocl::Context& cl, vk::Raymarcher& marcher, const cl::Buffer& field,
                     const cl::Buffer& voxels, Dims dims, const std::vector<Box>& regions);

class RenderField {
  public:
    // Allocates the compact field for `dims` as `marcher` plans it, on the first path that
    // works, from `fastest` on (a path 1 import that fails falls back, and says why in
    // why_not()). The ray marcher must be destroyed before this object (it may read this
    // memory).
    RenderField(ocl::Context& cl_ctx, vk::Context& vk_ctx, const vk::Raymarcher& marcher, Dims dims,
                vk::SharingPath fastest = vk::SharingPath::opaque_fd);
    ~RenderField();
    RenderField(const RenderField&) = delete;
    RenderField& operator=(const RenderField&) = delete;

    // Converts from a new source (the field in `format` with distances in `metric`, and the
    // world's voxels, both on the OpenCL device; they must stay alive until the next attach)
    // and shows the whole field in `marcher` (bound in place on paths 1/2, copied on path 3),
    // which then steps by that metric. Paths 1/2: first waits for the latest Vulkan frame that
    // reads the memory OpenCL overwrites. Returns the OpenCL time in ms.
    // `step` is the field's largest voxel spacing (1 for unit spacing): its distances are
    // converted into voxels, rounded down, for the ray marcher.
    double attach(vk::Raymarcher& marcher, const cl::Buffer& field, Format format, Metric metric,
                  const cl::Buffer& voxels, const Palette& palette, double step = 1.0);
    // Lets go of the source (before it is replaced, so that both never hold device memory
    // at once); update() needs an attach() after this.
    void detach() { writer_.reset(); }
    // After the source changed inside `regions`: converts those voxels and recomputes the
    // minima of the blocks they touch. Paths 1/2 copy nothing. With FieldSync::semaphore
    // (path 1) OpenCL waits on the device for the frames in flight and the later frames wait
    // on the device for OpenCL: nothing waits on the CPU, and the returned time is that of the
    // conversions found finished since the last update (an update's own usually counts at the
    // next). With FieldSync::fence the CPU first waits for the fence of the latest frame that
    // reads the field, which OpenCL overwrites, and OpenCL has finished writing when this
    // returns (also from the update where the semaphores failed part way on: they are not
    // used again, sync() turns to fence and sync_why_not() says why). Path 3 reads
    // back only those regions and blocks and copies them into the ray marcher in place, ordered
    // behind the frames in flight by the queue, with no CPU wait (vk::Raymarcher::
    // update_compact, update_block_min). Returns the OpenCL time in ms.
    double update(vk::Raymarcher& marcher, const std::vector<Box>& regions);

    vk::SharingPath path() const { return path_; }
    FieldSync sync() const { return sync_; }
    // Why the edits are not ordered by semaphores ("" when they are).
    const std::string& sync_why_not() const { return sync_why_not_; }
    // Why faster paths are not in use ("" on path 1).
    const std::string& why_not() const { return why_not_; }

  private:
    // Paths 1/2: no Vulkan frame in flight reads the shared field any more (the fence of the
    // latest frame that reads it, vk::Raymarcher::wait_for_readers).
    void wait_for_readers(vk::Raymarcher& marcher);
    // Path 3: the voxels of `boxes` (inside the world) read back from OpenCL, box after box
    // and x fastest in each.
    std::vector<std::uint16_t> read_boxes(const std::vector<Box>& boxes);

    ocl::Context& cl_;
    Dims dims_;
    vk::FieldLayout layout_;
    vk::SharingPath path_ = vk::SharingPath::copy;
    std::string why_not_;
    FieldSync sync_ = FieldSync::queue;
    std::string sync_why_not_;
    // Release order (reverse): writer (path 2: unmaps), OpenCL buffer, then the memory.
    vk::ExternalMemory shared_;
    cl::Buffer cl_field_;
    std::optional<ocl::CompactWriter> writer_;
    // Path 1 with FieldSync::semaphore; destroyed first (it waits for both queues).
    std::unique_ptr<FieldSemaphores> semaphores_;
};

}  // namespace voxfield::pipeline
