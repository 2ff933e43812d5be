#pragma once
// A scene (DESIGN §2): the one owner of a world on the host, its one copy on the OpenCL
// device, the distance field kept up to date there, the undo history and the falling-sand
// simulation, behind one edit protocol that `simulate`, `replay`, `bench --suite sand`, `view`
// and the frame pipeline share. Edits made on the host (brushes, undo / redo) reach the device
// as the changed voxels; simulation steps run in place on the device voxels and hand the field
// update their change list on the device, so nothing of theirs crosses to the host. The host
// world is brought up to date lazily, when something reads it (world(): a save, a brush, an
// undo), by reading back the box the device changed. Nothing here prints.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/incremental.hpp"
#include "voxfield/cl/sand.hpp"
#include "voxfield/core/brush.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/sand.hpp"
#include "voxfield/core/undo.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield::pipeline {

// Where a scene keeps its voxels and field. DenseStorage (a World and an
// ocl::IncrementalField) is the one there is; a sparse storage of tiles takes the same calls.
class SceneStorage {
  public:
    virtual ~SceneStorage() = default;
    virtual Dims dims() const = 0;
    // The host world, read back first where the device changed it.
    virtual const World& world() = 0;
    // The host world as last read back (without the device's changes since).
    virtual const World& last_read_world() const = 0;
    virtual ocl::UpdateStats apply(const std::vector<Brush>& batch) = 0;
    virtual ocl::UpdateStats apply_changes(const VoxelChanges& changes) = 0;
    virtual ocl::UpdateStats apply_device_changes(const ocl::DeviceChanges& changes) = 0;
    virtual ocl::UpdateStats set_focus(const std::optional<Focus>& focus) = 0;
    virtual double regenerate() = 0;
    // The field in the options' format, as `generate` writes it.
    virtual std::vector<std::uint8_t> read_field() = 0;
    // On the device: the field in the options' format, the voxels (a byte each, x fastest).
    virtual const cl::Buffer& field_buffer() const = 0;
    virtual const cl::Buffer& voxels_buffer() const = 0;
};

// Dense storage: every voxel on the host and on the device, the field of ocl::IncrementalField.
class DenseStorage : public SceneStorage {
  public:
    DenseStorage(ocl::Context& ctx, World world, const Palette& palette,
                 const ocl::GeneratorOptions& options, std::uint32_t max_margin);
    Dims dims() const override { return dims_; }
    const World& world() override { return field_.world(); }
    const World& last_read_world() const override { return field_.host_world(); }
    ocl::UpdateStats apply(const std::vector<Brush>& batch) override;
    ocl::UpdateStats apply_changes(const VoxelChanges& changes) override;
    ocl::UpdateStats apply_device_changes(const ocl::DeviceChanges& changes) override;
    ocl::UpdateStats set_focus(const std::optional<Focus>& focus) override;
    double regenerate() override { return field_.regenerate(); }
    std::vector<std::uint8_t> read_field() override { return field_.read(); }
    const cl::Buffer& field_buffer() const override { return field_.field_buffer(); }
    const cl::Buffer& voxels_buffer() const override { return field_.voxels_buffer(); }

  private:
    Dims dims_;
    ocl::IncrementalField field_;
};

// What one change of a scene did.
struct SceneUpdate {
    ocl::UpdateStats stats;  // the field update (stats.edits: the brushes' results)
    // The voxel boxes whose distance or material changed: what a render field converts.
    std::vector<Box> changed;
    double simulate_ms = -1;           // a simulation step's device time (-1: none)
    std::uint64_t voxels_changed = 0;  // voxels whose value changed
};

class Scene {
  public:
    // `options` resolved (ocl::resolve_options); exact or a chunk-local algorithm, as
    // ocl::IncrementalField takes them (InputError otherwise). Builds the field.
    Scene(ocl::Context& ctx, World world, const Palette& palette,
          const ocl::GeneratorOptions& options,
          std::uint32_t max_margin = ocl::IncrementalField::kNoMargin);
    ~Scene();
    Scene(const Scene&) = delete;
    Scene& operator=(const Scene&) = delete;

    Dims dims() const { return storage_->dims(); }
    const Palette& palette() const { return palette_; }
    const ocl::GeneratorOptions& options() const { return options_; }
    // The world, brought up to date from the device first where a simulation changed it.
    const World& world() { return storage_->world(); }
    // The world as the host last read it back, without the simulation's changes since: no
    // read-back. The simulation conserves every material's count, so counts read here are
    // exact.
    const World& last_read_world() const { return storage_->last_read_world(); }

    // The edit protocol. A batch of brushes in order, one field update; with `undoable` every
    // brush's result joins the history's open stroke (UndoStack::record), so that one undo
    // reverts the whole batch.
    SceneUpdate apply(const std::vector<Brush>& batch, bool undoable = false);
    // As apply(), the results of the first `undoable` brushes joining the open stroke and the
    // others not recorded (view: a stroke's brush first, then scripted or benchmark edits of
    // the same frame, in one field update).
    SceneUpdate apply_stroke(const std::vector<Brush>& batch, std::size_t undoable);
    // Explicit voxel changes as one edit; InputError, changing nothing, where a voxel does not
    // hold its `before`.
    SceneUpdate apply_changes(const VoxelChanges& changes);
    // The newest stroke undone / the newest undone stroke redone (nothing: an empty update).
    // Where later changes the history did not record (the simulation's, say) moved a voxel of
    // the stroke, InputError, and the history is cleared.
    SceneUpdate undo();
    SceneUpdate redo();
    UndoStack& history() { return history_; }
    const UndoStack& history() const { return history_; }
    // lod / monolithic: moves the focus (ocl::IncrementalField::set_focus).
    SceneUpdate set_focus(const std::optional<Focus>& focus);

    // Falling sand (core/sand.hpp) on the device voxels, in place: step `step` of the automaton
    // with `seed`, then the field updated from the step's change list on the device.
    // `capacity`: the change list's room (0: ocl::SandSimulator's default), fixed by the first
    // step with these rules. Throws InputError for bad rules.
    SceneUpdate step_sand(const SandRules& rules, std::uint64_t seed, std::uint64_t step,
                          std::size_t capacity = 0);
    std::string sand_variant()
        const;  // the simulator's kernel layout: "cpu layout" or "gpu layout"

    // Regenerates the whole field; returns its device time in ms.
    double regenerate() { return storage_->regenerate(); }
    std::vector<std::uint8_t> read_field() { return storage_->read_field(); }
    const cl::Buffer& field_buffer() const { return storage_->field_buffer(); }
    const cl::Buffer& voxels_buffer() const { return storage_->voxels_buffer(); }

  private:
    SceneUpdate finish(ocl::UpdateStats stats);

    ocl::Context& ctx_;
    Palette palette_;
    ocl::GeneratorOptions options_;
    std::unique_ptr<SceneStorage> storage_;
    UndoStack history_;
    std::unique_ptr<ocl::SandSimulator> sand_;
    SandRules sand_rules_;
};

}  // namespace voxfield::pipeline
