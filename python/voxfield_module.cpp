// The Python module `voxfield` (DESIGN §4): numpy arrays of shape (Z, Y, X) in, numpy arrays
// out, with the command line's semantics, messages and device rule.
//
// Copies: a C-contiguous uint8 (or bool) world is copied once, by one memcpy, into the World
// the library uploads (World owns its voxels); other layouts are made C-contiguous by numpy
// first, and uint16/uint32 worlds are checked and narrowed voxel by voxel. Fields are read from
// the device buffer straight into the memory of the numpy array that is returned (no host
// copy in between); the feature transform goes through one host copy (Generator only hands
// it out as a vector).
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "voxfield/cl/exact.hpp"
#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/incremental.hpp"
#include "voxfield/cl/runtime.hpp"
#include "voxfield/cl/separable.hpp"
#include "voxfield/core/brush.hpp"
#include "voxfield/core/edits.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/vox.hpp"

namespace py = pybind11;

namespace voxfield::python {
namespace {

// One OpenCL device with its context (queue and program cache), shared by every call and
// Field on that device, so repeated calls reuse the built kernels. The mutex serialises the
// device work of threads that released the GIL: a context's program cache is not thread-safe.
struct Device {
    explicit Device(ocl::DeviceInfo info) : context(std::move(info)) {}
    std::mutex mutex;
    ocl::Context context;
};

// Keyed by the index `voxfield devices` shows. Deliberately never destroyed: static
// destructors run after the interpreter is gone, when an OpenCL driver may already be unloaded,
// and a Field may still hold a device during interpreter shutdown.
std::map<std::size_t, std::shared_ptr<Device>>& device_cache() {
    static auto* cache = new std::map<std::size_t, std::shared_ptr<Device>>();
    return *cache;
}

// device: None (the CLI's default: $VOXFIELD_DEVICE, else the first GPU, else the first CPU),
// "cpu", "gpu", or an index (int or decimal string). Called with the GIL held, which guards the
// cache.
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
    ocl::DeviceInfo info = ocl::select_device(spec);
    auto& cache = device_cache();
    auto it = cache.find(info.index);
    if (it == cache.end()) {
        const std::size_t index = info.index;
        it = cache.emplace(index, std::make_shared<Device>(std::move(info))).first;
    }
    return it->second;
}

std::string shape_text(const py::array& a) {
    std::string s = "(";
    for (py::ssize_t i = 0; i < a.ndim(); ++i) {
        s += (i == 0 ? "" : ", ") + std::to_string(a.shape(i));
    }
    return s + (a.ndim() == 1 ? ",)" : ")");
}

// A world array checked and made C-contiguous (a copy only when it was not), with the voxel
// type the library's .npy reader uses for it. Holds a reference, so `data` stays valid while
// the GIL is released.
// A dtype's kind and item size and an array's byte count, asked of Python: NumPy 2 moved
// the descriptor's fields after `kind`, and pybind11 2.10 (Debian 12) reads them directly,
// which gives wrong sizes under NumPy 2.
char kind_of(const py::dtype& dt) {
    return dt.attr("kind").cast<std::string>().at(0);
}

py::ssize_t itemsize_of(const py::dtype& dt) {
    return dt.attr("itemsize").cast<py::ssize_t>();
}

std::size_t nbytes_of(const py::array& a) {
    return a.attr("nbytes").cast<std::size_t>();
}

struct WorldArray {
    py::array array;
    NpyType type = NpyType::u8;
    Dims dims;
    const std::uint8_t* data = nullptr;
    std::size_t bytes = 0;
};

WorldArray world_array(const py::object& object) {
    const py::array input = object.is_none() ? py::reinterpret_steal<py::array>(py::handle())
                                             : py::array::ensure(object);
    if (!input) {
        throw py::type_error("world must be a 3-D array (Z, Y, X), not " +
                             object.get_type().attr("__name__").cast<std::string>());
    }
    if (input.ndim() != 3) {
        throw py::value_error("world must be a 3-D array of shape (Z, Y, X), got shape " +
                              shape_text(input));
    }
    for (py::ssize_t i = 0; i < 3; ++i) {
        if (input.shape(i) == 0) {
            throw py::value_error("world has an empty axis: shape " + shape_text(input));
        }
        if (static_cast<unsigned long long>(input.shape(i)) >
            std::numeric_limits<std::uint32_t>::max()) {
            throw py::value_error("world axis of " + std::to_string(input.shape(i)) +
                                  " voxels is longer than 2^32-1");
        }
    }
    const py::dtype dt = input.dtype();
    const char kind = kind_of(dt);
    const py::ssize_t size = itemsize_of(dt);
    WorldArray w;
    if (kind == 'b' || (kind == 'u' && size == 1)) {
        w.type = NpyType::u8;
        w.array = py::array::ensure(input, py::array::c_style);
    } else if (kind == 'u' && size == 2) {
        w.type = NpyType::u16;
        w.array =
            py::array_t<std::uint16_t, py::array::c_style | py::array::forcecast>::ensure(input);
    } else if (kind == 'u' && size == 4) {
        w.type = NpyType::u32;
        w.array =
            py::array_t<std::uint32_t, py::array::c_style | py::array::forcecast>::ensure(input);
    } else {
        throw py::type_error("world dtype " + dt.attr("name").cast<std::string>() +
                             " is not supported: expected uint8, uint16, uint32 or bool "
                             "(palette indices 0..255, 0 = empty)");
    }
    if (!w.array) {
        throw py::error_already_set();
    }
    w.dims = {static_cast<std::uint32_t>(input.shape(2)),
              static_cast<std::uint32_t>(input.shape(1)),
              static_cast<std::uint32_t>(input.shape(0))};
    w.data = static_cast<const std::uint8_t*>(w.array.data());
    w.bytes = nbytes_of(w.array);
    return w;
}

// The World of a checked array: one memcpy for uint8, the .npy reader's checked narrowing
// (InputError naming the first voxel over 255) otherwise. Needs no GIL.
World make_world(const WorldArray& w) {
    if (w.type == NpyType::u8) {
        return World(w.dims, std::vector<std::uint8_t>(w.data, w.data + w.bytes));
    }
    NpyArray a;
    a.type = w.type;
    a.dims = w.dims;
    a.data.assign(w.data, w.data + w.bytes);
    return world_from_npy(a);
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

// C-order strides of a (Z, Y, X) array of format f, given explicitly: pybind11 2.10 would take
// the element size from the dtype's fields, which NumPy 2 moved.
std::vector<py::ssize_t> field_strides(Dims d, Format f) {
    const auto e = static_cast<py::ssize_t>(element_size(f));
    return {e * d.y * d.x, e * d.x, e};
}

py::array empty_field(Dims d, Format f) {
    return py::array(dtype_of(f), std::vector<py::ssize_t>{d.z, d.y, d.x}, field_strides(d, f));
}

// Blocking read of a device field into the numpy array's own memory.
void read_into(Device& device, const cl::Buffer& buffer, void* out, std::size_t bytes, Dims dims) {
    ocl::cl_call("reading the field of " + dims.to_string(),
                 [&] { device.context.queue().enqueueReadBuffer(buffer, CL_TRUE, 0, bytes, out); });
}

// An uninitialised field array over host memory of its own (ocl::HostMemory: aligned and
// huge-page advised, so that a CPU device writes it in place), freed with the array.
py::array host_field(Dims d, Format f, std::uint8_t*& data) {
    auto memory = std::make_unique<ocl::HostMemory>(d.count() * element_size(f));
    data = memory->data();
    py::capsule owner(memory.release(), [](void* p) { delete static_cast<ocl::HostMemory*>(p); });
    return py::array(dtype_of(f), std::vector<py::ssize_t>{d.z, d.y, d.x}, field_strides(d, f),
                     data, owner);
}

// `exact` (the sweeps of exact_manhattan.cl or the separable transforms) from a C-contiguous
// uint8 world straight into `field` (host_field's memory): a CPU device reads the array and
// writes the field in place, nothing copied; elsewhere the world is uploaded and the field
// read back into `field`.
void transform_into(Device& dev, const WorldArray& w, const ocl::GeneratorOptions& o,
                    std::uint8_t* field, std::size_t bytes) {
    auto& ctx = dev.context;
    const std::span<const std::uint8_t> voxels(w.data, w.bytes);
    const std::span<std::uint8_t> out(field, bytes);
    std::unique_ptr<ocl::Generator> made;
    if (ocl::ExactManhattan::handles(ctx, o)) {
        made = std::make_unique<ocl::ExactManhattan>(ctx, w.dims, voxels, Palette{}, o.format,
                                                     o.layout, o.metric, out, o.max_distance);
    } else {
        made = std::make_unique<ocl::ExactSeparable>(ctx, w.dims, voxels, Palette{}, o, out);
    }
    ocl::Generator& job = *made;
    job.run();
    if (ctx.computes_in_host_memory()) {
        // Mapping makes the kernels' writes visible to the host; in place it copies nothing.
        const ocl::MappedBuffer mapped(ctx, job.field_buffer(), bytes);
        if (mapped.bytes().data() != field) {
            std::memcpy(field, mapped.bytes().data(), bytes);
        }
    } else {
        read_into(dev, job.field_buffer(), field, bytes, w.dims);
    }
}

// sampling in array order (z, y, x), as SciPy takes it: None, one number for every axis, or
// three numbers; each positive and finite.
Spacing spacing_of(const py::object& sampling) {
    if (sampling.is_none()) {
        return {};
    }
    const auto values =
        py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(sampling);
    if (!values) {
        throw py::type_error(
            "sampling must be a number or a sequence of 3 numbers (z, y, x), not " +
            sampling.get_type().attr("__name__").cast<std::string>());
    }
    if (values.ndim() > 1 || (values.ndim() == 1 && values.size() != 3)) {
        throw py::value_error("sampling must be one number or 3 numbers (z, y, x), got shape " +
                              shape_text(values));
    }
    double zyx[3];
    for (int i = 0; i < 3; ++i) {
        zyx[i] = values.data()[values.ndim() == 0 ? 0 : i];
        if (!std::isfinite(zyx[i]) || zyx[i] <= 0) {
            std::ostringstream text;
            text << zyx[i];
            throw py::value_error("sampling: every value must be positive and finite, got " +
                                  text.str());
        }
    }
    return {zyx[2], zyx[1], zyx[0]};
}

// max_distance: None (unbounded) or a number; resolve_options checks that it is positive.
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

py::object distance_transform(const py::object& world, const std::string& metric, bool signed_field,
                              const py::object& sampling, bool return_indices,
                              const py::object& max_distance,
                              const std::optional<std::string>& format,
                              const std::string& algorithm, const py::object& device) {
    const WorldArray w = world_array(world);
    ocl::GeneratorOptions o;
    o.max_distance = bound_of(max_distance);
    o.algorithm = ocl::parse_algorithm(algorithm);
    o.metric = parse_metric(metric);
    o.spacing = spacing_of(sampling);
    o.signed_field = signed_field;
    o.indices = return_indices;
    o.format = format_of(format, o.metric, o.spacing, signed_field);
    const ocl::GeneratorOptions options = ocl::resolve_options(o, w.dims);
    const std::shared_ptr<Device> dev = device_for(device);

    // `exact` reads a uint8 array in place and writes the field into the returned array
    // (indices come back through the generator's own buffers).
    const bool sweeps =
        w.type == NpyType::u8 && options.algorithm == ocl::Algorithm::exact && !return_indices;
    std::uint8_t* sweep_out = nullptr;
    py::array field = sweeps ? host_field(w.dims, options.format, sweep_out)
                             : empty_field(w.dims, options.format);
    py::array_t<std::int32_t> indices;
    if (return_indices) {
        indices =
            py::array_t<std::int32_t>(std::vector<py::ssize_t>{3, w.dims.z, w.dims.y, w.dims.x});
    }
    void* field_out = field.mutable_data();
    std::int32_t* indices_out = return_indices ? indices.mutable_data() : nullptr;
    const std::size_t field_bytes = nbytes_of(field);
    {
        py::gil_scoped_release release;
        if (sweeps) {
            const std::lock_guard<std::mutex> lock(dev->mutex);
            transform_into(*dev, w, options, sweep_out, field_bytes);
        } else {
            const World vox = make_world(w);
            const std::lock_guard<std::mutex> lock(dev->mutex);
            const auto job = ocl::make_generator(dev->context, vox, Palette{}, options);
            job->run();
            read_into(*dev, job->field_buffer(), field_out, field_bytes, w.dims);
            if (indices_out != nullptr) {
                const std::vector<std::int32_t> idx = job->read_indices();
                std::memcpy(indices_out, idx.data(), idx.size() * sizeof(std::int32_t));
            }
        }
    }
    if (return_indices) {
        return py::make_tuple(field, indices);
    }
    return field;
}

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

py::list devices() {
    py::list out;
    for (const ocl::DeviceInfo& d : ocl::list_devices()) {
        out.append(device_dict(d));
    }
    return out;
}

py::array world_to_numpy(const World& world) {
    const Dims d = world.dims();
    py::array_t<std::uint8_t> out(std::vector<py::ssize_t>{d.z, d.y, d.x});
    std::memcpy(out.mutable_data(), world.voxels().data(), world.size());
    return out;
}

py::tuple load_vox(const std::filesystem::path& path) {
    std::optional<VoxModel> model;
    {
        py::gil_scoped_release release;
        model = read_vox(path);
    }
    py::array_t<std::uint8_t> palette(std::vector<py::ssize_t>{256, 4});
    auto p = palette.mutable_unchecked<2>();
    for (int i = 0; i < 256; ++i) {
        const Rgba& c = model->palette[static_cast<std::uint8_t>(i)];
        p(i, 0) = c.r;
        p(i, 1) = c.g;
        p(i, 2) = c.b;
        p(i, 3) = c.a;
    }
    return py::make_tuple(world_to_numpy(model->world), palette);
}

// palette: None (MagicaVoxel's default) or an integer array of shape (256, 4), values 0..255.
Palette palette_of(const py::object& palette) {
    Palette out;
    if (palette.is_none()) {
        return out;
    }
    const py::array a = py::array::ensure(palette);
    if (!a) {
        throw py::type_error("palette must be None or an array of shape (256, 4)");
    }
    if (a.ndim() != 2 || a.shape(0) != 256 || a.shape(1) != 4) {
        throw py::value_error("palette must have shape (256, 4) (RGBA per palette index), got " +
                              shape_text(a));
    }
    const char kind = kind_of(a.dtype());
    if (kind != 'u' && kind != 'i') {
        throw py::type_error("palette dtype " + a.dtype().attr("name").cast<std::string>() +
                             " is not supported: expected an integer type (uint8)");
    }
    const auto v = py::array_t<std::int64_t, py::array::forcecast>::ensure(a);
    const auto u = v.unchecked<2>();
    for (py::ssize_t i = 0; i < 256; ++i) {
        std::uint8_t rgba[4];
        for (py::ssize_t c = 0; c < 4; ++c) {
            if (u(i, c) < 0 || u(i, c) > 255) {
                throw py::value_error("palette value " + std::to_string(u(i, c)) + " at [" +
                                      std::to_string(i) + ", " + std::to_string(c) +
                                      "] is outside 0..255");
            }
            rgba[c] = static_cast<std::uint8_t>(u(i, c));
        }
        out[static_cast<std::uint8_t>(i)] = {rgba[0], rgba[1], rgba[2], rgba[3]};
    }
    return out;
}

void save_vox(const std::filesystem::path& path, const py::object& world,
              const py::object& palette) {
    const WorldArray w = world_array(world);
    const Palette colours = palette_of(palette);
    py::gil_scoped_release release;
    write_vox(path, make_world(w), colours);
}

py::dict stats_dict(const ocl::UpdateStats& s) {
    std::size_t changed = 0;
    for (const EditResult& e : s.edits) {
        changed += e.changes.size();
    }
    py::dict out;
    out["edits"] = s.edits.size();
    out["voxels_changed"] = changed;
    out["voxels_recomputed"] = s.voxels_recomputed;
    out["update_ms"] = s.update_ms;
    out["full_regeneration"] = s.full_regeneration;
    return out;
}

BrushOp parse_op(const std::string& op) {
    for (BrushOp o : {BrushOp::place, BrushOp::erase, BrushOp::paint}) {
        if (op == to_string(o)) {
            return o;
        }
    }
    throw InputError("unknown edit op '" + op + "': expected place, erase or paint");
}

BrushShape parse_shape(const std::string& shape) {
    for (BrushShape s : {BrushShape::sphere, BrushShape::cube}) {
        if (shape == to_string(s)) {
            return s;
        }
    }
    throw InputError("unknown brush shape '" + shape + "': expected sphere or cube");
}

// A world and its distance field kept on the device across edits (ocl::IncrementalField).
class Field {
  public:
    Field(const py::object& world, const std::string& metric, const py::object& device,
          const std::string& algorithm, const std::optional<std::string>& format,
          const py::object& sampling, bool signed_field, const py::object& max_distance) {
        const WorldArray w = world_array(world);
        ocl::GeneratorOptions o;
        o.max_distance = bound_of(max_distance);
        o.algorithm = ocl::parse_algorithm(algorithm);
        o.metric = parse_metric(metric);
        o.spacing = spacing_of(sampling);
        o.signed_field = signed_field;
        o.format = format_of(format, o.metric, o.spacing, signed_field);
        const ocl::GeneratorOptions options = ocl::resolve_options(o, w.dims);
        device_ = device_for(device);
        format_ = options.format;
        py::gil_scoped_release release;
        World vox = make_world(w);
        const std::lock_guard<std::mutex> lock(device_->mutex);
        field_ = std::make_unique<ocl::IncrementalField>(device_->context, std::move(vox),
                                                         Palette{}, options);
    }

    py::dict edit(const std::string& op, const std::string& shape,
                  const std::vector<std::int64_t>& center, std::int64_t radius,
                  std::int64_t material) {
        if (center.size() != 3) {
            throw py::value_error("center must be 3 integers (x, y, z) in world order, got " +
                                  std::to_string(center.size()));
        }
        if (material < 0 || material > 255) {
            throw py::value_error("material " + std::to_string(material) +
                                  " is not a palette index (expected 1..255)");
        }
        Brush b;
        b.op = parse_op(op);
        b.shape = parse_shape(shape);
        b.centre = {center[0], center[1], center[2]};
        b.radius = radius;
        b.material = static_cast<std::uint8_t>(material);
        return apply({b});
    }

    py::dict apply_edits(const std::string& text) {
        std::istringstream in(text);
        std::vector<Brush> batch;
        for (const Edit& e : parse_edits(in, "edits")) {
            batch.push_back(e.brush);
        }
        return apply(batch);
    }

    py::array distances() {
        const Dims d = field_->world().dims();
        py::array out = empty_field(d, format_);
        void* data = out.mutable_data();
        const std::size_t bytes = nbytes_of(out);
        py::gil_scoped_release release;
        const std::lock_guard<std::mutex> lock(device_->mutex);
        read_into(*device_, field_->field_buffer(), data, bytes, d);
        return out;
    }

    py::array world() {
        const Dims d = field_->world().dims();
        py::array_t<std::uint8_t> out(std::vector<py::ssize_t>{d.z, d.y, d.x});
        std::uint8_t* data = out.mutable_data();
        py::gil_scoped_release release;
        const std::lock_guard<std::mutex> lock(device_->mutex);
        std::memcpy(data, field_->world().voxels().data(), field_->world().size());
        return out;
    }

  private:
    py::dict apply(const std::vector<Brush>& batch) {
        ocl::UpdateStats stats;
        {
            py::gil_scoped_release release;
            const std::lock_guard<std::mutex> lock(device_->mutex);
            stats = field_->apply(batch);
        }
        return stats_dict(stats);
    }

    // Declared first so that the context outlives the field's buffers.
    std::shared_ptr<Device> device_;
    Format format_ = Format::u16;
    std::unique_ptr<ocl::IncrementalField> field_;
};

}  // namespace
}  // namespace voxfield::python

