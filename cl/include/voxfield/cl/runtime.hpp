#pragma once
// OpenCL runtime: errors, device enumeration and selection, a context with a profiling
// queue, and a program cache keyed by device, source and build options.
#include <CL/opencl.hpp>

#include <map>
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

    bool has_extension(const std::string& ext) const;
};

// Every device of every platform, in platform order. Empty if there is no ICD.
std::vector<DeviceInfo> list_devices();

// spec: "cpu", "gpu", a decimal index, or "" for the default: $VOXFIELD_DEVICE if set, else
// the first GPU, else the first CPU. Throws DeviceSelectionError explaining each rejection.
DeviceInfo select_device(const std::string& spec);

// One device with its own context and in-order profiling queue.
class Context {
  public:
    explicit Context(DeviceInfo device);

    const DeviceInfo& info() const { return info_; }
    cl::Context& context() { return context_; }
    cl::CommandQueue& queue() { return queue_; }
    bool is_cpu() const { return info_.type == "cpu"; }

    // Builds (or returns the cached) program from embedded sources; BuildError on failure.
    cl::Program program(const std::string& name, const std::vector<std::string>& sources,
                        const std::string& options);

  private:
    DeviceInfo info_;
    cl::Context context_;
    cl::CommandQueue queue_;
    std::map<std::tuple<std::string, std::string>, cl::Program> programs_;
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

}  // namespace voxfield::ocl
