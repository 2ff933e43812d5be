// voxfield.Field (DESIGN §4): a thin front end over pipeline::Scene, the one owner of a world,
// its device copy, the incremental field, the undo history and the falling-sand simulation.
#include <cstring>
#include <sstream>

#include "transform.hpp"
#include "voxfield/core/brush.hpp"
#include "voxfield/core/edits.hpp"
#include "voxfield/core/error.hpp"

namespace voxfield::python {

namespace {

py::dict stats_dict(const pipeline::SceneUpdate& u) {
    py::dict out;
    out["edits"] = u.stats.edits.size();
    out["voxels_changed"] = u.voxels_changed;
    out["voxels_recomputed"] = u.stats.voxels_recomputed;
    out["update_ms"] = u.stats.update_ms;
    out["full_regeneration"] = u.stats.full_regeneration;
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

std::uint8_t sand_material(std::int64_t value, const char* name) {
    if (value < 1 || value > 255) {
        throw py::value_error(std::string(name) + " must be a material 1..255, got " +
                              std::to_string(value));
    }
    return static_cast<std::uint8_t>(value);
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
    scene_ =
        std::make_unique<pipeline::Scene>(device_->context, std::move(vox), Palette{}, options);
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

py::dict Field::undo() {
    pipeline::SceneUpdate u;
    {
        py::gil_scoped_release release;
        const std::lock_guard<std::mutex> lock(device_->mutex);
        u = scene_->undo();
    }
    return stats_dict(u);
}

py::dict Field::redo() {
    pipeline::SceneUpdate u;
    {
        py::gil_scoped_release release;
        const std::lock_guard<std::mutex> lock(device_->mutex);
        u = scene_->redo();
    }
    return stats_dict(u);
}

bool Field::can_undo() const {
    return scene_->history().can_undo();
}

bool Field::can_redo() const {
    return scene_->history().can_redo();
}

py::dict Field::step_sand(std::int64_t steps, std::uint64_t seed, std::int64_t sand,
                          std::int64_t water) {
    if (steps < 0) {
        throw py::value_error("steps must be a step count >= 0, got " + std::to_string(steps));
    }
    const SandRules rules{sand_material(sand, "sand"), sand_material(water, "water")};
    check_sand_rules(rules);
    std::uint64_t changed = 0, recomputed = 0, regenerations = 0;
    double simulate_ms = 0, update_ms = 0;
    {
        py::gil_scoped_release release;
        const std::lock_guard<std::mutex> lock(device_->mutex);
        for (std::int64_t i = 0; i < steps; ++i) {
            const pipeline::SceneUpdate u = scene_->step_sand(rules, seed, sand_steps_);
            ++sand_steps_;
            changed += u.voxels_changed;
            recomputed += u.stats.voxels_recomputed;
            regenerations += u.stats.full_regeneration ? 1 : 0;
            simulate_ms += u.simulate_ms;
            update_ms += u.stats.update_ms;
        }
    }
    py::dict out;
    out["steps"] = steps;
    out["voxels_changed"] = changed;
    out["voxels_recomputed"] = recomputed;
    out["simulate_ms"] = simulate_ms;
    out["update_ms"] = update_ms;
    out["full_regenerations"] = regenerations;
    return out;
}

py::array Field::distances() {
    const Dims d = scene_->dims();
    py::array out = empty_field(d, format_);
    void* data = out.mutable_data();
    const std::size_t bytes = d.count() * element_size(format_);
    py::gil_scoped_release release;
    const std::lock_guard<std::mutex> lock(device_->mutex);
    read_into(*device_, scene_->field_buffer(), data, bytes, d);
    return out;
}

py::array Field::world() {
    const Dims d = scene_->dims();
    py::array_t<std::uint8_t> out(std::vector<py::ssize_t>{d.z, d.y, d.x});
    std::uint8_t* data = out.mutable_data();
    py::gil_scoped_release release;
    const std::lock_guard<std::mutex> lock(device_->mutex);
    const World& w = scene_->world();
    std::memcpy(data, w.voxels().data(), w.size());
    return out;
}

py::dict Field::apply(const std::vector<Brush>& batch) {
    pipeline::SceneUpdate u;
    {
        py::gil_scoped_release release;
        const std::lock_guard<std::mutex> lock(device_->mutex);
        u = scene_->apply(batch);
        // The whole batch is one stroke: one undo() takes all of it back.
        for (const EditResult& e : u.stats.edits) {
            scene_->history().record(e);
        }
        scene_->history().end_stroke();
    }
    return stats_dict(u);
}

}  // namespace voxfield::python
