#pragma once
// Pinned host memory for the small transfers of an edit (issue 24): a CL_MEM_ALLOC_HOST_PTR
// buffer mapped once for the object's life, so that writes from it and reads into it are the
// device's own copies, with no staging copy by the driver (on a CPU device it is host memory).
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

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
            ctx_ = &ctx;
            map_queue_ = ctx.queue();
            buffer_ = cl::Buffer(ctx.context(), CL_MEM_ALLOC_HOST_PTR | CL_MEM_READ_WRITE, size);
            data_ = static_cast<std::uint8_t*>(
                map_queue_.enqueueMapBuffer(buffer_, CL_TRUE, CL_MAP_READ | CL_MAP_WRITE, 0, size));
        });
        size_ = size;
    }
    std::uint8_t* data() { return data_; }
    std::size_t size() const { return size_; }

    // The event of the last transfer from or into this memory (`last() = ...`), or of a later
    // command of the same in-order queue.
    cl::Event& last() { return last_; }
    // A transfer enqueued without an event: until last() is set, settle() waits for the queue.
    void unfenced() {
        last_ = cl::Event();
        unfenced_ = true;
    }
    // Waits until that transfer is done, when it is not yet, before the memory is rewritten;
    // returns whether it had to wait.
    // The event is dropped first: one whose command failed (an error the edit that enqueued it
    // reported already) is not waited for again by every later call.
    bool settle() {
        const cl::Event pending = last_;
        const bool without_event = unfenced_;
        last_ = cl::Event();
        unfenced_ = false;
        if (pending() == nullptr) {
            if (without_event) {
                cl_call("waiting for a transfer", [&] { ctx_->queue().finish(); });
            }
            return without_event;
        }
        const bool done = cl_call("polling a transfer", [&] {
            return pending.getInfo<CL_EVENT_COMMAND_EXECUTION_STATUS>() == CL_COMPLETE;
        });
        if (!done) {
            cl_call("waiting for a transfer", [&] { pending.wait(); });
        }
        return !done;
    }

  private:
    void release() {
        if (data_ == nullptr) {
            return;
        }
        // A failing unmap has no one left to report to; the buffer is released either way.
        try {
            map_queue_.enqueueUnmapMemObject(buffer_, data_);
            map_queue_.finish();
        } catch (const cl::Error&) {
        }
        data_ = nullptr;
        size_ = 0;
        last_ = cl::Event();
        unfenced_ = false;
    }

    // settle() waits on the context's current queue (Context::Unprofiled: a transfer without an
    // event is on it, the other having finished); the map and unmap use the queue that was
    // current at the map (a copy: release() does not need the context).
    Context* ctx_ = nullptr;
    cl::CommandQueue map_queue_;
    cl::Buffer buffer_;
    std::uint8_t* data_ = nullptr;
    std::size_t size_ = 0;
    cl::Event last_;
    bool unfenced_ = false;
};

// Small tables written to the device in one transfer: one device buffer with a sub-buffer per
// table (at the device's base address alignment) and its pinned host copy.
class PinnedTables {
  public:
    // Room for table i of bytes[i] bytes, once the last write from the host copy is done
    // (whether that needed a wait: `waited`). A table whose room falls short gets twice that;
    // the tables are then made again (their contents dropped).
    void fit(Context& ctx, std::span<const std::size_t> bytes, bool* waited) {
        *waited = pinned_.settle();
        bool grow = caps_.size() != bytes.size();
        caps_.resize(bytes.size(), 0);
        for (std::size_t i = 0; i < bytes.size(); ++i) {
            if (bytes[i] > caps_[i]) {
                caps_[i] = std::max<std::size_t>(2 * bytes[i], 64);
                grow = true;
            }
        }
        if (grow) {
            make(ctx);
        }
        end_ = offsets_.back() + bytes.back();
    }
    template <class T>
    T* host(std::size_t i) {
        return reinterpret_cast<T*>(pinned_.data() + offsets_[i]);
    }
    const cl::Buffer& buffer(std::size_t i) const { return subs_[i]; }
    // Enqueues the write of every table (one transfer, without waiting), with an event, or
    // without one (an event costs the host several microseconds on a GPU): then the caller
    // names a later command of the same in-order queue (settled_by) for the next fit() to wait
    // for, else that fit() waits for the queue.
    void write(cl::CommandQueue& q, bool event = true) {
        if (event) {
            q.enqueueWriteBuffer(all_, CL_FALSE, 0, end_, pinned_.data(), nullptr, &pinned_.last());
        } else {
            q.enqueueWriteBuffer(all_, CL_FALSE, 0, end_, pinned_.data());
            pinned_.unfenced();
        }
    }
    void settled_by(const cl::Event& later) { pinned_.last() = later; }
    // The last write's event (null for one without).
    const cl::Event& last_write() { return pinned_.last(); }

  private:
    void make(Context& ctx) {
        const cl::Device device = ctx.queue().getInfo<CL_QUEUE_DEVICE>();
        const std::size_t align =
            std::max<std::size_t>(device.getInfo<CL_DEVICE_MEM_BASE_ADDR_ALIGN>() / 8, 64);
        offsets_.clear();
        std::size_t size = 0;
        for (const std::size_t cap : caps_) {
            offsets_.push_back(size);
            size += (cap + align - 1) / align * align;
        }
        cl_call("allocating " + std::to_string(size) + " bytes of tables", [&] {
            all_ = cl::Buffer(ctx.context(), CL_MEM_READ_ONLY, size);
            subs_.clear();
            for (std::size_t i = 0; i < caps_.size(); ++i) {
                const cl_buffer_region region{offsets_[i], caps_[i]};
                subs_.push_back(
                    all_.createSubBuffer(CL_MEM_READ_ONLY, CL_BUFFER_CREATE_TYPE_REGION, &region));
            }
        });
        pinned_.reserve(ctx, size);
    }

    PinnedHost pinned_;
    cl::Buffer all_;
    std::vector<cl::Buffer> subs_;
    std::vector<std::size_t> caps_, offsets_;
    std::size_t end_ = 0;
};

}  // namespace voxfield::ocl
