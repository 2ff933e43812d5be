// The frame pipeline shared by render, view and bench (see frame_pipeline.hpp).
#include "voxfield/pipeline/frame_pipeline.hpp"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <utility>

#include "voxfield/core/error.hpp"

namespace voxfield::pipeline {
namespace {

// Many small boxes (a long stroke, many chunks) are converted as one launch over their hull.
constexpr std::size_t kMaxRegionsPerLaunch = 64;

std::vector<std::uint32_t> as_words(const std::vector<std::uint8_t>& bytes) {
    std::vector<std::uint32_t> words(bytes.size() / sizeof(std::uint32_t));
    std::memcpy(words.data(), bytes.data(), words.size() * sizeof(std::uint32_t));
    return words;
}

}  // namespace

FramePipeline::FramePipeline(ocl::Context& cl, vk::Context& vkc, Palette palette, Dims dims,
                             PipelineOptions options)
    : cl_(cl), palette_(palette), dims_(dims), pipeline_options_(options) {
    marcher_ = std::make_unique<vk::Raymarcher>(vkc, options.max_binding_bytes);
    if (options.render_format == vk::FieldFormat::compact) {
        render_field_ =
            std::make_unique<RenderField>(cl, vkc, *marcher_, dims, options.fastest_path);
    }
}

FramePipeline::~FramePipeline() {
    marcher_.reset();
}  // before the memory it reads

double FramePipeline::show(ocl::IncrementalField& field, const ocl::GeneratorOptions& options) {
    if (!render_field_) {
        // packed32: the field as generate writes it, plus the world's materials (path 3).
        marcher_->upload(field.world(), palette_, as_words(field.read()));
        marcher_->set_metric(options.metric);
        return 0;
    }
    return render_field_->attach(*marcher_, field.field_buffer(), options.format, options.metric,
                                 field.voxels_buffer(), palette_, options.spacing.largest());
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
    // The new field is complete before the old one goes: never a pipeline without one.
    auto field = std::make_unique<ocl::IncrementalField>(cl_, std::move(world), palette_, next);
    if (render_field_) {
        render_field_->detach();
    }
    try {
        show(*field, next);
    } catch (...) {
        if (field_) {
            show(*field_, options_);
        }
        throw;
    }
    field_ = std::move(field);
    options_ = next;
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

double FramePipeline::switch_field(const ocl::GeneratorOptions& options) {
    return rebuild(World(world()), options);
}

UpdateTimings FramePipeline::apply(const std::vector<Brush>& batch,
                                   std::vector<EditResult>* edits) {
    return finish(field_->apply(batch), edits);
}

UpdateTimings FramePipeline::apply_changes(const VoxelChanges& changes) {
    return finish(field_->apply_changes(changes), nullptr);
}

UpdateTimings FramePipeline::set_focus(const std::optional<Focus>& focus) {
    const ocl::UpdateStats s = field_->set_focus(focus);
    options_.focus = focus;
    UpdateTimings u;
    u.field_ms = s.update_ms;
    u.voxels_recomputed = s.voxels_recomputed;
    u.convert_ms = publish(s.regions);
    return u;
}

void FramePipeline::render(const vk::RenderOptions& options, vk::Image& out) {
    marcher_->render(options, out);
}

double FramePipeline::render_to(const vk::RenderOptions& options, const vk::ExternalMemory& frame) {
    return marcher_->render_to(options, frame);
}

const World& FramePipeline::world() const {
    return field_->world();
}

std::vector<std::uint8_t> FramePipeline::read_field() {
    return field_->read();
}

vk::SharingPath FramePipeline::sharing() const {
    return render_field_ ? render_field_->path() : vk::SharingPath::copy;
}

std::string FramePipeline::why_not() const {
    return render_field_ ? render_field_->why_not() : "packed32 is always copied (path 3)";
}

UpdateTimings FramePipeline::finish(ocl::UpdateStats s, std::vector<EditResult>* edits) {
    std::vector<Box> regions = s.regions;
    for (const EditResult& e : s.edits) {
        if (e.changed()) {
            regions.push_back(e.bounds);  // recoloured voxels keep their distance
        }
    }
    UpdateTimings u;
    u.field_ms = s.update_ms;
    u.voxels_recomputed = s.voxels_recomputed;
    u.full_regeneration = s.full_regeneration;
    u.convert_ms = publish(std::move(regions));
    if (edits != nullptr) {
        *edits = std::move(s.edits);
    }
    return u;
}

double FramePipeline::publish(std::vector<Box> regions) {
    if (regions.empty()) {
        return 0;
    }
    if (!render_field_) {
        show(*field_, options_);
        return 0;
    }
    if (regions.size() > kMaxRegionsPerLaunch) {
        Box hull = regions.front();
        for (const Box& b : regions) {
            hull.min = {std::min(hull.min.x, b.min.x), std::min(hull.min.y, b.min.y),
                        std::min(hull.min.z, b.min.z)};
            hull.max = {std::max(hull.max.x, b.max.x), std::max(hull.max.y, b.max.y),
                        std::max(hull.max.z, b.max.z)};
        }
        regions = {hull};
    }
    return render_field_->update(*marcher_, regions);
}

}  // namespace voxfield::pipeline
