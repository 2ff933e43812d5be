// Incremental field updates, host side: IncrementalField picks its engine (one file each:
// incremental_global.cpp, incremental_separable.cpp, incremental_chunks.cpp; what they share:
// incremental_engine.hpp).
#include "voxfield/cl/incremental.hpp"

#include <memory>
#include <string>

#include "incremental_engine.hpp"
#include "voxfield/cl/separable.hpp"

namespace voxfield::ocl {

struct IncrementalField::Impl {
    std::unique_ptr<incremental::Engine> engine;
};

IncrementalField::IncrementalField(Context& ctx, World world, const Palette& palette,
                                   const GeneratorOptions& options, std::uint32_t max_margin)
    : impl_(std::make_unique<Impl>()) {
    if (options.algorithm == Algorithm::exact && options.indices) {
        throw InputError(
            "incremental fields keep no feature transform (--indices); generate "
            "it with `voxfield generate --indices`");
    }
    // Bounded fields that the L1 sweeps compute unbounded take them, capped.
    GeneratorOptions unbounded = options;
    unbounded.max_distance.reset();
    const bool sweeps = options.metric == Metric::manhattan && !ExactSeparable::needed(unbounded);
    if (options.algorithm == Algorithm::exact && !sweeps) {
        impl_->engine = incremental::make_separable_engine(ctx, std::move(world), palette, options);
    } else if (options.algorithm == Algorithm::exact) {
        impl_->engine =
            incremental::make_global_engine(ctx, std::move(world), palette, options, max_margin);
    } else if (options.chunk != 0) {
        impl_->engine = incremental::make_chunk_engine(ctx, std::move(world), palette, options);
    } else {
        throw InputError("incremental updates of " + to_string(options.algorithm) +
                         " need chunk-local semantics (--chunk C); with global semantics use "
                         "exact, whose updates are exact and local");
    }
    impl_->engine->regenerate();
}

IncrementalField::~IncrementalField() = default;

double IncrementalField::regenerate() {
    return impl_->engine->rebuild();
}

void IncrementalField::fail_next_update_for_testing() {
    impl_->engine->fail_next = true;
}

UpdateStats IncrementalField::apply(const std::vector<Brush>& batch) {
    return impl_->engine->apply(batch);
}

UpdateStats IncrementalField::apply_changes(const VoxelChanges& changes) {
    return impl_->engine->apply_changes(changes);
}

const World& IncrementalField::world() {
    return impl_->engine->current_world();
}

UpdateStats IncrementalField::apply_device_changes(const DeviceChanges& changes) {
    return impl_->engine->apply_device_changes(changes);
}

std::vector<std::uint8_t> IncrementalField::read() {
    return cl_call("reading the field", [&] {
        std::vector<std::uint8_t> bytes(impl_->engine->world.size() *
                                        element_size(impl_->engine->options.format));
        impl_->engine->ctx.queue().enqueueReadBuffer(impl_->engine->out, CL_TRUE, 0, bytes.size(),
                                                     bytes.data());
        return bytes;
    });
}

const cl::Buffer& IncrementalField::field_buffer() const {
    return impl_->engine->out;
}

const cl::Buffer& IncrementalField::voxels_buffer() const {
    return impl_->engine->voxels_buffer();
}

UpdateStats IncrementalField::set_focus(std::optional<Focus> focus) {
    return impl_->engine->set_focus(focus);
}

}  // namespace voxfield::ocl
