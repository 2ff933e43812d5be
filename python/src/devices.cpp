// The process's OpenCL devices (DESIGN §4): one context per device, made on first use and kept
// for the life of the process; a device request is resolved (platforms enumerated) once.
#include <cstdlib>
#include <map>

#include "common.hpp"

namespace voxfield::python {

namespace {

// Deliberately never destroyed: static destructors run after the interpreter is gone, when an
// OpenCL driver may already be unloaded, and a Field may still hold a device at shutdown.
struct Cache {
    std::map<std::size_t, std::shared_ptr<Device>> by_index;
    // The effective request ("" for the default, "cpu", "gpu", "3") -> the device it chose.
    std::map<std::string, std::shared_ptr<Device>> by_request;
};

Cache& cache() {
    static auto* c = new Cache();
    return *c;
}

}  // namespace

std::shared_ptr<Device> device_for(const py::object& device) {
    std::string spec;
    if (py::isinstance<py::bool_>(device)) {
        throw py::type_error("device must be None, 'cpu', 'gpu' or an index, not a bool");
    }
    if (PyIndex_Check(device.ptr()) != 0) {  // int, numpy integers
        spec = py::str(py::int_(device)).cast<std::string>();
        if (spec.front() == '-') {
            throw py::value_error("device index " + spec +
                                  " is negative: use an index from voxfield.devices()");
        }
    } else if (py::isinstance<py::str>(device)) {
        spec = device.cast<std::string>();
    } else if (!device.is_none()) {
        throw py::type_error(
            "device must be None, 'cpu', 'gpu' or an index from "
            "voxfield.devices(), not " +
            device.get_type().attr("__name__").cast<std::string>());
    }
    if (spec.empty()) {
        // The default follows $VOXFIELD_DEVICE as it is at each call (a Dask worker may set
        // it after import); select_device reads it again on a cache miss.
        if (const char* env = std::getenv("VOXFIELD_DEVICE"); env != nullptr && *env != '\0') {
            spec = env;
        }
    }
    Cache& c = cache();
    if (auto it = c.by_request.find(spec); it != c.by_request.end()) {
        return it->second;
    }
    ocl::DeviceInfo info = ocl::select_device(spec);
    auto it = c.by_index.find(info.index);
    if (it == c.by_index.end()) {
        const std::size_t index = info.index;
        it = c.by_index.emplace(index, std::make_shared<Device>(std::move(info))).first;
    }
    c.by_request.emplace(spec, it->second);
    return it->second;
}

namespace {

py::dict device_dict(const ocl::DeviceInfo& d) {
    py::dict out;
    out["index"] = d.index;
    out["name"] = d.name;
    out["vendor"] = d.vendor;
    out["platform"] = d.platform;
    out["type"] = d.type;
    out["version"] = d.version;
    out["driver"] = d.driver;
    out["compute_units"] = d.compute_units;
    out["global_mem_bytes"] = d.global_mem;
    out["max_alloc_bytes"] = d.max_alloc;
    out["local_mem_bytes"] = d.local_mem;
    out["max_work_group_size"] = d.max_work_group;
    out["available"] = d.available;
    out["compiler_available"] = d.compiler_available;
    out["extensions"] = d.extensions;
    return out;
}

}  // namespace

py::list devices() {
    py::list out;
    for (const ocl::DeviceInfo& d : ocl::list_devices()) {
        out.append(device_dict(d));
    }
    return out;
}

}  // namespace voxfield::python
