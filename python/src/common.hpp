#pragma once
// What the files of the `voxfield._core` extension share (DESIGN §4): the per-process device
// cache, array checks and conversions, and the options every front end parses the same way.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/runtime.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/metric.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield::python {

namespace py = pybind11;

// One OpenCL device with its context (queue and program cache), shared by every call and
// Field on that device for the life of the process, so kernels are built once. The mutex
// serialises the device work of threads that released the GIL: a context's queue and program
// cache are not thread-safe.
struct Device {
    explicit Device(ocl::DeviceInfo info) : context(std::move(info)) {}
    std::mutex mutex;
    ocl::Context context;
};

// device: None ($VOXFIELD_DEVICE as it is now, else the first GPU, else the first CPU),
// "cpu", "gpu", or an index (int or decimal string). Platforms are enumerated once per
// distinct request; later calls find the device in the cache. Call with the GIL held (it
// guards the cache).
std::shared_ptr<Device> device_for(const py::object& device);
py::list devices();

// "(2, 3, 4)" / "(5,)".
std::string shape_text(const py::array& a);
// A dtype's kind and item size and an array's byte count, asked of Python: NumPy 2 moved the
// descriptor's fields, and pybind11 2.10 (Debian 12) reads them directly.
char kind_of(const py::dtype& dt);
std::size_t itemsize_of(const py::dtype& dt);
std::string dtype_name(const py::dtype& dt);

// MemoryError with the numbers unless `bytes` more bytes of host memory (for `what`) can be
// had: more than the machine has in all is refused before anything is allocated.
void check_host_bytes(std::size_t bytes, const std::string& what);
// MemoryError with the numbers unless the device can hold one buffer of `bytes` and
// `total` bytes in all.
void check_device_bytes(const Device& device, std::size_t bytes, std::size_t total,
                        const std::string& what);

// A world array checked (3-D, bool or any integer dtype: a label volume, nonzero = solid) and
// made C-contiguous in native byte order (a copy only when it was not), holding a reference so
// that `data` stays valid while the GIL is released. `allow_empty`: a zero-size array passes.
struct WorldArray {
    py::array array;
    NpyType type = NpyType::u8;
    Dims dims;
    std::size_t count = 0;  // voxels (0 for an empty array)
    const std::uint8_t* data = nullptr;
    std::size_t bytes = 0;
    // uint8 or bool: the kernels read the array itself.
    bool bytes_are_voxels() const { return type == NpyType::u8 || type == NpyType::b1; }
};
WorldArray world_array(const py::object& object, bool allow_empty = false);

// The World of a checked array: one memcpy for uint8/bool, label conversion otherwise
// (InputError naming the first voxel outside 0..255 when `labels` is palette). Needs no GIL.
World make_world(const WorldArray& w, Labels labels);

py::dtype dtype_of(Format f);
// An uninitialised (Z, Y, X) field array of format f over memory numpy owns.
py::array empty_field(Dims d, Format f);
// The same over ocl::HostMemory (aligned, huge-page advised, so that a CPU device writes it
// in place), freed with the array; `data` is set to its memory.
py::array host_field(Dims d, Format f, std::uint8_t*& data);
// The caller's output array `out` checked as a (Z, Y, X) field of format f: C-contiguous,
// writable, aligned, of the format's dtype (ValueError naming what differs).
py::array caller_field(const py::object& out, Dims d, Format f);
// Blocking read of a device buffer into host memory.
void read_into(Device& device, const cl::Buffer& buffer, void* out, std::size_t bytes, Dims dims);

// sampling in array order (z, y, x), as SciPy takes it: None, one number, or 3 numbers, each
// positive and finite; a string is refused. Returned in world order (x, y, z).
Spacing spacing_of(const py::object& sampling);
// max_distance: None (unbounded) or a number (TypeError otherwise).
std::optional<double> bound_of(const py::object& max_distance);
Format format_of(const std::optional<std::string>& format, Metric metric, const Spacing& spacing,
                 bool signed_field);
// resolve_options with its messages in Python's names (max_distance, return_indices,
// sampling) instead of the command line's flags.
ocl::GeneratorOptions resolve_python_options(const ocl::GeneratorOptions& options, Dims dims,
                                             bool field);

}  // namespace voxfield::python
