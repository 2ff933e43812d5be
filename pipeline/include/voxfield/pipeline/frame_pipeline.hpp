#pragma once
// The frame pipeline that `render`, `view` and `bench` share (DESIGN §2, "The frame
// pipeline"): a scene (pipeline::Scene: the world, its device copy and distance field, the
// history and the simulation),
// the ray marcher's render field converted from it (RenderField: sharing path 1, 2 or 3), and
// the Vulkan ray marcher reading it. Every edit goes edit -> field -> render field; every frame
// is one ray march. Switching the world, algorithm or metric is transactional: the new field is
// built completely before the old one goes, and a failure (refused options, a device error)
// leaves the pipeline as it was. Nothing here prints.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/incremental.hpp"
#include "voxfield/core/brush.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/undo.hpp"
#include "voxfield/core/world.hpp"
#include "voxfield/pipeline/render_field.hpp"
#include "voxfield/pipeline/scene.hpp"
#include "voxfield/vk/raymarcher.hpp"

namespace voxfield::pipeline {

struct PipelineOptions {
    // What the ray marcher reads: the compact field (16 bits per voxel, written by OpenCL in
    // place on paths 1/2) or packed32 (the field read back and uploaded, path 3; after a change
    // only its boxes: update_packed32).
    vk::FieldFormat render_format = vk::FieldFormat::compact;
    // The fastest sharing path the render field may take (tests force the slower ones).
    vk::SharingPath fastest_path = vk::SharingPath::opaque_fd;
    // Split the ray marcher's field into bindings of at most this many bytes (0: the device's
    // limit; tests lower it).
    std::uint64_t max_binding_bytes = 0;
};

// What one edit batch cost (device times, from OpenCL profiling events).
struct UpdateTimings {
    double field_ms = 0;    // the incremental update of the distance field
    double convert_ms = 0;  // writing the changed voxels into the render field (and copying
                            // them on path 3); FieldSync::semaphore: the conversions found
                            // finished since the last update (RenderField::update)
    std::uint64_t voxels_recomputed = 0;
    bool full_regeneration = false;
    double simulate_ms = -1;           // a simulation step's device time (-1: none)
    std::uint64_t voxels_changed = 0;  // voxels whose value changed
    double total_ms() const { return field_ms + convert_ms; }
};

class FramePipeline {
  public:
    // Call rebuild() before anything else (until one succeeds, every other call but the
    // ray marcher's throws std::logic_error). `palette` colours every world of this pipeline.
    FramePipeline(ocl::Context& cl, vk::Context& vkc, Palette palette, Dims dims,
                  PipelineOptions options = {});
    ~FramePipeline();
    FramePipeline(const FramePipeline&) = delete;
    FramePipeline& operator=(const FramePipeline&) = delete;

    // Builds the field of `world` with `options` (resolved here) and shows it: a new world,
    // algorithm, metric, format or chunk size. Returns the wall time in ms. Throws InputError
    // for a world whose dims differ from the pipeline's. On any failure the pipeline keeps its
    // previous world, field and options and the exception goes on; should showing the previous
    // field fail too, the next update shows it again first (and throws if it cannot).
    double rebuild(World world, const ocl::GeneratorOptions& options);
    // As rebuild() with the current world.
    double switch_field(const ocl::GeneratorOptions& options);

    // One batch of brushes (one frame's edits), applied in order; `edits` receives what each
    // brush changed; the first `undoable` brushes join the history's open stroke
    // (Scene::apply_stroke: view passes its stroke's brush first, 1, or 0 without a stroke).
    UpdateTimings apply(const std::vector<Brush>& batch, std::vector<EditResult>* edits = nullptr,
                        std::size_t undoable = 0);
    // Explicit voxel changes as one edit.
    UpdateTimings apply_changes(const VoxelChanges& changes);
    // The scene's history: Scene::undo / redo, then the render field.
    UpdateTimings undo();
    UpdateTimings redo();
    // One step of falling sand in place on the device (Scene::step_sand), then the render
    // field.
    UpdateTimings step_sand(const SandRules& rules, std::uint64_t seed, std::uint64_t step);
    // lod / monolithic: moves the focus and recomputes the chunks that entered or left it.
    UpdateTimings set_focus(const std::optional<Focus>& focus);

    // Ray-marches one frame and reads it back (out's storage is reused); its raymarch_ms is
    // the dispatch's GPU time.
    void render(const vk::RenderOptions& options, vk::Image& out);
    // Ray-marches one frame into exported memory for a presenter on another VkDevice; returns
    // the dispatch's GPU time in ms (-1: not available).
    double render_to(const vk::RenderOptions& options, const vk::ExternalMemory& frame);
    // Ray-marches one frame on the device only (headless frames: nothing read back, nothing
    // presented) without waiting for it, at most kFramesInFlight frames queued; returns the
    // ray march GPU time in ms of the latest frame known to have finished (-1: none yet).
    double march(const vk::RenderOptions& options);
    static constexpr std::size_t kFramesInFlight = 2;

    // The scene's world (brought up to date from the device where the simulation moved it).
    const World& world() const;
    // The scene's world as last read back (Scene::last_read_world: no read-back); throws
    // std::logic_error before the first successful rebuild().
    const World& last_read_world() const;
    Dims dims() const { return dims_; }
    Scene& scene();
    const Palette& palette() const { return palette_; }
    // The scene's options (default ones before the first successful rebuild()).
    const ocl::GeneratorOptions& options() const;
    // The field in options().format, as `generate` writes it.
    std::vector<std::uint8_t> read_field();
    vk::Raymarcher& marcher() { return *marcher_; }
    const vk::Raymarcher& marcher() const { return *marcher_; }
    // The sharing path of the compact render field and why faster ones are not used (packed32
    // is always copied: path 3).
    vk::SharingPath sharing() const;
    std::string why_not() const;
    // How edits are ordered against the frames that read the field (RenderField::sync:
    // semaphore, fence or queue; packed32: queue) and why not by semaphores ("" when they are).
    FieldSync sync() const;
    std::string sync_why_not() const;

    // Test seam: the next `count` times the pipeline shows a field in the ray marcher, it
    // throws ocl::ClError (CL_OUT_OF_RESOURCES) first, as a failing conversion would.
    void fail_next_shows_for_testing(int count) { failing_shows_ = count; }

  private:
    UpdateTimings finish(SceneUpdate u, std::vector<EditResult>* edits);
    double publish(std::vector<Box> regions);
    // Shows `scene`'s field in the ray marcher; returns the OpenCL time.
    double show(Scene& scene);
    // The scene, shown: throws std::logic_error before the first successful rebuild().
    Scene& current();

    ocl::Context& cl_;
    vk::Context& vk_;
    std::vector<std::uint64_t> marched_;  // submissions of march() not known to be finished
    Palette palette_;
    Dims dims_;
    std::unique_ptr<Scene> scene_;
    bool shown_ = false;  // scene_'s field is the one the render field converts
    int failing_shows_ = 0;
    // Declared before the ray marcher: destroyed after it (it may read this memory).
    std::unique_ptr<RenderField> render_field_;
    std::unique_ptr<vk::Raymarcher> marcher_;
};

}  // namespace voxfield::pipeline
