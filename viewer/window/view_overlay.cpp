// `view`'s overlay (see view_overlay.hpp).
#include "view_overlay.hpp"

#include <imgui.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "voxfield/core/scenes.hpp"

namespace voxfield::cli {
namespace {

const ImVec4 kRed(1.0f, 0.45f, 0.4f, 1.0f);  // what went wrong

// The sharing path in a few words (the compact overlay; the full panel has the whole story).
const char* sharing_summary(vk::SharingPath path) {
    switch (path) {
        case vk::SharingPath::opaque_fd:
            return "path 1 (opaque fd, no copy)";
        case vk::SharingPath::host_pointer:
            return "path 2 (host memory, no copy)";
        case vk::SharingPath::copy:
            break;
    }
    return "path 3 (copy)";
}

// The brush's target drawn over the image: a cube's box as 12 edges, a sphere as the circle
// of its projected radius (place: green, erase: red, paint: the brush's colour).
void draw_brush_preview(ImDrawList* draw, const Brush& b, const ViewCamera& camera,
                        std::uint32_t fb_w, std::uint32_t fb_h, ImVec2 display,
                        const Palette& palette) {
    const Vec3d eye = camera.position(), forward = camera.forward();
    const double fov = camera.settings.fov_deg;
    // Framebuffer pixels -> overlay units (they differ on HiDPI displays).
    const double sx = display.x / static_cast<double>(fb_w);
    const double sy = display.y / static_cast<double>(fb_h);
    const auto project = [&](const Vec3d& p) -> std::optional<ImVec2> {
        const auto ip = project_point(eye, forward, fov, fb_w, fb_h, p);
        if (!ip) {
            return std::nullopt;
        }
        return ImVec2(static_cast<float>(ip->x * sx), static_cast<float>(ip->y * sy));
    };
    ImU32 colour = IM_COL32(80, 255, 120, 230);
    if (b.op == BrushOp::erase) {
        colour = IM_COL32(255, 80, 80, 230);
    } else if (b.op == BrushOp::paint) {
        const Rgba c = palette[b.material];
        colour = IM_COL32(c.r, c.g, c.b, 255);
    }
    const double r = static_cast<double>(b.radius);
    const Vec3d c{static_cast<double>(b.centre.x) + 0.5, static_cast<double>(b.centre.y) + 0.5,
                  static_cast<double>(b.centre.z) + 0.5};
    if (b.shape == BrushShape::sphere) {
        const auto centre = project(c);
        const Vec3d right = view_basis(forward).right;
        const auto edge = project({c[0] + (r + 0.5) * right[0], c[1] + (r + 0.5) * right[1],
                                   c[2] + (r + 0.5) * right[2]});
        if (centre && edge) {
            const float radius = std::hypot(edge->x - centre->x, edge->y - centre->y);
            draw->AddCircle(*centre, std::max(radius, 2.0f), colour, 0, 2);
        }
        return;
    }
    const double lo[3] = {c[0] - r - 0.5, c[1] - r - 0.5, c[2] - r - 0.5};
    const double hi[3] = {c[0] + r + 0.5, c[1] + r + 0.5, c[2] + r + 0.5};
    std::optional<ImVec2> corner[8];
    for (int i = 0; i < 8; ++i) {
        corner[i] =
            project({(i & 1) ? hi[0] : lo[0], (i & 2) ? hi[1] : lo[1], (i & 4) ? hi[2] : lo[2]});
    }
    for (int i = 0; i < 8; ++i) {
        for (const int bit : {1, 2, 4}) {
            const int j = i | bit;
            if (j != i && corner[i] && corner[j]) {
                draw->AddLine(*corner[i], *corner[j], colour, 2);
            }
        }
    }
}

void push(std::deque<float>& h, double v) {
    h.push_back(static_cast<float>(v));
    if (h.size() > 120) {
        h.pop_front();
    }
}

}  // namespace

Overlay::Overlay(const vk::Presenter& presenter, std::string vulkan, std::string opencl,
                 const char* frames, bool simulate, std::string world)
    : presenter_(presenter),
      vulkan_(std::move(vulkan)),
      opencl_(std::move(opencl)),
      frames_(frames),
      simulate_(simulate),
      world_(std::move(world)),
      scenes_(scene_names()) {}

SwitchRequest Overlay::draw(ViewState& s, const pipeline::FramePipeline& session,
                            const OverlayFrame& frame, SwitchRequest script) {
    const ImGuiIO& io = ImGui::GetIO();
    // Crosshair.
    ImDrawList* fg = ImGui::GetForegroundDrawList();
    const ImVec2 c(io.DisplaySize.x / 2, io.DisplaySize.y / 2);
    fg->AddLine(ImVec2(c.x - 8, c.y), ImVec2(c.x + 9, c.y), IM_COL32(255, 255, 255, 220), 2);
    fg->AddLine(ImVec2(c.x, c.y - 8), ImVec2(c.x, c.y + 9), IM_COL32(255, 255, 255, 220), 2);
    if (s.preview && frame.fb_width > 0 && frame.fb_height > 0) {
        draw_brush_preview(fg, *s.preview, s.camera, frame.fb_width, frame.fb_height,
                           io.DisplaySize, session.palette());
    }
    push(hist_frame_, frame.frame_ms);
    push(hist_update_, s.last_update.field_ms + s.last_update.convert_ms);
    push(hist_march_, frame.raymarch_ms);
    SwitchRequest request = script;
    if (!s.controls.full_panel) {
        compact(s, session, frame);
    } else {
        full_panel(s, session, frame, request);
    }
    if (s.controls.show_help) {
        ImGui::SetNextWindowPos(ImVec2(io.DisplaySize.x / 2, io.DisplaySize.y / 2),
                                ImGuiCond_Always, ImVec2(0.5f, 0.5f));
        ImGui::Begin("keys (F1)", &s.controls.show_help, ImGuiWindowFlags_AlwaysAutoResize);
        for (const auto& k : kViewKeys) {
            ImGui::Text("%-20s %s", k[0], k[1]);
        }
        ImGui::End();
    }
    if (request.scene) {
        // From now on the world shown is the selected scene, not the file or scene it started as.
        world_ = "scene " + scenes_.at(static_cast<std::size_t>(s.selection.scene));
    }
    ImGui::Render();
    return request;
}

void Overlay::compact(const ViewState& s, const pipeline::FramePipeline& session,
                      const OverlayFrame& frame) {
    // The compact overlay: one small box that takes no input.
    ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_Always);
    ImGui::SetNextWindowBgAlpha(0.5f);
    ImGui::Begin("##compact", nullptr,
                 ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_AlwaysAutoResize |
                     ImGuiWindowFlags_NoInputs | ImGuiWindowFlags_NoSavedSettings |
                     ImGuiWindowFlags_NoFocusOnAppearing | ImGuiWindowFlags_NoNav);
    ImGui::Text("%.1f FPS  frame %.2f  update %.3f  march %.3f ms",
                frame.frame_ms > 0 ? 1000.0 / frame.frame_ms : 0.0, frame.frame_ms,
                s.last_update.field_ms + s.last_update.convert_ms, frame.raymarch_ms);
    if (simulate_) {
        ImGui::Text("sand: step %llu%s, simulate %.3f ms, %zu voxels moved",
                    static_cast<unsigned long long>(s.sand.step),
                    s.controls.sand_paused ? " (paused: G runs, N steps)" : "", s.sand.last_ms,
                    s.sand.last_changed);
    }
    ImGui::Text("%s + %s", vulkan_.c_str(), opencl_.c_str());
    ImGui::Text("%s, %s; F1 keys, F2 panel", sharing_summary(session.sharing()),
                ocl::to_string(session.options().algorithm).c_str());
    if (!s.switch_error.empty()) {
        ImGui::PushTextWrapPos(ImGui::GetFontSize() * 32);
        ImGui::TextColored(kRed, "cannot switch: %s", s.switch_error.c_str());
        ImGui::PopTextWrapPos();
    }
    ImGui::End();
}

