#pragma once
// Pinned host memory for the small transfers of an edit (issue 24): a CL_MEM_ALLOC_HOST_PTR
// buffer mapped once for the object's life, so that writes from it and reads into it are the
// device's own copies, with no staging copy by the driver (on a CPU device it is host memory).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>

#include "voxfield/cl/runtime.hpp"

namespace voxfield::ocl {

class PinnedHost {
  public:
    PinnedHost() = default;
    ~PinnedHost() { release(); }
    PinnedHost(const PinnedHost&) = delete;
    PinnedHost& operator=(const PinnedHost&) = delete;

    // At least `bytes` of it (its contents are dropped when it grows; waits for the queue then).
    void reserve(Context& ctx, std::size_t bytes) {
        if (bytes <= size_) {
            return;
        }
        release();
        const std::size_t size = std::max<std::size_t>(bytes, 4096);
        cl_call("allocating " + std::to_string(size) + " bytes of pinned host memory", [&] {
            queue_ = ctx.queue();
            buffer_ = cl::Buffer(ctx.context(), CL_MEM_ALLOC_HOST_PTR | CL_MEM_READ_WRITE, size);
            data_ = static_cast<std::uint8_t*>(
                queue_.enqueueMapBuffer(buffer_, CL_TRUE, CL_MAP_READ | CL_MAP_WRITE, 0, size));
        });
        size_ = size;
    }
    std::uint8_t* data() { return data_; }
    std::size_t size() const { return size_; }

    // The event of the last transfer from or into this memory (`last() = ...`).
    cl::Event& last() { return last_; }
    // Waits until that transfer is done, when it is not yet, before the memory is rewritten;
    // returns whether it had to wait.
    bool settle() {
        if (last_() == nullptr) {
            return false;
        }
        const bool done = cl_call("polling a transfer", [&] {
            return last_.getInfo<CL_EVENT_COMMAND_EXECUTION_STATUS>() == CL_COMPLETE;
        });
        if (!done) {
            cl_call("waiting for a transfer", [&] { last_.wait(); });
        }
        last_ = cl::Event();
        return !done;
    }

  private:
    void release() {
        if (data_ == nullptr) {
            return;
        }
        // A failing unmap has no one left to report to; the buffer is released either way.
        try {
            queue_.enqueueUnmapMemObject(buffer_, data_);
            queue_.finish();
        } catch (const cl::Error&) {
        }
        data_ = nullptr;
        size_ = 0;
        last_ = cl::Event();
    }

    cl::CommandQueue queue_;
    cl::Buffer buffer_;
    std::uint8_t* data_ = nullptr;
    std::size_t size_ = 0;
    cl::Event last_;
};

}  // namespace voxfield::ocl
