// Array checks and conversions of the `voxfield._core` extension: worlds (label volumes),
// field arrays, sampling, bounds, formats and the size checks made before any allocation.
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>

#include "common.hpp"
#include "voxfield/core/error.hpp"

namespace voxfield::python {

std::string shape_text(const py::array& a) {
    std::string s = "(";
    for (py::ssize_t i = 0; i < a.ndim(); ++i) {
        s += (i == 0 ? "" : ", ") + std::to_string(a.shape(i));
    }
    return s + (a.ndim() == 1 ? ",)" : ")");
}

char kind_of(const py::dtype& dt) {
    return dt.attr("kind").cast<std::string>().at(0);
}

std::size_t itemsize_of(const py::dtype& dt) {
    return dt.attr("itemsize").cast<std::size_t>();
}

std::string dtype_name(const py::dtype& dt) {
    return dt.attr("name").cast<std::string>();
}

namespace {

std::string gib(std::size_t bytes) {
    std::ostringstream s;
    s.precision(3);
    s << static_cast<double>(bytes) / (1024.0 * 1024.0 * 1024.0) << " GiB";
    return s.str();
}

[[noreturn]] void memory_error(const std::string& text) {
    PyErr_SetString(PyExc_MemoryError, text.c_str());
    throw py::error_already_set();
}

std::size_t host_memory_bytes() {
    const long pages = sysconf(_SC_PHYS_PAGES);
    const long page = sysconf(_SC_PAGE_SIZE);
    if (pages <= 0 || page <= 0) {
        return std::numeric_limits<std::size_t>::max();
    }
    return static_cast<std::size_t>(pages) * static_cast<std::size_t>(page);
}

py::module_ numpy() {
    return py::module_::import("numpy");
}

// The NpyType of a bool or integer dtype (native order assumed by the caller).
std::optional<NpyType> label_type(char kind, std::size_t size) {
    if (kind == 'b' && size == 1) {
        return NpyType::b1;
    }
    if (kind == 'u') {
        switch (size) {
            case 1:
                return NpyType::u8;
            case 2:
                return NpyType::u16;
            case 4:
                return NpyType::u32;
            case 8:
                return NpyType::u64;
            default:
                break;
        }
    }
    if (kind == 'i') {
        switch (size) {
            case 1:
                return NpyType::i8;
            case 2:
                return NpyType::i16;
            case 4:
                return NpyType::i32;
            case 8:
                return NpyType::i64;
            default:
                break;
        }
    }
    return std::nullopt;
}

}  // namespace

void check_host_bytes(std::size_t bytes, const std::string& what) {
    const std::size_t have = host_memory_bytes();
    if (bytes > have) {
        memory_error(what + " needs " + std::to_string(bytes) + " bytes (" + gib(bytes) +
                     "), more than this machine's " + std::to_string(have) + " bytes (" +
                     gib(have) + ") of memory");
    }
}

void check_device_bytes(const Device& device, std::size_t bytes, std::size_t total,
                        const std::string& what) {
    const ocl::DeviceInfo& d = device.context.info();
    if (bytes > d.max_alloc) {
        memory_error(what + " needs a device buffer of " + std::to_string(bytes) + " bytes (" +
                     gib(bytes) + "), more than " + d.name + " allocates at once (" +
                     std::to_string(d.max_alloc) + " bytes, " + gib(d.max_alloc) + ")");
    }
    if (total > d.global_mem) {
        memory_error(what + " needs " + std::to_string(total) + " bytes (" + gib(total) +
                     ") of device memory, more than " + d.name + " has (" +
                     std::to_string(d.global_mem) + " bytes, " + gib(d.global_mem) + ")");
    }
}

WorldArray world_array(const py::object& object, bool allow_empty) {
    if (object.is_none()) {
        throw py::type_error("world must be a 3-D array (Z, Y, X), not NoneType");
    }
    // numpy.asarray (not py::array::ensure, which clears numpy's MemoryError and leaves
    // pybind11's internal error instead) so that numpy's own exceptions reach the caller.
    py::array input = numpy().attr("asarray")(object);
    if (input.ndim() != 3) {
        throw py::value_error("world must be a 3-D array of shape (Z, Y, X), got shape " +
                              shape_text(input));
    }
    std::size_t count = 1;
    for (py::ssize_t i = 0; i < 3; ++i) {
        const auto n = static_cast<unsigned long long>(input.shape(i));
        if (n == 0 && !allow_empty) {
            throw py::value_error("world has an empty axis: shape " + shape_text(input));
        }
        if (n > std::numeric_limits<std::uint32_t>::max()) {
            throw py::value_error("world axis of " + std::to_string(n) +
                                  " voxels is longer than 2^32-1");
        }
        count *= static_cast<std::size_t>(n);
    }
    py::dtype dt = input.dtype();
    const char kind = kind_of(dt);
    const std::size_t size = itemsize_of(dt);
    const std::optional<NpyType> type = label_type(kind, size);
    if (!type) {
        throw py::type_error("world dtype " + dtype_name(dt) +
                             " is not supported: expected bool or an integer type (a label "
                             "volume: 0 = empty, nonzero = solid)");
    }
    WorldArray w;
    w.type = *type;
    w.count = count;
    w.dims = {static_cast<std::uint32_t>(input.shape(2)),
              static_cast<std::uint32_t>(input.shape(1)),
              static_cast<std::uint32_t>(input.shape(0))};
    const bool native = dt.attr("isnative").cast<bool>();
    const bool contiguous = (input.flags() & py::array::c_style) != 0;
    if (!native || !contiguous) {
        // The voxel count times the element size fits size_t: each axis is below 2^32 and a
        // view this large has a zero stride somewhere, so check before numpy copies it.
        if (count != 0 && size > std::numeric_limits<std::size_t>::max() / count) {
            memory_error("a C-contiguous copy of the world of shape " + shape_text(input) +
                         " would exceed the address space");
        }
        check_host_bytes(count * size,
                         "a C-contiguous copy of the world of shape " + shape_text(input));
        const py::object native_type = dt.attr("newbyteorder")("=");
        input = numpy().attr("ascontiguousarray")(input, native_type);
    }
    w.array = input;
    w.data = static_cast<const std::uint8_t*>(w.array.data());
    w.bytes = count * size;
    return w;
}

World make_world(const WorldArray& w, Labels labels) {
    if (w.bytes_are_voxels()) {
        // bool's bytes are 0 and 1: palette index 1.
        return World(w.dims, std::vector<std::uint8_t>(w.data, w.data + w.bytes));
    }
    return world_from_labels(w.type, w.dims, {w.data, w.bytes}, labels);
}

py::dtype dtype_of(Format f) {
    switch (f) {
        case Format::u8:
            return py::dtype::of<std::uint8_t>();
        case Format::u16:
            return py::dtype::of<std::uint16_t>();
        case Format::u32:
        case Format::packed32:
            return py::dtype::of<std::uint32_t>();
        case Format::i8:
            return py::dtype::of<std::int8_t>();
        case Format::i16:
            return py::dtype::of<std::int16_t>();
        case Format::i32:
            return py::dtype::of<std::int32_t>();
        case Format::f32:
            return py::dtype::of<float>();
        case Format::f64:
            return py::dtype::of<double>();
    }
    throw std::invalid_argument("unknown Format value");
}

namespace {

// C-order strides of a (Z, Y, X) array of format f, given explicitly: pybind11 2.10 would
// take the element size from the dtype's fields, which NumPy 2 moved.
std::vector<py::ssize_t> field_strides(Dims d, Format f) {
    const auto e = static_cast<py::ssize_t>(element_size(f));
    return {e * d.y * d.x, e * d.x, e};
}

}  // namespace

py::array empty_field(Dims d, Format f) {
    check_host_bytes(d.count() * element_size(f), "a field of " + d.to_string());
    return py::array(dtype_of(f), std::vector<py::ssize_t>{d.z, d.y, d.x}, field_strides(d, f));
}

py::array host_field(Dims d, Format f, std::uint8_t*& data) {
    check_host_bytes(d.count() * element_size(f), "a field of " + d.to_string());
    auto memory = std::make_unique<ocl::HostMemory>(d.count() * element_size(f));
    data = memory->data();
    py::capsule owner(memory.release(), [](void* p) { delete static_cast<ocl::HostMemory*>(p); });
    return py::array(dtype_of(f), std::vector<py::ssize_t>{d.z, d.y, d.x}, field_strides(d, f),
                     data, owner);
}

py::array caller_field(const py::object& out, Dims d, Format f) {
    if (!py::isinstance<py::array>(out)) {
        throw py::type_error("out must be a numpy array");
    }
    py::array a = py::reinterpret_borrow<py::array>(out);
    const std::vector<py::ssize_t> want{d.z, d.y, d.x};
    if (!a.dtype().is(dtype_of(f)) && !a.dtype().equal(dtype_of(f))) {
        throw py::value_error("out must be of dtype " + dtype_name(dtype_of(f)) + ", not " +
                              dtype_name(a.dtype()));
    }
    if (std::vector<py::ssize_t>(a.shape(), a.shape() + a.ndim()) != want) {
        throw py::value_error("out must have the field's shape (" + std::to_string(d.z) + ", " +
                              std::to_string(d.y) + ", " + std::to_string(d.x) + "), not " +
                              shape_text(a));
    }
    if (!(a.flags() & py::array::c_style) || !a.writeable() ||
        !(a.flags() & py::detail::npy_api::NPY_ARRAY_ALIGNED_)) {
        throw py::value_error("out must be a writable, aligned, C-contiguous array");
    }
    return a;
}

void read_into(Device& device, const cl::Buffer& buffer, void* out, std::size_t bytes, Dims dims) {
    ocl::cl_call("reading the field of " + dims.to_string(),
                 [&] { device.context.queue().enqueueReadBuffer(buffer, CL_TRUE, 0, bytes, out); });
}

Spacing spacing_of(const py::object& sampling) {
    if (sampling.is_none()) {
        return {};
    }
    // A string is a sequence of characters: numpy would read '123' as the number 123.
    if (py::isinstance<py::str>(sampling) || py::isinstance<py::bytes>(sampling)) {
        throw py::type_error(
            "sampling must be a number or a sequence of 3 numbers (z, y, x), not a string");
    }
    py::array values;
    try {
        values = numpy().attr("asarray")(sampling, "float64");
    } catch (py::error_already_set& e) {
        if (!e.matches(PyExc_TypeError) && !e.matches(PyExc_ValueError)) {
            throw;
        }
        throw py::type_error(
            "sampling must be a number or a sequence of 3 numbers (z, y, x), not " +
            sampling.get_type().attr("__name__").cast<std::string>());
    }
    if (values.ndim() > 1 || (values.ndim() == 1 && values.size() != 3)) {
        throw py::value_error("sampling must be one number or 3 numbers (z, y, x), got shape " +
                              shape_text(values));
    }
    const bool one = values.ndim() == 0;
    // ascontiguousarray makes a 0-d array 1-d: one value then.
    values = numpy().attr("ascontiguousarray")(values);
    const auto* v = static_cast<const double*>(values.data());
    double zyx[3];
    for (int i = 0; i < 3; ++i) {
        zyx[i] = v[one ? 0 : i];
        if (!std::isfinite(zyx[i]) || zyx[i] <= 0) {
            std::ostringstream text;
            text << zyx[i];
            throw py::value_error("sampling: every value must be positive and finite, got " +
                                  text.str());
        }
        if (zyx[i] > static_cast<double>(std::numeric_limits<float>::max())) {
            std::ostringstream text;
            text << zyx[i];
            throw py::value_error("sampling value " + text.str() +
                                  " is beyond float32's range (the kernels compute in float32 "
                                  "with spacing)");
        }
    }
    return {zyx[2], zyx[1], zyx[0]};
}

std::optional<double> bound_of(const py::object& max_distance) {
    if (max_distance.is_none()) {
        return std::nullopt;
    }
    if (py::isinstance<py::str>(max_distance) || py::isinstance<py::bytes>(max_distance)) {
        throw py::type_error("max_distance must be None or a number, not a string");
    }
    return py::float_(max_distance).cast<double>();  // TypeError for anything else
}

Format format_of(const std::optional<std::string>& format, Metric metric, const Spacing& spacing,
                 bool signed_field) {
    return format ? parse_format(*format) : ocl::default_format(metric, spacing, signed_field);
}

ocl::GeneratorOptions resolve_python_options(const ocl::GeneratorOptions& o, Dims dims,
                                             bool field) {
    const std::string algorithm = "algorithm='" + ocl::to_string(o.algorithm) + "'";
    if (o.algorithm != ocl::Algorithm::exact) {
        if (o.metric != Metric::manhattan) {
            throw InputError("metric='" + to_string(o.metric) + "': " + algorithm +
                             " (the dissertation's) computes manhattan distances only; use "
                             "algorithm='exact'");
        }
        if (!o.spacing.unit()) {
            throw InputError("sampling: " + algorithm +
                             " works on unit sampling only; use algorithm='exact'");
        }
        if (o.signed_field) {
            throw InputError("signed=True: " + algorithm +
                             " has no signed fields; use algorithm='exact'");
        }
        if (o.indices) {
            throw InputError("return_indices=True: " + algorithm +
                             " has no feature transform; use algorithm='exact'");
        }
        if (holds_sign(o.format)) {
            throw InputError("format='" + to_string(o.format) + "': " + algorithm +
                             " writes u8, u16, u32 or packed32 only");
        }
        if (field && !ocl::always_chunked(o.algorithm)) {
            throw InputError(algorithm +
                             ": a Field keeps the global field up to date with 'exact' or a "
                             "chunk-local one with 'brute-chunked', 'lod' or 'monolithic'");
        }
    }
    if (o.max_distance && !(std::isfinite(*o.max_distance) && *o.max_distance > 0)) {
        std::ostringstream text;
        text << *o.max_distance;
        throw InputError("max_distance must be a positive number, not " + text.str());
    }
    if (o.max_distance && o.algorithm != ocl::Algorithm::exact) {
        throw InputError("max_distance: " + algorithm +
                         " has no bounded fields; use algorithm='exact'");
    }
    if (o.signed_field && !holds_sign(o.format)) {
        throw InputError(
            "signed=True needs a signed format (i8, i16, i32, f32 or f64), not "
            "format='" +
            to_string(o.format) + "'");
    }
    if (o.signed_field && o.indices) {
        throw InputError(
            "return_indices=True needs an unsigned field: the feature transform names the "
            "nearest solid voxel, which a signed field's solid voxels do not have; pass "
            "signed=False or return_indices=False");
    }
    return ocl::resolve_options(o, dims);
}

}  // namespace voxfield::python
