#pragma once
// OpenCL runtime: errors, device enumeration and selection, a context with a profiling
// queue, a program cache keyed by device, source and build options (in memory, and on disk
// across runs), and host memory that buffers can use in place.
#include <CL/opencl.hpp>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "voxfield/core/error.hpp"

namespace voxfield::ocl {

// A failed OpenCL call: the API function, its symbolic error code, and our context (kernel,
// sizes). The command line maps it to exit code 1.
class ClError : public std::runtime_error {
  public:
    ClError(const std::string& call, cl_int code, const std::string& context);
    cl_int code() const { return code_; }

  private:
    cl_int code_;
};

// A kernel program that failed to build: carries the device name and the full build log.
class BuildError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// No device matches the request: the message lists every device and why it was rejected.
class DeviceSelectionError : public InputError {
  public:
    using InputError::InputError;
};

const char* error_name(cl_int code);

struct DeviceInfo {
    std::size_t index = 0;  // position in list_devices(), as `voxfield devices` shows it
    cl::Device device;
    std::string name, vendor, platform, version, driver, type;  // type: "cpu", "gpu", ...
    cl_uint compute_units = 0;
    cl_ulong global_mem = 0, max_alloc = 0, local_mem = 0;
    std::size_t max_work_group = 0;
    std::vector<std::string> extensions;
    bool available = false, compiler_available = false;
    bool host_unified_memory = false;  // CL_DEVICE_HOST_UNIFIED_MEMORY

    bool has_extension(const std::string& ext) const;
};

// Every device of every platform, in platform order. Empty if there is no ICD.
std::vector<DeviceInfo> list_devices();

// spec: "cpu", "gpu", a decimal index, or "" for the default: $VOXFIELD_DEVICE if set, else
// the first GPU, else the first CPU. Throws DeviceSelectionError explaining each rejection.
// Walks the platforms in order only as far as the one holding the device asked for (the
// platforms after it are never asked for devices) and reads the full info of that device
// alone; every device is listed only to explain a failure.
DeviceInfo select_device(const std::string& spec);

// Built programs kept across runs on disk: one file per program, named by a digest of the
// kernel sources, the build options, the device's name and version, the driver version and
// the platform, under $XDG_CACHE_HOME/voxfield/programs (else ~/.cache/voxfield/programs).
// Off when $VOXFIELD_NO_PROGRAM_CACHE is set to anything but "" or "0" (or without a home).
// An entry that cannot be read, fails its checksum or does not load is built from source and
// written again; entries are written atomically (a temporary renamed onto the name), so a
// reader sees a whole entry or none. The folder it uses, empty when off (read per call).
std::filesystem::path program_cache_dir();

// What a context's programs came from (for reports and tests).
struct ProgramCacheStats {
    std::size_t loaded = 0;    // from a disk entry
    std::size_t built = 0;     // from source
    std::size_t stored = 0;    // disk entries written
    std::size_t rejected = 0;  // disk entries found unusable, rebuilt
};

// One device with its own context and in-order profiling queue (and, while an Unprofiled guard
// lives, a second in-order queue without profiling in its place).
class Context {
  public:
    explicit Context(DeviceInfo device);

    const DeviceInfo& info() const { return info_; }
    cl::Context& context() { return context_; }
    cl::CommandQueue& queue() { return queue_; }
    // While a guard lives, queue() is an in-order queue without profiling, for short work that
    // does not time its commands (a lean sparse edit): NVIDIA's driver takes about a third less
    // host time per command there (bench/README.md). Making the guard waits for the profiling
    // queue's commands and dropping it for its own, so that each queue starts with the other's
    // work done. Commands enqueued under it have no profiling info (elapsed_ms gives 0, and
    // command_span an empty span). A guard made while another lives changes nothing.
    class Unprofiled {
      public:
        explicit Unprofiled(Context& ctx);
        ~Unprofiled();
        Unprofiled(const Unprofiled&) = delete;
        Unprofiled& operator=(const Unprofiled&) = delete;

      private:
        Context* ctx_ = nullptr;  // null for a nested guard
    };
    bool is_cpu() const { return info_.type == "cpu"; }
    // Whether the device computes in host memory (a CPU device, or one that reports
    // CL_DEVICE_HOST_UNIFIED_MEMORY), so that a buffer over host memory
    // (CL_MEM_USE_HOST_PTR) is used in place: no upload, no download, no staging copy.
    bool computes_in_host_memory() const { return is_cpu() || info_.host_unified_memory; }

    // Builds (or returns the cached) program from embedded sources; BuildError on failure.
    // Cached in this context, and on disk across runs (program_cache_dir(), as it was when
    // the context was made).
    cl::Program program(const std::string& name, const std::vector<std::string>& sources,
                        const std::string& options);
    const ProgramCacheStats& program_cache_stats() const { return cache_stats_; }