PYBIND11_MODULE(voxfield, m) {
    namespace vp = voxfield::python;
    namespace ocl = voxfield::ocl;
    m.doc() =
        "Exact distance fields of voxel worlds on OpenCL devices (PoCL on the CPU, GPUs).\n\n"
        "Arrays are numpy arrays of shape (Z, Y, X) in C order (x fastest), 0 = empty, 1..255 = "
        "palette index; the semantics are those of `voxfield generate` (DESIGN §3). Bad input "
        "raises TypeError or ValueError with the command line's message, device failures "
        "RuntimeError. The GIL is released while a device works.";
    m.attr("__version__") = VOXFIELD_VERSION;
    // The docstrings start with hand-written signatures that name the return values.
    py::options options;
    options.disable_function_signatures();

    py::register_exception_translator([](std::exception_ptr p) {
        try {
            if (p) {
                std::rethrow_exception(p);
            }
        } catch (const voxfield::InputError& e) {
            PyErr_SetString(PyExc_ValueError, e.what());
        } catch (const ocl::ClError& e) {
            PyErr_SetString(PyExc_RuntimeError, e.what());
        } catch (const ocl::BuildError& e) {
            PyErr_SetString(PyExc_RuntimeError, e.what());
        }
    });

    m.def("devices", &vp::devices,
          "devices() -> list of dict\n\n"
          "Every OpenCL device of every platform, as `voxfield devices --json` lists them: "
          "index (what device= takes), name, vendor, platform, type ('cpu', 'gpu', ...), "
          "version, driver, compute_units, global_mem_bytes, max_alloc_bytes, local_mem_bytes, "
          "max_work_group_size, available, compiler_available, extensions. Empty without an "
          "OpenCL platform.");

    m.def("distance_transform", &vp::distance_transform, py::arg("world"),
          py::arg("metric") = "manhattan", py::arg("signed") = false,
          py::arg("sampling") = py::none(), py::arg("return_indices") = false,
          py::arg("max_distance") = py::none(), py::arg("format") = py::none(),
          py::arg("algorithm") = "exact", py::arg("device") = py::none(),
          "distance_transform(world, metric='manhattan', signed=False, sampling=None, "
          "return_indices=False, max_distance=None, format=None, algorithm='exact', "
          "device=None) -> ndarray, or (ndarray, indices)\n\n"
          "The distance from every voxel to the nearest solid (non-zero) voxel, between voxel "
          "centres, 0 on solids; outside the world counts as empty; with no solid voxel at all "
          "every value is the format's maximum (+inf for floats).\n\n"
          "world: 3-D array (Z, Y, X) of uint8, uint16, uint32 (values 0..255) or bool; a "
          "C-contiguous uint8 array is copied once into the device upload, other layouts are "
          "made contiguous first.\n"
          "metric: 'manhattan' (L1), 'chebyshev' (L-inf) or 'euclidean' (L2): SciPy's "
          "distance_transform_cdt(world == 0, metric='taxicab' / 'chessboard') and "
          "distance_transform_edt(world == 0).\n"
          "signed: empty voxels +distance to the nearest solid, solid voxels -distance to the "
          "nearest empty voxel, the world surrounded by empty space (needs a signed format).\n"
          "sampling: voxel spacing in array order (z, y, x) as in SciPy, or one number for "
          "every axis; positive.\n"
          "return_indices: also return an int32 array of shape (3, Z, Y, X) holding the "
          "(z, y, x) of a nearest solid voxel of every voxel (-1 without solids), SciPy's "
          "layout; unsigned fields only.\n"
          "max_distance: a bounded field, exact up to this distance (positive) and equal to it "
          "beyond (saturated); exact algorithm only. None: unbounded.\n"
          "format: 'u8', 'u16', 'u32', 'packed32' (uint8/uint16/uint32; distances rounded "
          "down, saturated), 'i8', 'i16', 'i32' (signed, toward zero), 'f32', 'f64'. Default: "
          "u16 (i16 when signed) for manhattan and chebyshev with unit sampling, f32 "
          "otherwise.\n"
          "algorithm: 'exact' or one of the dissertation's (brute, brute-chunked, fim, "
          "fim-host, jfa, jfa-host, jfa-fim, lod, monolithic; manhattan, unit sampling, "
          "unsigned only).\n"
          "device: None ($VOXFIELD_DEVICE, else the first GPU, else the first CPU), 'cpu', "
          "'gpu' or an index from devices(). One OpenCL context per device is kept for the "
          "module's lifetime, so kernels are built once.\n\n"
          "The result is a new array of the format's dtype that the device writes into "
          "directly.");

    py::class_<vp::Field>(
        m, "Field",
        "Field(world, metric='manhattan', device=None, algorithm='exact', format=None, *, "
        "sampling=None, signed=False, max_distance=None)\n\n"
        "A copy of `world` and its distance field kept on the device across edits: each edit "
        "uploads only the changed voxels and recomputes only what it can change, exactly "
        "(`voxfield replay`); the field always equals distance_transform of world() with the "
        "same arguments. world, metric, sampling, signed, max_distance, format and device: as for "
        "distance_transform (packed32 uses MagicaVoxel's default palette). algorithm: 'exact' "
        "(global semantics) or a chunk-local one of the dissertation (brute-chunked, lod, "
        "monolithic in 16^3 chunks; manhattan only).")
        .def(py::init<const py::object&, const std::string&, const py::object&, const std::string&,
                      const std::optional<std::string>&, const py::object&, bool,
                      const py::object&>(),
             py::arg("world"), py::arg("metric") = "manhattan", py::arg("device") = py::none(),
             py::arg("algorithm") = "exact", py::arg("format") = py::none(), py::kw_only(),
             py::arg("sampling") = py::none(), py::arg("signed") = false,
             py::arg("max_distance") = py::none(),
             "Field(world, metric='manhattan', device=None, algorithm='exact', format=None, *, "
             "sampling=None, signed=False, max_distance=None)\n\n"
             "Uploads a copy of `world` and computes its field (see the class).")
        .def("edit", &vp::Field::edit, py::arg("op"), py::arg("shape"), py::arg("center"),
             py::arg("radius"), py::arg("material") = 1,
             "edit(op, shape, center, radius, material=1) -> dict\n\n"
             "Applies one brush and updates the field. op: 'place' (sets material), 'erase' "
             "(sets 0; material ignored) or 'paint' (recolours solid voxels only); shape: "
             "'sphere' (dx^2+dy^2+dz^2 <= radius^2) or 'cube' (max(|dx|,|dy|,|dz|) <= radius); "
             "center: (x, y, z) in WORLD order, i.e. array index [z, y, x]; may lie outside "
             "the world, which clips the brush. Returns edits, voxels_changed, "
             "voxels_recomputed, update_ms (device time) and full_regeneration.")
        .def("apply_edits", &vp::Field::apply_edits, py::arg("text"),
             "apply_edits(text) -> dict\n\n"
             "Applies the edits of an edit file's text (`voxfield replay`: one "
             "'place|erase|paint sphere|cube X Y Z R [MATERIAL]' per line, '#' comments) in "
             "order, as one batch. The whole text is checked first: a bad line raises "
             "ValueError 'edits:LINE: ...' and changes nothing. Returns the batch's stats as "
             "edit() does.")
        .def("distances", &vp::Field::distances,
             "distances() -> ndarray\n\n"
             "The current field, shape (Z, Y, X), in the field's format, read from the device "
             "straight into a new array.")
        .def("world", &vp::Field::world,
             "world() -> ndarray\n\n"
             "A copy of the current world, uint8 of shape (Z, Y, X).");

    m.def("load_vox", &vp::load_vox, py::arg("path"),
          "load_vox(path) -> (world, palette)\n\n"
          "Reads a MagicaVoxel .vox file (first model): world uint8 of shape (Z, Y, X) with "
          "MagicaVoxel's z-up turned into y-up (vox (x, y, z) -> world (x, z, y)), palette uint8 "
          "of shape (256, 4) (RGBA of every voxel value; MagicaVoxel's default when the file "
          "has none). ValueError for a missing or malformed file.");
    m.def("save_vox", &vp::save_vox, py::arg("path"), py::arg("world"),
          py::arg("palette") = py::none(),
          "save_vox(path, world, palette=None)\n\n"
          "Writes a MagicaVoxel .vox (version 150) that load_vox reads back unchanged: world "
          "as for distance_transform (every axis at most 256, the format's limit), palette an "
          "integer array of shape (256, 4) (RGBA, 0..255; None: MagicaVoxel's default). The "
          "file is written to a temporary name and renamed, never left partial.");
}
