// voxfield.distance_transform (DESIGN §4): a world array in, its field (and the feature
// transform) out, with the command line's semantics.
//
// Copies: a C-contiguous uint8 or bool world is read in place by a device that computes in
// host memory (and uploaded from where it is elsewhere); other layouts are made C-contiguous
// by numpy first, and wider label volumes are turned into a World voxel by voxel. Fields are
// written by the device straight into the memory of the returned array (CPU devices; the
// caller's `out` array when given) or read from the device buffer into it; so are the index
// planes of the feature transform on a CPU device (elsewhere they are read slab by slab into
// the returned array). `targets='zero'` (voxfield.ndimage's convention): the distances are to
// the nearest zero voxel; the separable passes read the world as it is (the GPU layout's
// banded ones from a copy inverted on the device), other paths take an inverted copy.
#include <cstring>
#include <span>
#include <utility>

#include "common.hpp"
#include "transform.hpp"
#include "voxfield/cl/exact.hpp"
#include "voxfield/cl/separable.hpp"

namespace voxfield::python {

namespace {

// `exact` (the sweeps of exact_manhattan.cl or the separable transforms) from a C-contiguous
// uint8/bool world straight into `field` (host_field's memory) and, with o.indices, the index
// planes into `indices`: a CPU device reads the array and writes the field and planes in
// place, nothing copied; elsewhere the world is uploaded and the results read back into
// them. `zero_targets`: the distances are to the nearest zero voxel of `voxels` (the
// separable transforms; the caller inverts the world for exact_manhattan.cl's sweeps).
void transform_into(Device& dev, Dims dims, std::span<const std::uint8_t> voxels,
                    const ocl::GeneratorOptions& o, std::uint8_t* field, std::size_t bytes,
                    std::int32_t* indices, bool zero_targets) {
    auto& ctx = dev.context;
    const std::span<std::uint8_t> out(field, bytes);
    const std::span<std::int32_t> planes(indices, indices != nullptr ? 3 * dims.count() : 0);
    std::unique_ptr<ocl::Generator> made;
    if (!zero_targets && ocl::ExactManhattan::handles(ctx, o, dims)) {
        made = std::make_unique<ocl::ExactManhattan>(ctx, dims, voxels, Palette{}, o.format,
                                                     o.layout, o.metric, out, o.max_distance);
    } else {
        made = std::make_unique<ocl::ExactSeparable>(ctx, dims, voxels, Palette{}, o, out, planes,
                                                     zero_targets);
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
        read_into(dev, job.field_buffer(), field, bytes, dims);
    }
    if (indices != nullptr) {
        // Mapped slab by slab: in place (nothing to copy) where the device wrote `indices`.
        auto* dst = reinterpret_cast<std::uint8_t*>(indices);
        job.read_indices([&](std::span<const std::uint8_t> slab) {
            if (slab.data() != dst) {
                std::memcpy(dst, slab.data(), slab.size());
            }
            dst += slab.size();
        });
    }
}

// Whether `o` on `dev` runs the separable transforms, which read zero voxels as targets
// themselves (the CPU layout's passes; the GPU layout's banded passes from a copy the device
// inverts, its col_pass from the world); exact_manhattan.cl's sweeps take an inverted copy
// made on the host.
bool native_zero_targets(const Device& dev, const ocl::GeneratorOptions& o, Dims dims) {
    return !ocl::ExactManhattan::handles(dev.context, o, dims);
}

}  // namespace

py::object distance_transform(const py::object& world, const std::string& metric, bool signed_field,
                              const py::object& sampling, bool return_indices,
                              const py::object& max_distance,
                              const std::optional<std::string>& format,
                              const std::string& algorithm, const py::object& device,
                              const py::object& out, const std::string& targets) {
    if (targets != "nonzero" && targets != "zero") {
        throw py::value_error("targets must be 'nonzero' or 'zero', not '" + targets + "'");
    }
    const bool zero = targets == "zero";
    if (zero && signed_field) {
        throw py::value_error("targets='zero' needs signed=False");
    }
    const WorldArray w = world_array(world, true);
    ocl::GeneratorOptions o;
    o.max_distance = bound_of(max_distance);
    o.algorithm = ocl::parse_algorithm(algorithm);
    o.metric = parse_metric(metric);
    o.spacing = spacing_of(sampling);
    o.signed_field = signed_field;
    o.indices = return_indices;
    o.format = format_of(format, o.metric, o.spacing, signed_field);
    const bool empty = w.count == 0;
    const ocl::GeneratorOptions options =
        resolve_python_options(o, empty ? Dims{1, 1, 1} : w.dims, false);
    const std::shared_ptr<Device> dev = device_for(device);
    const Labels labels = options.format == Format::packed32 ? Labels::palette : Labels::solid;
    if (zero && labels != Labels::solid) {
        throw py::value_error("targets='zero' needs a distance format, not packed32");
    }

    const std::size_t field_bytes = w.count * element_size(options.format);
    const std::size_t index_bytes = return_indices ? 3 * w.count * sizeof(std::int32_t) : 0;
    // `exact` from a uint8/bool array: read in place (or one inverted copy for zero targets
    // where the kernels do not take them), field and index planes written into the returned
    // arrays.
    const bool direct = w.bytes_are_voxels() && options.algorithm == ocl::Algorithm::exact &&
                        labels == Labels::solid;
    const bool invert = zero && !(direct && native_zero_targets(*dev, options, w.dims));
    if (!empty) {
        check_device_bytes(*dev, std::max(field_bytes, index_bytes),
                           w.count + field_bytes + index_bytes,
                           "the field of " + w.dims.to_string());
        check_host_bytes((out.is_none() ? field_bytes : 0) + index_bytes +
                             (w.bytes_are_voxels() && !invert ? 0 : w.count),
                         "the field of " + w.dims.to_string());
    }
    std::uint8_t* direct_out = nullptr;
    py::array field;
    if (!out.is_none()) {
        // The caller's array: written in place (by the device where it computes in host
        // memory), no field allocated here.
        field = caller_field(out, w.dims, options.format);
        direct_out = static_cast<std::uint8_t*>(field.mutable_data());
    } else {
        field = direct ? host_field(w.dims, options.format, direct_out)
                       : empty_field(w.dims, options.format);
    }
    py::array_t<std::int32_t> indices;
    if (return_indices) {
        indices =
            py::array_t<std::int32_t>(std::vector<py::ssize_t>{3, w.dims.z, w.dims.y, w.dims.x});
    }
    if (empty) {
        return return_indices ? py::object(py::make_tuple(field, indices)) : py::object(field);
    }
    void* field_out = field.mutable_data();
    std::int32_t* indices_out = return_indices ? indices.mutable_data() : nullptr;
    {
        py::gil_scoped_release release;
        if (direct) {
            std::vector<std::uint8_t> inverted;
            std::span<const std::uint8_t> voxels(w.data, w.bytes);
            if (invert) {
                inverted.resize(w.count);
                for (std::size_t i = 0; i < w.count; ++i) {
                    inverted[i] = w.data[i] == 0 ? 1 : 0;
                }
                voxels = inverted;
            }
            const std::lock_guard<std::mutex> lock(dev->mutex);
            transform_into(*dev, w.dims, voxels, options, direct_out, field_bytes, indices_out,
                           zero && !invert);
        } else {
            World vox = make_world(w, labels);
            if (invert) {
                for (std::uint8_t& v : vox.voxels()) {
                    v = v == 0 ? 1 : 0;
                }
            }
            const std::lock_guard<std::mutex> lock(dev->mutex);
            const auto job = ocl::make_generator(dev->context, vox, Palette{}, options);
            job->run();
            read_into(*dev, job->field_buffer(), field_out, field_bytes, w.dims);
            if (indices_out != nullptr) {
                // Slab by slab into the numpy array: no whole-volume copy on the host.
                auto* dst = reinterpret_cast<std::uint8_t*>(indices_out);
                job->read_indices([&](std::span<const std::uint8_t> slab) {
                    std::memcpy(dst, slab.data(), slab.size());
                    dst += slab.size();
                });
            }
        }
    }
    if (return_indices) {
        return py::make_tuple(field, indices);
    }
    return field;
}

}  // namespace voxfield::python