  private:
    // The program of a disk entry, built for the device; nullopt when there is none or it is
    // unusable (counted as rejected).
    std::optional<cl::Program> load_program(const std::filesystem::path& entry,
                                            const std::string& digest, const std::string& options);
    void store_program(const std::filesystem::path& entry, const std::string& digest,
                       const std::string& name, const std::string& options,
                       const cl::Program& program);

    DeviceInfo info_;
    cl::Context context_;
    cl::CommandQueue queue_;
    cl::CommandQueue other_queue_;  // the profiling queue while an Unprofiled guard lives
    bool unprofiled_ = false;
    std::filesystem::path cache_dir_;
    ProgramCacheStats cache_stats_;
    // Keyed by (name, options, sources): two programs of one name built from different
    // sources are two programs.
    std::map<std::tuple<std::string, std::string, std::vector<std::string>>, cl::Program> programs_;
};

// Runs `body`, turning a cl::Error into a ClError with `context`.
template <class F>
decltype(auto) cl_call(const std::string& context, F&& body) {
    try {
        return body();
    } catch (const cl::Error& e) {
        throw ClError(e.what(), e.err(), context);
    }
}

// Milliseconds between the start of `first` and the end of `last` (profiling info).
double elapsed_ms(const cl::Event& first, const cl::Event& last);

// Of `commands` (finished, profiled; empty events are skipped): the first start to the last end,
// and the part of that span in which none of them ran (ms); an empty span where one has no
// profiling info (enqueued under Context::Unprofiled).
struct CommandSpan {
    double span_ms = 0, idle_ms = 0;
};
CommandSpan command_span(const std::vector<cl::Event>& commands);
// The same of (start, end) pairs in nanoseconds, in any order, overlapping or not.
CommandSpan command_span(std::vector<std::pair<cl_ulong, cl_ulong>> runs);

// Page-aligned host memory that is never zero-filled: its pages are touched first by whoever
// writes them first (a read from a file, or the kernels writing a CL_MEM_USE_HOST_PTR buffer
// over it, in parallel). Allocations of 2 MiB and more are 2 MiB-aligned, a whole number of
// 2 MiB long, and ask for transparent huge pages (madvise MADV_HUGEPAGE), so that first
// touches fault 2 MiB at a time. Those blocks, when freed, go to a process-wide cache of at
// most 1 GiB, from which the next allocation of the same length takes them with their pages
// already in place: a process that transforms world after world (the Python module, repeated
// runs) does not fault and zero the same memory again on every call. An allocation the cache
// cannot serve first empties it (the lengths in use have changed), so the cache never holds
// more than the blocks of the calls since.
class HostMemory {
  public:
    HostMemory() = default;
    explicit HostMemory(std::size_t bytes);  // std::bad_alloc when the host cannot give it

    std::uint8_t* data() { return data_.get(); }
    const std::uint8_t* data() const { return data_.get(); }
    std::size_t size() const { return size_; }
    std::span<std::uint8_t> span() { return {data_.get(), size_}; }
    std::span<const std::uint8_t> span() const { return {data_.get(), size_}; }

  private:
    struct Free {
        std::size_t capacity;  // the block's length (2 MiB multiples go to the cache)
        void operator()(std::uint8_t* p) const;
    };
    std::unique_ptr<std::uint8_t, Free> data_;
    std::size_t size_ = 0;
};

// A buffer mapped for reading on the host (blocking map; unmapped, and the unmap waited for,
// when destroyed). A buffer over host memory on a device that computes in host memory maps in
// place; elsewhere the driver copies the buffer into host memory of its own.
class MappedBuffer {
  public:
    MappedBuffer(Context& ctx, const cl::Buffer& buffer, std::size_t bytes);
    ~MappedBuffer();
    MappedBuffer(const MappedBuffer&) = delete;
    MappedBuffer& operator=(const MappedBuffer&) = delete;

    std::span<const std::uint8_t> bytes() const { return {data_, size_}; }
    double map_ms() const { return map_ms_; }  // the map command (profiling event)

  private:
    cl::CommandQueue queue_;
    cl::Buffer buffer_;
    const std::uint8_t* data_ = nullptr;
    std::size_t size_ = 0;
    double map_ms_ = 0;
};

// Hands the first `bytes` of `buffer` to `sink` in order, piece by piece, after the work queued
// before. On a device that computes in host memory: one map (in place where the buffer lies over
// host memory). Elsewhere through two pinned staging buffers (CL_MEM_ALLOC_HOST_PTR) of at most
// `piece` bytes each: the download of a piece overlaps the sink's work on the one before, so a
// sink that writes a file hides the download. Returns the transfers' device time (profiling
// events) in ms. `staged`: the staging path on any device (for tests on a CPU device).
double read_streamed(Context& ctx, const cl::Buffer& buffer, std::size_t bytes,
                     const std::function<void(std::span<const std::uint8_t>)>& sink,
                     std::size_t piece = std::size_t{32} << 20, bool staged = false);

}  // namespace voxfield::ocl
