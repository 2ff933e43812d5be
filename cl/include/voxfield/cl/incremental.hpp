#pragma once
// A world and its distance field kept on the device across edits: each batch of brush edits
// (one frame) uploads only the changed voxels and recomputes only what the edits can change,
// in one submission with no host wait per region or chunk.
//
// Global semantics (`exact`): exact after every batch. Let B be the bounding box of the
// voxels C whose occupancy an edit changed, and d_C(p) the L1 distance from p to C: per axis
// outside B, |p - c| splits at B's face for every c in B, so d_C(p) = L1(p, B) + f(clamp(p,
// B)) with f = d_C inside B, which the host computes over B alone (an L1 shortest path
// between two voxels of a box stays in the box). Only R = {p : old d(p) >= d_C(p)} can change
// (outside R the old nearest solid is nearer than anything edited). The device finds R's
// bounding box W over the blocks whose maximum reaches the least d_C over them (block maxima
// are kept per 8^3 voxels), testing each voxel of those, then recomputes W by separable
// min-plus sweeps from sources that are already right: the new solids, and the old values
// outside R in W and in W's one-voxel ring. If R reaches further than `max_margin` voxels
// from B (by default: no limit inside the world) the batch falls back to a full regeneration
// (still exact, reported as such). An edit that only places solids needs no sweeps: the new
// distance is min(old, d_S) with d_S the distance to the solids inside B, computed the same
// way; one pass over the blocks that can hold R lowers the distances, rewrites the blocks'
// maxima and finds the box of the changed voxels. Bounded unit-spacing L1 fields
// (--max-distance D) run the same way on distances capped at floor(D) (min-plus sweeps
// commute with the cap), so R lies within D of B. Every other exact field: ExactSeparable's
// incremental passes.
//
// Chunk-local algorithms (the dissertation's): the dirty chunks of the batch are recomputed
// with the algorithm's own per-chunk kernel, all in one launch (one work-group per chunk).
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "voxfield/cl/generator.hpp"
#include "voxfield/core/brush.hpp"
#include "voxfield/core/chunks.hpp"
#include "voxfield/core/undo.hpp"

namespace voxfield::ocl {

struct UpdateStats {
    double update_ms = 0;  // the batch's device time: uploads and kernels (profiling events)
    // Voxels whose distance the batch recomputed (global: W's for a swept edit, those of the
    // blocks read for an edit that only placed solids).
    std::uint64_t voxels_recomputed = 0;
    // The voxel boxes whose distances were recomputed (global: per edit W, or the box of the
    // voxels that a place lowered).
    std::vector<Box> regions;
    bool full_regeneration = false;  // a region grew past max_margin, or the batch's
                                     // changes spanned an eighth of the world or more
    std::vector<EditResult> edits;   // what each brush changed in the world
};

// Voxel changes already made on the device, in place in an IncrementalField's voxels (a
// simulation step: ocl::SandSimulator), listed there by the kernel that made them.
struct DeviceChanges {
    // list[k] = (linear index, before | after << 8) for k < min(count, capacity), in no
    // particular order; a voxel appears at most once.
    const cl::Buffer* list = nullptr;
    std::uint64_t capacity = 0;  // the list's room, in entries
    std::uint64_t count = 0;     // changes made (more than capacity: the list overflowed)
    Box bounds;                  // the box of every changed voxel
    Box occupancy_bounds;        // the box of the voxels that became solid or empty
    bool overflow() const { return count > capacity; }
};

class IncrementalField {
  public:
    // options: resolved; algorithm exact (global) or a chunk-local algorithm (options.chunk
    // != 0: brute-chunked, fim, fim-host, jfa, jfa-host, jfa-fim, lod, monolithic). Throws
    // InputError for algorithms it cannot update (global brute/fim/jfa variants).
    IncrementalField(Context& ctx, World world, const Palette& palette,
                     const GeneratorOptions& options, std::uint32_t max_margin = kNoMargin);
    static constexpr std::uint32_t kNoMargin = 0xFFFFFFFFu;
    ~IncrementalField();
    IncrementalField(const IncrementalField&) = delete;
    IncrementalField& operator=(const IncrementalField&) = delete;

    // Regenerates the whole field; returns its device time in ms. After a failed update that
    // could not be undone on the device (see apply()), uploads the world first and makes the
    // object usable again.
    double regenerate();
    // Applies the brushes in order to the world and updates the field (one batch).
    // apply, apply_changes and set_focus are all or nothing: when the device fails (ClError)
    // the world, the device voxels and the field are left as they were before the call (the
    // world's changes are undone, the device voxels rebuilt from it and the field
    // regenerated), and the error is rethrown. Should the device fail again while restoring,
    // every later apply, apply_changes and set_focus throws ClError until regenerate()
    // succeeds.
    UpdateStats apply(const std::vector<Brush>& batch);
    // Applies explicit voxel changes (an undo or redo of a stroke: core/undo.hpp) as one edit,
    // updated like apply(): exact, local to what the changes can affect. Throws InputError,
    // changing nothing, when a voxel does not hold its `before` value.
    UpdateStats apply_changes(const VoxelChanges& changes);
    // Brings the field up to date after `changes` were made on the device in voxels_buffer()
    // (enqueued before this call), reading the changes from the device list and not the host:
    // exact, local like apply() where the list holds every change and their occupancy box
    // spans less than an eighth of the world, else a full regeneration on the device. The host
    // world is then out of date until world() (or apply, apply_changes) reads the changed box
    // back. On a device failure the changes stay made (they happened on the device) and the
    // field is regenerated from the device voxels; should that fail too, the field is broken
    // as after a failed apply(). UpdateStats::edits stays empty.
    UpdateStats apply_device_changes(const DeviceChanges& changes);
    // lod and monolithic (chunk-local with a focus): moves the focus, the chunks where FIM
    // runs after JFA (std::nullopt: no focus, JFA only everywhere), and recomputes exactly
    // the chunks whose membership in the focus box changed (old box XOR new box), in one
    // launch. The field then equals a fresh IncrementalField with that focus. Returns the
    // launch's device time, the voxel boxes of the recomputed chunks and their voxel count;
    // empty stats when no chunk changed membership (the same focus). Throws InputError for
    // algorithms without a focus (exact, the other chunk-local ones) and for a focus outside
    // the chunk grid or of negative size.
    UpdateStats set_focus(std::optional<Focus> focus);

    // Test seam: the next apply, apply_changes or set_focus that reaches the device throws
    // ClError (CL_OUT_OF_RESOURCES) after enqueueing its commands and before waiting for them,
    // as a failing enqueue there would, so that tests can check the all-or-nothing guarantee.
    void fail_next_update_for_testing();

    // The world, read back from the device first where device changes made it out of date.
    const World& world();
    // The field in options.format, as generate() would write it.
    std::vector<std::uint8_t> read();
    // The field in options.format, on the device.
    const cl::Buffer& field_buffer() const;
    // The world's voxels on the device (one uchar per voxel, x fastest), kept current by
    // apply().
    const cl::Buffer& voxels_buffer() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace voxfield::ocl