void Overlay::full_panel(ViewState& s, const pipeline::FramePipeline& session,
                         const OverlayFrame& frame, SwitchRequest& request) {
    ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_FirstUseEver);
    // Wide enough for the device and sharing lines, which also wrap rather than being clipped.
    ImGui::SetNextWindowSize(ImVec2(ImGui::GetFontSize() * 36, 0), ImGuiCond_FirstUseEver);
    ImGui::Begin("voxfield (F2: compact)");
    ImGui::PushTextWrapPos(0.0f);
    if (!s.switch_error.empty()) {
        ImGui::PushTextWrapPos(ImGui::GetFontSize() * 40);
        ImGui::TextColored(kRed, "cannot switch: %s", s.switch_error.c_str());
        ImGui::PopTextWrapPos();
    }
    const std::vector<float> hf(hist_frame_.begin(), hist_frame_.end());
    const std::vector<float> hu(hist_update_.begin(), hist_update_.end());
    const std::vector<float> hm(hist_march_.begin(), hist_march_.end());
    ImGui::Text("%.1f FPS, frame %.2f ms", frame.frame_ms > 0 ? 1000.0 / frame.frame_ms : 0.0,
                frame.frame_ms);
    ImGui::PlotLines("frame ms", hf.data(), static_cast<int>(hf.size()));
    ImGui::Text("field update %.3f ms + render field %.3f ms (device)", s.last_update.field_ms,
                s.last_update.convert_ms);
    ImGui::PlotLines("update ms", hu.data(), static_cast<int>(hu.size()));
    ImGui::Text("ray march %.3f ms (GPU timestamps)", frame.raymarch_ms);
    ImGui::PlotLines("march ms", hm.data(), static_cast<int>(hm.size()));
    const World& w = session.last_read_world();  // no read-back; the sand conserves counts
    ImGui::TextWrapped("world: %s, %s, %zu solid of %zu voxels", world_.c_str(),
                       w.dims().to_string().c_str(), w.solid_count(), w.size());
    ImGui::Text("memory/voxel: render 2 B (compact), OpenCL field %zu B (%s) + world 1 B",
                element_size(session.options().format),
                to_string(session.options().format).c_str());
    ImGui::TextWrapped("OpenCL: %s", opencl_.c_str());
    ImGui::TextWrapped("Vulkan: %s / present %s (%s)", vulkan_.c_str(),
                       presenter_.device_name().c_str(), vk::to_string(presenter_.mode()).c_str());
    ImGui::TextWrapped("frames: %s", frames_);
    ImGui::TextWrapped("sharing: %s", session.marcher().sharing_path().c_str());
    if (!session.why_not().empty() && ImGui::IsItemHovered()) {
        ImGui::SetTooltip("%s", session.why_not().c_str());
    }
    ImGui::Separator();
    const auto& names = ocl::algorithm_names();
    std::vector<const char*> cnames;
    for (const auto& n : names) {
        cnames.push_back(n.c_str());
    }
    if (ImGui::Combo("algorithm", &s.selection.algorithm, cnames.data(),
                     static_cast<int>(cnames.size()))) {
        request.field = true;
    }
    std::vector<const char*> mnames;
    for (const auto& n : metric_names()) {
        mnames.push_back(n.c_str());
    }
    if (ImGui::Combo("metric", &s.selection.metric, mnames.data(),
                     static_cast<int>(mnames.size()))) {
        request.field = true;
    }
    ImGui::SliderInt("chunk 2^k", &s.selection.chunk_log2, 3, 7);
    if (has_focus(session.options().algorithm)) {
        ImGui::SliderInt("focus size", &s.selection.focus_size, 0, 8);
        ImGui::Checkbox("focus follows camera", &s.selection.focus_follows);
        if (const auto& f = session.options().focus) {
            ImGui::Text("focus: chunk (%lld, %lld, %lld), size %lld",
                        static_cast<long long>(f->centre.x), static_cast<long long>(f->centre.y),
                        static_cast<long long>(f->centre.z), static_cast<long long>(f->size));
        }
    }
    std::vector<const char*> snames;
    for (const auto& n : scenes_) {
        snames.push_back(n.c_str());
    }
    // The scene "regenerate" makes; the world shown is named on the "world:" line above.
    ImGui::Combo("new scene", &s.selection.scene, snames.data(), static_cast<int>(snames.size()));
    request.scene = ImGui::Button("regenerate") || request.scene;
    ImGui::SameLine();
    request.field = ImGui::Button("apply algorithm") || request.field;
    int shading = s.render.shading == vk::Shading::lit ? 1 : 0;
    const char* shadings[] = {"flat", "lit"};
    if (ImGui::Combo("shading", &shading, shadings, 2)) {
        set_shading(s.render, shading == 1 ? vk::Shading::lit : vk::Shading::flat);
    }
    ImGui::Text(
        "brush: %s %s, size %lld, colour %d  (%s)", s.controls.paint_mode ? "paint" : "place",
        to_string(s.controls.brush.shape).c_str(), static_cast<long long>(s.controls.brush.size),
        s.controls.brush.material, s.camera.mode() == ViewCamera::Mode::orbit ? "orbit" : "fly");
    ImGui::Text("undo %zu, redo %zu. F1: keys", s.history().undo_count(), s.history().redo_count());
    if (ImGui::CollapsingHeader("palette")) {
        const Palette& pal = session.palette();
        for (int m = 1; m < 256; ++m) {
            const Rgba rgb = pal[static_cast<std::uint8_t>(m)];
            ImGui::PushID(m);
            if (ImGui::ColorButton("##colour",
                                   ImVec4(rgb.r / 255.0f, rgb.g / 255.0f, rgb.b / 255.0f, 1),
                                   ImGuiColorEditFlags_NoAlpha, ImVec2(14, 14))) {
                s.controls.brush.material = static_cast<std::uint8_t>(m);
            }
            if (m == s.controls.brush.material) {
                ImGui::GetWindowDrawList()->AddRect(ImGui::GetItemRectMin(),
                                                    ImGui::GetItemRectMax(),
                                                    IM_COL32(255, 255, 255, 255), 0, 0, 2);
            }
            ImGui::PopID();
            if (m % 16 != 15) {
                ImGui::SameLine(0, 2);
            }
        }
        ImGui::NewLine();
    }
    ImGui::PopTextWrapPos();
    ImGui::End();
}

