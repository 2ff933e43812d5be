// The frame pipeline shared by render, view and bench (see frame_pipeline.hpp).
#include "voxfield/pipeline/frame_pipeline.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <stdexcept>
#include <utility>

#include "voxfield/core/error.hpp"

namespace voxfield::pipeline {
namespace {

// The most boxes converted one launch each (a long stroke, many chunks): more are merged.
constexpr std::size_t kMaxRegionsPerLaunch = 64;

std::vector<std::uint32_t> as_words(const std::vector<std::uint8_t>& bytes) {
    std::vector<std::uint32_t> words(bytes.size() / sizeof(std::uint32_t));
    std::memcpy(words.data(), bytes.data(), words.size() * sizeof(std::uint32_t));
    return words;
}

}  // namespace

FramePipeline::FramePipeline(ocl::Context& cl, vk::Context& vkc, Palette palette, Dims dims,
                             PipelineOptions options)
    : cl_(cl), vk_(vkc), palette_(palette), dims_(dims) {
    marcher_ = std::make_unique<vk::Raymarcher>(vkc, options.max_binding_bytes);
    if (options.render_format == vk::FieldFormat::compact) {
        render_field_ =
            std::make_unique<RenderField>(cl, vkc, *marcher_, dims, options.fastest_path);
    }
}

FramePipeline::~FramePipeline() {
    marcher_.reset();
}  // before the memory it reads

double FramePipeline::show(Scene& scene) {
    const ocl::GeneratorOptions& options = scene.options();
    if (failing_shows_ > 0) {
        --failing_shows_;
        throw ocl::ClError("clEnqueueNDRangeKernel", CL_OUT_OF_RESOURCES,
                           "a failure injected by FramePipeline::fail_next_shows_for_testing");
    }
    if (!render_field_) {
        // packed32: the field as generate writes it, plus the world's materials (path 3).
        marcher_->upload(scene.world(), palette_, as_words(scene.read_field()));
        marcher_->set_metric(options.metric);
        return 0;
    }
    return render_field_->attach(*marcher_, scene.field_buffer(), options.format, options.metric,
                                 scene.voxels_buffer(), palette_, options.spacing.largest());
}

Scene& FramePipeline::current() {
    if (!scene_) {
        throw std::logic_error("FramePipeline: no field yet (rebuild() has not succeeded)");
    }
    if (!shown_) {
        // A failed rebuild could not show the previous field again: shown now, or the update
        // stops here.
        show(*scene_);
        shown_ = true;
    }
    return *scene_;
}

double FramePipeline::rebuild(World world, const ocl::GeneratorOptions& options) {
    const auto t = std::chrono::steady_clock::now();
    if (world.dims() != dims_) {
        throw InputError("a world of " + world.dims().to_string() + " for a pipeline of " +
                         dims_.to_string());
    }
    ocl::GeneratorOptions next = options;
    if (!render_field_) {
        next.format = Format::packed32;
    }
    next = ocl::resolve_options(next, world.dims());
    // The new scene is complete before the old one goes: never a pipeline without one.
    auto scene = std::make_unique<Scene>(cl_, std::move(world), palette_, next);
    if (render_field_) {
        render_field_->detach();
        shown_ = false;
    }
    try {
        show(*scene);
    } catch (...) {
        if (scene_) {
            try {
                show(*scene_);
                shown_ = true;
            } catch (const std::exception&) {
                // The first error is the one reported; the next update shows it again.
            }
        }
        throw;
    }
    scene_ = std::move(scene);
    shown_ = true;
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

double FramePipeline::switch_field(const ocl::GeneratorOptions& options) {
    return rebuild(World(world()), options);
}

UpdateTimings FramePipeline::apply(const std::vector<Brush>& batch, std::vector<EditResult>* edits,
                                   std::size_t undoable) {
    return finish(current().apply_stroke(batch, undoable), edits);
}

UpdateTimings FramePipeline::apply_changes(const VoxelChanges& changes) {
    return finish(current().apply_changes(changes), nullptr);
}

UpdateTimings FramePipeline::undo() {
    return finish(current().undo(), nullptr);
}

UpdateTimings FramePipeline::redo() {
    return finish(current().redo(), nullptr);
}

UpdateTimings FramePipeline::step_sand(const SandRules& rules, std::uint64_t seed,
                                       std::uint64_t step) {
    return finish(current().step_sand(rules, seed, step), nullptr);
}

UpdateTimings FramePipeline::set_focus(const std::optional<Focus>& focus) {
    return finish(current().set_focus(focus), nullptr);
}

void FramePipeline::render(const vk::RenderOptions& options, vk::Image& out) {
    marcher_->render(options, out);
}

double FramePipeline::render_to(const vk::RenderOptions& options, const vk::ExternalMemory& frame) {
    return marcher_->render_to(options, frame);
}

double FramePipeline::march(const vk::RenderOptions& options) {
    std::erase_if(marched_, [&](std::uint64_t serial) { return vk_.finished(serial); });
    if (marched_.size() >= kFramesInFlight) {
        vk_.wait_for(marched_.front());
        marched_.erase(marched_.begin());
    }
    marched_.push_back(vk_.submit_unwaited(
        [&](VkCommandBuffer cmd) { marcher_->record(cmd, options); }, "a headless frame"));
    return marcher_->finished_raymarch_ms();
}

const World& FramePipeline::world() const {
    if (!scene_) {
        throw std::logic_error("FramePipeline: no world yet (rebuild() has not succeeded)");
    }
    return scene_->world();
}

const ocl::GeneratorOptions& FramePipeline::options() const {
    static const ocl::GeneratorOptions none;
    return scene_ ? scene_->options() : none;
}

const World& FramePipeline::last_read_world() const {
    if (!scene_) {
        throw std::logic_error("FramePipeline: no world yet (rebuild() has not succeeded)");
    }
    return scene_->last_read_world();
}

Scene& FramePipeline::scene() {
    return current();
}

std::vector<std::uint8_t> FramePipeline::read_field() {
    return current().read_field();
}

vk::SharingPath FramePipeline::sharing() const {
    return render_field_ ? render_field_->path() : vk::SharingPath::copy;
}

std::string FramePipeline::why_not() const {
    return render_field_ ? render_field_->why_not() : "packed32 is always copied (path 3)";
}

FieldSync FramePipeline::sync() const {
    return render_field_ ? render_field_->sync() : FieldSync::queue;
}

std::string FramePipeline::sync_why_not() const {
    return render_field_ ? render_field_->sync_why_not() : "packed32 is always copied (path 3)";
}

UpdateTimings FramePipeline::finish(SceneUpdate s, std::vector<EditResult>* edits) {
    UpdateTimings u;
    u.field_ms = s.stats.update_ms;
    u.voxels_recomputed = s.stats.voxels_recomputed;
    u.full_regeneration = s.stats.full_regeneration;
    u.simulate_ms = s.simulate_ms;
    u.voxels_changed = s.voxels_changed;
    u.convert_ms = publish(std::move(s.changed));
    if (edits != nullptr) {
        *edits = std::move(s.stats.edits);
    }
    return u;
}

double FramePipeline::publish(std::vector<Box> regions) {
    if (regions.empty()) {
        return 0;
    }
    if (!render_field_) {
        // packed32 (path 3): the changed boxes' words and materials, copied in place.
        update_packed32(cl_, *marcher_, scene_->field_buffer(), scene_->voxels_buffer(), dims_,
                        regions);
        return 0;
    }
    // Two launches per box: boxes merge while that converts fewer extra voxels than a launch
    // costs (about 100 us on a CPU device, 5 us on a GPU, in voxels of conversion).
    const std::int64_t launch_voxels = cl_.is_cpu() ? std::int64_t{1} << 16 : std::int64_t{1} << 19;
    return render_field_->update(
        *marcher_, merge_for_launches(std::move(regions), launch_voxels, kMaxRegionsPerLaunch));
}

}  // namespace voxfield::pipeline
