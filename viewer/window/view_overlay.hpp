#pragma once
// `view`'s overlay (Dear ImGui): the crosshair and the preview of the brush aimed at, then
// either the compact overlay (FPS, frame / update / ray march ms, the sand, devices, sharing
// path; it takes no input) or the full panel (F2: the times plotted, world, memory, devices,
// frame and sharing paths, the algorithm, metric, chunk, focus, scene and shading widgets, the
// brush, undo depth, palette), and the keys (F1). It draws the session's state, lets the
// widgets change the selections, shading, colour and help, and returns the switch asked for.
#include <cstdint>
#include <deque>
#include <string>
#include <vector>

#include "view_session.hpp"
#include "voxfield/vk/present.hpp"
#include "voxfield/vk/sparse_tracer.hpp"

namespace voxfield::cli {

// What one frame adds to the overlay.
struct OverlayFrame {
    double frame_ms = 0;      // the last frame's (0 before the first)
    double raymarch_ms = -1;  // the last ray march's (-1: none yet)
    std::uint32_t fb_width = 0, fb_height = 0;
};

class Overlay {
  public:
    // vulkan and opencl: the devices' names; frames: how frames reach the window; world: what
    // is shown at the start (the INPUT file, or "scene NAME").
    Overlay(const vk::Presenter& presenter, std::string vulkan, std::string opencl,
            const char* frames, bool simulate, std::string world);
    // Builds this frame's overlay (ImGui::Render included). `script`: what the script's
    // selections asked for, to which the panel's widgets add.
    SwitchRequest draw(ViewState& s, const pipeline::FramePipeline& session,
                       const OverlayFrame& frame, SwitchRequest script);

  private:
    void compact(const ViewState& s, const pipeline::FramePipeline& session,
                 const OverlayFrame& frame);
    void full_panel(ViewState& s, const pipeline::FramePipeline& session, const OverlayFrame& frame,
                    SwitchRequest& request);

    const vk::Presenter& presenter_;
    std::string vulkan_, opencl_;
    const char* frames_;
    bool simulate_;
    std::string world_;                                        // what the world shown came from
    std::vector<std::string> scenes_;                          // the scene combo's entries
    std::deque<float> hist_frame_, hist_update_, hist_march_;  // the last 120 frames
};

// What the sparse viewer's overlay shows (view_sparse): the world as stored, its field, the
// tracer's device copy, the last frame's and edit's times, the devices.
struct SparseOverlayInfo {
    std::string world, vulkan, opencl, format;
    std::string sharing;  // how the tracer gets the trees: "path 2", ...
    Dims dims;
    std::uint32_t tiles = 0, field_tiles = 0;
    std::uint64_t solid = 0, world_bytes = 0, field_bytes = 0;
    double max_distance = 0;
    vk::SparseDeviceStats tracer;
    double frame_ms = 0, trace_ms = -1;
    // The last edit: wall time in all, the field's kernels, the tiles' read-back, the tracer's
    // update, and the tiles it wrote and removed.
    double edit_ms = 0, field_kernel_ms = 0, readback_ms = 0, tracer_ms = 0;
    std::uint32_t tiles_written = 0, tiles_removed = 0;
    std::uint64_t edits = 0;
    // --simulate: steps run, the last one's wall time (step, field, read-back and tracer), the
    // voxels it changed and the tiles it ran and changed.
    std::uint64_t sand_steps = 0, sand_changed = 0;
    double sand_ms = 0;
    std::uint32_t sand_tiles_run = 0, sand_tiles_changed = 0;
    bool simulate = false;
};

// The sparse viewer's overlay (ImGui::Render included): crosshair and brush preview as on dense
// worlds, a box that takes no input with the above (F2 adds the shading and palette widgets,
// which change `render` and the brush's colour), and the keys (F1).
void draw_sparse_overlay(const SparseOverlayInfo& info, ViewControls& controls,
                         const ViewCamera& camera, const std::optional<Brush>& preview,
                         vk::RenderOptions& render, const Palette& palette, std::uint32_t fb_width,
                         std::uint32_t fb_height);

}  // namespace voxfield::cli
