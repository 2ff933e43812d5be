#pragma once
// Path 1's edits ordered on the devices (DESIGN §2 "Synchronisation"): two binary semaphores
// that Vulkan creates and exports as opaque fds and OpenCL imports. "Field read": signalled by
// a Vulkan batch after every submission so far (the frames in flight that read the field),
// waited for by OpenCL before it writes. "Field written": signalled by OpenCL after the
// conversion released the field, waited for by a Vulkan batch before every later submission
// (the next frames). No CPU waits for a frame, nor for the conversion.
#include <string>
#include <vector>

#include "voxfield/cl/interop.hpp"
#include "voxfield/vk/context.hpp"
#include "voxfield/vk/shared.hpp"

namespace voxfield::pipeline {

class FieldSemaphores {
  public:
    // Creates, exports and imports both. Throws (VkError, ocl::ClError) where a driver refuses;
    // the render field then keeps the fence path and says why.
    FieldSemaphores(ocl::Context& cl, vk::Context& vk);
    // Both queues idle first (OpenCL finished, Vulkan's submissions done), then OpenCL's
    // imports released, then Vulkan's semaphores destroyed. Never throws.
    ~FieldSemaphores();
    FieldSemaphores(const FieldSemaphores&) = delete;
    FieldSemaphores& operator=(const FieldSemaphores&) = delete;

    // One update of the shared field by `writer` (its destination imported from Vulkan),
    // ordered by the semaphores: returns ocl::CompactWriter::run_ordered's time. A failure part
    // way leaves a semaphore signalled that nothing will wait for: the pair is then broken()
    // for good (OpenCL finished what it enqueued) and the caller converts again on the fence
    // path. A failure before (the "read" batch not submitted) leaves it usable.
    double update(ocl::CompactWriter& writer, const std::vector<Box>& regions);
    bool broken() const { return broken_; }

  private:
    ocl::Context& cl_;
    vk::Context& vk_;
    // Vulkan's semaphores outlive OpenCL's imports of them (released first, declared last).
    vk::ExportedSemaphore read_vk_, written_vk_;
    ocl::ExternalSemaphore read_cl_, written_cl_;
    bool broken_ = false;
};

}  // namespace voxfield::pipeline
