// A scene: world, device copy, field, history and simulation behind one edit protocol
// (scene.hpp).
#include "voxfield/pipeline/scene.hpp"

#include <algorithm>
#include <utility>

#include "voxfield/core/error.hpp"

namespace voxfield::pipeline {

DenseStorage::DenseStorage(ocl::Context& ctx, World world, const Palette& palette,
                           const ocl::GeneratorOptions& options, std::uint32_t max_margin)
    : dims_(world.dims()), field_(ctx, std::move(world), palette, options, max_margin) {}

ocl::UpdateStats DenseStorage::apply(const std::vector<Brush>& batch) {
    return field_.apply(batch);
}

ocl::UpdateStats DenseStorage::apply_changes(const VoxelChanges& changes) {
    return field_.apply_changes(changes);
}

ocl::UpdateStats DenseStorage::apply_device_changes(const ocl::DeviceChanges& changes) {
    return field_.apply_device_changes(changes);
}

ocl::UpdateStats DenseStorage::set_focus(const std::optional<Focus>& focus) {
    return field_.set_focus(focus);
}

Scene::Scene(ocl::Context& ctx, World world, const Palette& palette,
             const ocl::GeneratorOptions& options, std::uint32_t max_margin)
    : ctx_(ctx),
      palette_(palette),
      options_(options),
      storage_(
          std::make_unique<DenseStorage>(ctx, std::move(world), palette, options, max_margin)) {}

Scene::~Scene() = default;

SceneUpdate Scene::finish(ocl::UpdateStats stats) {
    SceneUpdate u;
    u.changed = stats.regions;
    for (const EditResult& e : stats.edits) {
        if (e.changed()) {
            u.changed.push_back(e.bounds);  // recoloured voxels keep their distance
            u.voxels_changed += e.changes.size();
        }
    }
    u.stats = std::move(stats);
    return u;
}

SceneUpdate Scene::apply(const std::vector<Brush>& batch, bool undoable) {
    return apply_stroke(batch, undoable ? batch.size() : 0);
}

SceneUpdate Scene::apply_stroke(const std::vector<Brush>& batch, std::size_t undoable) {
    SceneUpdate u = finish(storage_->apply(batch));
    // Every recorded brush, in order: the stroke merges them per voxel (first before, last
    // after), so that one undo restores what the batch found.
    const std::size_t n = std::min(undoable, u.stats.edits.size());
    for (std::size_t i = 0; i < n; ++i) {
        history_.record(u.stats.edits[i]);
    }
    return u;
}

SceneUpdate Scene::apply_changes(const VoxelChanges& changes) {
    return finish(storage_->apply_changes(changes));
}

SceneUpdate Scene::undo() {
    const VoxelChanges changes = history_.undo();
    if (changes.empty()) {
        return {};
    }
    try {
        return apply_changes(changes);
    } catch (const InputError&) {
        history_.clear();
        throw;
    }
}

SceneUpdate Scene::redo() {
    const VoxelChanges changes = history_.redo();
    if (changes.empty()) {
        return {};
    }
    try {
        return apply_changes(changes);
    } catch (const InputError&) {
        history_.clear();
        throw;
    }
}

SceneUpdate Scene::set_focus(const std::optional<Focus>& focus) {
    SceneUpdate u = finish(storage_->set_focus(focus));
    options_.focus = focus;
    return u;
}

SceneUpdate Scene::step_sand(const SandRules& rules, std::uint64_t seed, std::uint64_t step,
                             std::size_t capacity) {
    check_sand_rules(rules);
    if (!sand_ || rules.sand != sand_rules_.sand || rules.water != sand_rules_.water) {
        sand_ = std::make_unique<ocl::SandSimulator>(ctx_, storage_->voxels_buffer(), dims(), rules,
                                                     ocl::Layout::automatic, capacity);
        sand_rules_ = rules;
    }
    const ocl::SandStepResult r = sand_->step(seed, step);
    SceneUpdate u = finish(storage_->apply_device_changes(r.changes));
    if (!r.changes.bounds.empty()) {
        u.changed.push_back(r.changes.bounds);
    }
    u.simulate_ms = r.simulate_ms;
    u.voxels_changed = r.changes.count;
    return u;
}

std::string Scene::sand_variant() const {
    return sand_ ? sand_->variant() : ctx_.is_cpu() ? "cpu layout" : "gpu layout";
}

}  // namespace voxfield::pipeline