namespace {

double mib(std::uint64_t bytes) {
    return double(bytes) / double(1 << 20);
}

}  // namespace

void draw_sparse_overlay(const SparseOverlayInfo& info, ViewControls& controls,
                         const ViewCamera& camera, const std::optional<Brush>& preview,
                         vk::RenderOptions& render, const Palette& palette, std::uint32_t fb_width,
                         std::uint32_t fb_height) {
    const ImGuiIO& io = ImGui::GetIO();
    ImDrawList* fg = ImGui::GetForegroundDrawList();
    const ImVec2 c(io.DisplaySize.x / 2, io.DisplaySize.y / 2);
    fg->AddLine(ImVec2(c.x - 8, c.y), ImVec2(c.x + 9, c.y), IM_COL32(255, 255, 255, 220), 2);
    fg->AddLine(ImVec2(c.x, c.y - 8), ImVec2(c.x, c.y + 9), IM_COL32(255, 255, 255, 220), 2);
    if (preview && fb_width > 0 && fb_height > 0) {
        draw_brush_preview(fg, *preview, camera, fb_width, fb_height, io.DisplaySize, palette);
    }
    ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_Always);
    ImGui::SetNextWindowBgAlpha(0.5f);
    ImGuiWindowFlags flags = ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_AlwaysAutoResize |
                             ImGuiWindowFlags_NoSavedSettings |
                             ImGuiWindowFlags_NoFocusOnAppearing | ImGuiWindowFlags_NoNav;
    if (!controls.full_panel) {
        flags |= ImGuiWindowFlags_NoInputs;
    }
    ImGui::Begin("##sparse", nullptr, flags);
    ImGui::Text("%.1f FPS  frame %.2f  trace %.3f ms",
                info.frame_ms > 0 ? 1000.0 / info.frame_ms : 0.0, info.frame_ms, info.trace_ms);
    ImGui::Text("sparse world: %s %s", info.world.c_str(), info.dims.to_string().c_str());
    ImGui::Text("  %u tiles of 64^3 stored (%.3g voxels), %.3g solid, 64-trees %.1f MiB",
                info.tiles, double(info.tiles) * double(kTileVoxels), double(info.solid),
                mib(info.world_bytes));
    ImGui::Text("  field: exact, bounded at %g, %s, %u tiles with values, %.1f MiB",
                info.max_distance, info.format.c_str(), info.field_tiles, mib(info.field_bytes));
    if (info.tracer.shared_bytes != 0) {
        ImGui::Text("  tracer: %.1f MiB of its own, reads %.1f MiB of OpenCL's trees in place (%s)",
                    mib(info.tracer.bytes), mib(info.tracer.shared_bytes), info.sharing.c_str());
    } else {
        ImGui::Text(
            "  tracer: %.1f MiB on the device; edit arena %u tiles, %.1f of %.1f MiB",
            mib(info.tracer.bytes), info.tracer.arena_tiles,
            mib(info.tracer.arena_nodes * 12 + info.tracer.arena_material_bytes),
            mib(info.tracer.arena_node_capacity * 12 + info.tracer.arena_material_capacity));
    }
    ImGui::Text(
        "edit %llu: %.3f ms (field kernels %.3f, read-back %.3f, tracer %.3f), tiles "
        "%u written, %u removed",
        static_cast<unsigned long long>(info.edits), info.edit_ms, info.field_kernel_ms,
        info.readback_ms, info.tracer_ms, info.tiles_written, info.tiles_removed);
    if (info.simulate) {
        ImGui::Text("sand%s: step %llu, %.3f ms, %llu voxels moved, tiles %u run, %u changed",
                    controls.sand_paused ? " (paused, N steps)" : "",
                    static_cast<unsigned long long>(info.sand_steps), info.sand_ms,
                    static_cast<unsigned long long>(info.sand_changed), info.sand_tiles_run,
                    info.sand_tiles_changed);
    }
    ImGui::Text("brush: %s %s, size %lld, colour %d; no undo on sparse worlds",
                controls.paint_mode ? "paint" : "place", to_string(controls.brush.shape).c_str(),
                static_cast<long long>(controls.brush.size), controls.brush.material);
    ImGui::Text("%s + %s; frames through the host; F1 keys, F2 widgets", info.vulkan.c_str(),
                info.opencl.c_str());
    if (controls.full_panel) {
        int shading = render.shading == vk::Shading::lit ? 1 : 0;
        const char* shadings[] = {"flat", "lit"};
        if (ImGui::Combo("shading", &shading, shadings, 2)) {
            set_shading(render, shading == 1 ? vk::Shading::lit : vk::Shading::flat);
        }
        for (int m = 1; m < 256; ++m) {
            const Rgba rgb = palette[static_cast<std::uint8_t>(m)];
            ImGui::PushID(m);
            if (ImGui::ColorButton("##colour",
                                   ImVec4(rgb.r / 255.0f, rgb.g / 255.0f, rgb.b / 255.0f, 1),
                                   ImGuiColorEditFlags_NoAlpha, ImVec2(14, 14))) {
                controls.brush.material = static_cast<std::uint8_t>(m);
            }
            ImGui::PopID();
            if (m % 32 != 31) {
                ImGui::SameLine(0, 2);
            }
        }
        ImGui::NewLine();
    }
    ImGui::End();
    if (controls.show_help) {
        ImGui::SetNextWindowPos(ImVec2(io.DisplaySize.x / 2, io.DisplaySize.y / 2),
                                ImGuiCond_Always, ImVec2(0.5f, 0.5f));
        ImGui::Begin("keys (F1)", &controls.show_help, ImGuiWindowFlags_AlwaysAutoResize);
        for (const auto& k : kViewKeys) {
            ImGui::Text("%-20s %s", k[0], k[1]);
        }
        ImGui::End();
    }
    ImGui::Render();
}

}  // namespace voxfield::cli
