// Path 1's edits ordered by OpenCL <-> Vulkan semaphores (field_semaphores.hpp).
#include "field_semaphores.hpp"

#include <exception>

namespace voxfield::pipeline {

FieldSemaphores::FieldSemaphores(ocl::Context& cl, vk::Context& vk)
    : cl_(cl),
      vk_(vk),
      read_vk_(vk, "the field-read semaphore"),
      written_vk_(vk, "the field-written semaphore"),
      // Each import takes its fd (cl_khr_external_semaphore: a successful import owns it, a
      // failed one is closed by ocl::ExternalSemaphore): never closed here.
      read_cl_(cl, read_vk_.export_fd()),
      written_cl_(cl, written_vk_.export_fd()) {}

FieldSemaphores::~FieldSemaphores() {
    // Nothing to report from a destructor: the semaphores go after this anyway.
    try {
        cl_.queue().finish();  // OpenCL's waits and signals have executed
    } catch (const std::exception&) {
    }
    try {
        vk_.wait_frames_in_flight();  // so have Vulkan's batches that use them
    } catch (const std::exception&) {
    }
    read_cl_ = ocl::ExternalSemaphore();
    written_cl_ = ocl::ExternalSemaphore();
}

double FieldSemaphores::update(ocl::CompactWriter& writer, const std::vector<Box>& regions) {
    // Each semaphore is signalled, then waited for, once per update, in that order: "read" by a
    // Vulkan batch then OpenCL; "written" by OpenCL then a Vulkan batch submitted after
    // OpenCL enqueued (and flushed) the signal. So no wait meets an unsignalled semaphore (a
    // frame without an edit waits for nothing) and no signal a signalled one: this update's
    // "read" batch follows the previous update's "written" wait through its barrier, and
    // OpenCL's "written" signal follows its "read" wait.
    // Nothing submitted is unfinished: no frame reads the field, and the previous update's
    // "written" wait has executed. OpenCL then writes without waiting.
    const bool readers = vk_.busy();
    if (readers) {
        // Fails before anything is signalled (a failed vkQueueSubmit leaves semaphores as
        // they were): the pair stays usable.
        vk_.signal_semaphore(read_vk_.get(), "the frames reading the field, done");
    }
    broken_ = true;  // until both halves below are in
    try {
        const double ms = writer.run_ordered(regions, readers ? &read_cl_ : nullptr, written_cl_);
        vk_.wait_semaphore(written_vk_.get(), "the next frames wait for the written field");
        broken_ = false;
        return ms;
    } catch (...) {
        // The frames after this read the field only once OpenCL finished writing it.
        try {
            cl_.queue().finish();
        } catch (const std::exception&) {
        }
        throw;
    }
}

}  // namespace voxfield::pipeline
