// The separable engine of IncrementalField: L-inf, L2, spacing and signed fields by
// ExactSeparable's incremental passes (Meijster et al. 2000; kernels: exact_separable.cl).
#include "incremental_engine.hpp"

#include "voxfield/cl/separable.hpp"

namespace voxfield::ocl::incremental {
namespace {

// Every other exact field (chebyshev, euclidean, spacing, signed; ExactSeparable): the batch's
// changed voxels are scattered into the device world, then ExactSeparable::update
// recomputes exactly the rows and lines whose input changed, for the hull of the batch's
// edits.
class SeparableEngine : public Engine {
  public:
    SeparableEngine(Context& c, World w, const Palette& palette, const GeneratorOptions& o)
        : Engine(c, std::move(w), palette, o, false),
          sep(std::make_unique<ExactSeparable>(ctx, world, palette, o, true)) {
        out = sep->field_buffer();
    }

    double regenerate() override { return sep->run(); }

    void update(UpdateStats& stats) override {
        // Runs of consecutive edits whose boxes lie close together share one update of their
        // hull; edits far apart (two strokes at opposite corners) are updated one run at a
        // time, each after its own voxels were written, so that none recomputes the space
        // between them.
        struct Run {
            std::size_t first = 0, last = 0;  // edits [first, last]
            Box box;
            std::int64_t volume = 0;  // the sum of its edits' box volumes
        };
        std::vector<Run> runs;
        std::int64_t recomputed = 0;
        for (std::size_t e = 0; e < stats.edits.size(); ++e) {
            const Box& b = stats.edits[e].bounds;
            if (b.empty()) {
                continue;
            }
            if (!runs.empty() && hull(runs.back().box, b).volume() <=
                                     kRunSlack * (runs.back().volume + b.volume())) {
                Run& r = runs.back();
                recomputed -= r.box.volume();
                r.last = e;
                r.box = hull(r.box, b);
                r.volume += b.volume();
            } else {
                runs.push_back({e, e, b, b.volume()});
            }
            recomputed += runs.back().box.volume();
        }
        if (runs.empty()) {
            return;
        }
        if (regenerate_instead(recomputed)) {
            // The changed voxels straight from the host world (nothing staged per voxel).
            cl_call("regenerating the field of " + world.dims().to_string(), [&] {
                Events events;
                for (const Run& r : runs) {
                    upload_box(events, sep->voxels_buffer(), r.box);
                }
                check_injected_failure();
                ctx.queue().finish();
                stats.update_ms = elapsed_ms(events.front(), events.back()) + sep->run();
            });
            regenerated(stats);
            return;
        }
        std::vector<std::size_t> first;
        stage(stats, first);
        cl_call("updating the field of " + world.dims().to_string(), [&] {
            Events events = upload();
            for (const Run& r : runs) {
                for (std::size_t e = r.first; e <= r.last; ++e) {
                    if (stats.edits[e].changed()) {
                        scatter(events, sep->voxels_buffer(), stats, first, e);
                    }
                }
                const ExactSeparable::Update u = sep->update(r.box, events);
                stats.voxels_recomputed += u.voxels_recomputed;
                if (!u.changed.empty()) {
                    stats.regions.push_back(u.changed);
                }
            }
            check_injected_failure();
            ctx.queue().finish();
            stats.update_ms = elapsed_ms(events.front(), events.back());
        });
    }

    void device_update(const DeviceChanges& c, UpdateStats& stats) override {
        if (c.overflow() || regenerate_instead(c.bounds.volume())) {
            check_injected_failure();
            stats.update_ms = sep->run();
            regenerated(stats);
            return;
        }
        Events events;
        const ExactSeparable::Update u = sep->update(c.bounds, events);
        stats.voxels_recomputed = u.voxels_recomputed;
        if (!u.changed.empty()) {
            stats.regions.push_back(u.changed);
        }
        check_injected_failure();
        ctx.queue().finish();
        stats.update_ms = events.empty() ? 0 : elapsed_ms(events.front(), events.back());
    }

    UpdateStats move_focus(const std::optional<Focus>&) override { no_focus_in_exact(); }

    const cl::Buffer& voxels_buffer() const override { return sep->voxels_buffer(); }

  private:
    std::unique_ptr<ExactSeparable> sep;
};

}  // namespace

std::unique_ptr<Engine> make_separable_engine(Context& ctx, World world, const Palette& palette,
                                              const GeneratorOptions& options) {
    return std::make_unique<SeparableEngine>(ctx, std::move(world), palette, options);
}

}  // namespace voxfield::ocl::incremental
