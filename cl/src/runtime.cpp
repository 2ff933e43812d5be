#include "voxfield/cl/runtime.hpp"

#include <sys/mman.h>

#include <algorithm>
#include <cstdlib>
#include <new>
#include <sstream>
#include <utility>

namespace voxfield::ocl {
namespace {

std::string with_context(const std::string& call, cl_int code, const std::string& context) {
    std::string msg = call + " failed with " + error_name(code);
    if (!context.empty()) {
        msg += " (" + context + ")";
    }
    return msg;
}

std::string type_name(cl_device_type t) {
    if (t & CL_DEVICE_TYPE_GPU) {
        return "gpu";
    }
    if (t & CL_DEVICE_TYPE_CPU) {
        return "cpu";
    }
    if (t & CL_DEVICE_TYPE_ACCELERATOR) {
        return "accelerator";
    }
    return "other";
}

std::string trim(std::string s) {
    while (!s.empty() && (s.back() == '\0' || s.back() == ' ')) {
        s.pop_back();
    }
    return s;
}

std::string describe(const DeviceInfo& d) {
    return "#" + std::to_string(d.index) + " " + d.name + " (" + d.platform + ", " + d.type + ")";
}

// Why `d` cannot serve any request, or "" if it can.
std::string unusable(const DeviceInfo& d) {
    if (!d.available) {
        return "device reports it is not available";
    }
    if (!d.compiler_available) {
        return "device has no OpenCL C compiler";
    }
    return "";
}

}  // namespace

ClError::ClError(const std::string& call, cl_int code, const std::string& context)
    : std::runtime_error(with_context(call, code, context)), code_(code) {}

const char* error_name(cl_int code) {
    switch (code) {
#define VF_CASE(c) \
    case c:        \
        return #c;
        VF_CASE(CL_SUCCESS)
        VF_CASE(CL_DEVICE_NOT_FOUND)
        VF_CASE(CL_DEVICE_NOT_AVAILABLE)
        VF_CASE(CL_COMPILER_NOT_AVAILABLE)
        VF_CASE(CL_MEM_OBJECT_ALLOCATION_FAILURE)
        VF_CASE(CL_OUT_OF_RESOURCES)
        VF_CASE(CL_OUT_OF_HOST_MEMORY)
        VF_CASE(CL_PROFILING_INFO_NOT_AVAILABLE)
        VF_CASE(CL_MEM_COPY_OVERLAP)
        VF_CASE(CL_BUILD_PROGRAM_FAILURE)
        VF_CASE(CL_MAP_FAILURE)
        VF_CASE(CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST)
        VF_CASE(CL_COMPILE_PROGRAM_FAILURE)
        VF_CASE(CL_LINK_PROGRAM_FAILURE)
        VF_CASE(CL_INVALID_VALUE)
        VF_CASE(CL_INVALID_DEVICE_TYPE)
        VF_CASE(CL_INVALID_PLATFORM)
        VF_CASE(CL_INVALID_DEVICE)
        VF_CASE(CL_INVALID_CONTEXT)
        VF_CASE(CL_INVALID_QUEUE_PROPERTIES)
        VF_CASE(CL_INVALID_COMMAND_QUEUE)
        VF_CASE(CL_INVALID_HOST_PTR)
        VF_CASE(CL_INVALID_MEM_OBJECT)
        VF_CASE(CL_INVALID_BUILD_OPTIONS)
        VF_CASE(CL_INVALID_PROGRAM)
        VF_CASE(CL_INVALID_PROGRAM_EXECUTABLE)
        VF_CASE(CL_INVALID_KERNEL_NAME)
        VF_CASE(CL_INVALID_KERNEL)
        VF_CASE(CL_INVALID_ARG_INDEX)
        VF_CASE(CL_INVALID_ARG_VALUE)
        VF_CASE(CL_INVALID_ARG_SIZE)
        VF_CASE(CL_INVALID_KERNEL_ARGS)
        VF_CASE(CL_INVALID_WORK_DIMENSION)
        VF_CASE(CL_INVALID_WORK_GROUP_SIZE)
        VF_CASE(CL_INVALID_WORK_ITEM_SIZE)
        VF_CASE(CL_INVALID_GLOBAL_OFFSET)
        VF_CASE(CL_INVALID_EVENT_WAIT_LIST)
        VF_CASE(CL_INVALID_EVENT)
        VF_CASE(CL_INVALID_OPERATION)
        VF_CASE(CL_INVALID_BUFFER_SIZE)
        VF_CASE(CL_INVALID_GLOBAL_WORK_SIZE)
        VF_CASE(CL_INVALID_PROPERTY)
        VF_CASE(CL_PLATFORM_NOT_FOUND_KHR)
#undef VF_CASE
        default:
            return "CL_UNKNOWN_ERROR";
    }
}

bool DeviceInfo::has_extension(const std::string& ext) const {
    return std::find(extensions.begin(), extensions.end(), ext) != extensions.end();
}

std::vector<DeviceInfo> list_devices() {
    std::vector<cl::Platform> platforms;
    try {
        cl::Platform::get(&platforms);
    } catch (const cl::Error& e) {
        if (e.err() == CL_PLATFORM_NOT_FOUND_KHR) {
            return {};
        }
        throw ClError(e.what(), e.err(), "listing OpenCL platforms");
    }
    std::vector<DeviceInfo> out;
    for (auto& platform : platforms) {
        std::vector<cl::Device> devices;
        try {
            platform.getDevices(CL_DEVICE_TYPE_ALL, &devices);
        } catch (const cl::Error& e) {
            if (e.err() == CL_DEVICE_NOT_FOUND) {
                continue;
            }
            throw ClError(e.what(), e.err(), "listing devices");
        }
        for (auto& dev : devices) {
            cl_call("querying device info", [&] {
                DeviceInfo d;
                d.index = out.size();
                d.device = dev;
                d.name = trim(dev.getInfo<CL_DEVICE_NAME>());
                d.vendor = trim(dev.getInfo<CL_DEVICE_VENDOR>());
                d.platform = trim(platform.getInfo<CL_PLATFORM_NAME>());
                d.version = trim(dev.getInfo<CL_DEVICE_VERSION>());
                d.driver = trim(dev.getInfo<CL_DRIVER_VERSION>());
                d.type = type_name(dev.getInfo<CL_DEVICE_TYPE>());
                d.compute_units = dev.getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>();
                d.global_mem = dev.getInfo<CL_DEVICE_GLOBAL_MEM_SIZE>();
                d.max_alloc = dev.getInfo<CL_DEVICE_MAX_MEM_ALLOC_SIZE>();
                d.local_mem = dev.getInfo<CL_DEVICE_LOCAL_MEM_SIZE>();
                d.max_work_group = dev.getInfo<CL_DEVICE_MAX_WORK_GROUP_SIZE>();
                d.available = dev.getInfo<CL_DEVICE_AVAILABLE>() != CL_FALSE;
                d.compiler_available = dev.getInfo<CL_DEVICE_COMPILER_AVAILABLE>() != CL_FALSE;
                d.host_unified_memory = dev.getInfo<CL_DEVICE_HOST_UNIFIED_MEMORY>() != CL_FALSE;
                std::istringstream ext(dev.getInfo<CL_DEVICE_EXTENSIONS>());
                for (std::string e; ext >> e;) {
                    d.extensions.push_back(e);
                }
                out.push_back(std::move(d));
            });
        }
    }
    return out;
}

DeviceInfo select_device(const std::string& requested) {
    std::string spec = requested;
    std::string origin = "--device";
    if (spec.empty()) {
        if (const char* env = std::getenv("VOXFIELD_DEVICE"); env != nullptr && *env != '\0') {
            spec = env;
            origin = "VOXFIELD_DEVICE";
        }
    }
    const bool is_index = !spec.empty() && std::all_of(spec.begin(), spec.end(),
                                                       [](char c) { return c >= '0' && c <= '9'; });
    if (!spec.empty() && spec != "cpu" && spec != "gpu" && !is_index) {
        throw DeviceSelectionError(origin + " '" + spec +
                                   "' is not a device: use cpu, gpu or an index from "
                                   "`voxfield devices`");
    }
    const auto devices = list_devices();
    if (devices.empty()) {
        throw DeviceSelectionError(
            "no OpenCL device found: no platform is installed (install an ICD such as "
            "pocl-opencl-icd; see /etc/OpenCL/vendors)");
    }
    std::string reasons;
    auto consider = [&](const std::string& want_type, bool by_index,
                        std::size_t index) -> const DeviceInfo* {
        for (const auto& d : devices) {
            std::string why;
            if (by_index && d.index != index) {
                why = "not index " + std::to_string(index);
            } else if (!want_type.empty() && d.type != want_type) {
                why = "is a " + d.type + ", not a " + want_type;
            } else {
                why = unusable(d);
            }
            if (why.empty()) {
                return &d;
            }
            reasons += (reasons.empty() ? "" : "; ") + describe(d) + ": " + why;
        }
        return nullptr;
    };
    const DeviceInfo* found = nullptr;
    std::string wanted;
    if (spec.empty()) {
        wanted = "the default (first GPU, else first CPU)";
        found = consider("gpu", false, 0);
        if (found == nullptr) {
            reasons.clear();
            found = consider("cpu", false, 0);
        }
        if (found == nullptr) {
            reasons.clear();
            found = consider("", false, 0);
        }
    } else if (is_index) {
        wanted = origin + " " + spec;
        // Compared as text, never converted: an index beyond the integers (18446744073709551616)
        // must not wrap around to a device.
        const std::string trimmed = spec.find_first_not_of('0') == std::string::npos
                                        ? "0"
                                        : spec.substr(spec.find_first_not_of('0'));
        std::size_t index = devices.size();
        for (const auto& d : devices) {
            if (std::to_string(d.index) == trimmed) {
                index = d.index;
            }
        }
        if (index == devices.size()) {
            for (const auto& d : devices) {
                reasons += (reasons.empty() ? "" : "; ") + describe(d) + ": not index " + trimmed;
            }
            throw DeviceSelectionError(
                "no OpenCL device matches " + wanted + ": the indices are 0.." +
                std::to_string(devices.size() - 1) + " (" + reasons + "; see `voxfield devices`)");
        }
        found = consider("", true, index);
    } else {
        wanted = origin + " " + spec;
        found = consider(spec, false, 0);
    }
    if (found == nullptr) {
        throw DeviceSelectionError("no OpenCL device matches " + wanted + " (" + reasons + ")");
    }
    return *found;
}

Context::Context(DeviceInfo device) : info_(std::move(device)) {
    cl_call("creating a context on " + info_.name, [&] {
        context_ = cl::Context(info_.device);
        queue_ = cl::CommandQueue(context_, info_.device, CL_QUEUE_PROFILING_ENABLE);
    });
}

cl::Program Context::program(const std::string& name, const std::vector<std::string>& sources,
                             const std::string& options) {
    auto key = std::make_tuple(name, options, sources);
    if (auto it = programs_.find(key); it != programs_.end()) {
        return it->second;
    }
    cl::Program program = cl_call("creating program " + name, [&] {
        return cl::Program(context_, cl::Program::Sources(sources.begin(), sources.end()));
    });
    try {
        program.build({info_.device}, options.c_str());
    } catch (const cl::Error& e) {
        std::string log;
        try {
            log = program.getBuildInfo<CL_PROGRAM_BUILD_LOG>(info_.device);
        } catch (const cl::Error&) {
            log = "(no build log available)";
        }
        throw BuildError("building kernel program " + name + " with options '" + options +
                         "' failed on " + info_.name + " (" + info_.platform +
                         "): " + error_name(e.err()) + "\nbuild log:\n" + log);
    }
    programs_.emplace(std::move(key), program);
    return program;
}

double elapsed_ms(const cl::Event& first, const cl::Event& last) {
    return cl_call("reading profiling info", [&] {
        const auto start = first.getProfilingInfo<CL_PROFILING_COMMAND_START>();
        const auto end = last.getProfilingInfo<CL_PROFILING_COMMAND_END>();
        return static_cast<double>(end - start) * 1e-6;
    });
}

HostMemory::HostMemory(std::size_t bytes) : size_(bytes) {
    constexpr std::size_t huge = std::size_t{2} << 20;
    const std::size_t align = bytes >= huge ? huge : 4096;
    void* p = nullptr;
    if (posix_memalign(&p, align, std::max<std::size_t>(bytes, 1)) != 0) {
        throw std::bad_alloc();
    }
    data_.reset(static_cast<std::uint8_t*>(p));
    if (bytes >= huge) {
        // Advice only: where transparent huge pages are off the memory works in small pages.
        ::madvise(p, bytes, MADV_HUGEPAGE);
    }
}

MappedBuffer::MappedBuffer(Context& ctx, const cl::Buffer& buffer, std::size_t bytes)
    : queue_(ctx.queue()), buffer_(buffer), size_(bytes) {
    cl_call("mapping " + std::to_string(bytes) + " bytes for reading on the host", [&] {
        cl::Event ev;
        data_ = static_cast<const std::uint8_t*>(
            queue_.enqueueMapBuffer(buffer_, CL_TRUE, CL_MAP_READ, 0, bytes, nullptr, &ev));
        map_ms_ = elapsed_ms(ev, ev);
    });
}

MappedBuffer::~MappedBuffer() {
    // A failing unmap has no one left to report to; the buffer is released either way.
    try {
        queue_.enqueueUnmapMemObject(buffer_, const_cast<std::uint8_t*>(data_));
        queue_.finish();
    } catch (const cl::Error&) {
    }
}

}  // namespace voxfield::ocl
