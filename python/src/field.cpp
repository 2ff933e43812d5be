// voxfield.Field (DESIGN §4): a world and its field kept on the device across edits.
#include <cstring>
#include <sstream>

#include "transform.hpp"
#include "voxfield/core/brush.hpp"
#include "voxfield/core/edits.hpp"
#include "voxfield/core/error.hpp"

namespace voxfield::python {

namespace {

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

}  // namespace

Field::Field(const py::object& world, const std::string& metric, const py::object& device,
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
    const ocl::GeneratorOptions options = resolve_python_options(o, w.dims, true);
    device_ = device_for(device);
    format_ = options.format;
    const std::size_t field_bytes = w.count * element_size(options.format);
    check_device_bytes(*device_, field_bytes, w.count + field_bytes,
                       "the field of " + w.dims.to_string());
    check_host_bytes(w.count, "the world of " + w.dims.to_string());
    const Labels labels = options.format == Format::packed32 ? Labels::palette : Labels::solid;
    py::gil_scoped_release release;
    World vox = make_world(w, labels);
    const std::lock_guard<std::mutex> lock(device_->mutex);
    field_ = std::make_unique<ocl::IncrementalField>(device_->context, std::move(vox), Palette{},
                                                     options);
}

py::dict Field::edit(const std::string& op, const std::string& shape,
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

py::dict Field::apply_edits(const std::string& text) {
    std::istringstream in(text);
    std::vector<Brush> batch;
    for (const Edit& e : parse_edits(in, "edits")) {
        batch.push_back(e.brush);
    }
    return apply(batch);
}

py::array Field::distances() {
    const Dims d = field_->world().dims();
    py::array out = empty_field(d, format_);
    void* data = out.mutable_data();
    const std::size_t bytes = d.count() * element_size(format_);
    py::gil_scoped_release release;
    const std::lock_guard<std::mutex> lock(device_->mutex);
    read_into(*device_, field_->field_buffer(), data, bytes, d);
    return out;
}

py::array Field::world() {
    const Dims d = field_->world().dims();
    py::array_t<std::uint8_t> out(std::vector<py::ssize_t>{d.z, d.y, d.x});
    std::uint8_t* data = out.mutable_data();
    py::gil_scoped_release release;
    const std::lock_guard<std::mutex> lock(device_->mutex);
    std::memcpy(data, field_->world().voxels().data(), field_->world().size());
    return out;
}

py::dict Field::apply(const std::vector<Brush>& batch) {
    ocl::UpdateStats stats;
    {
        py::gil_scoped_release release;
        const std::lock_guard<std::mutex> lock(device_->mutex);
        stats = field_->apply(batch);
    }
    return stats_dict(stats);
}

}  // namespace voxfield::python
