// Incremental field updates, host side (kernels: cl/kernels/incremental.cl for the global
// exact field, the per-chunk batch kernel of monolithic.cl for chunk-local algorithms).
#include "voxfield/cl/incremental.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>

#include "classic.hpp"
#include "util.hpp"
#include "voxfield/cl/exact.hpp"
#include "voxfield/cl/separable.hpp"
#include "voxfield/core/dirty.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/undo.hpp"

namespace voxfield::cl_sources {
extern const char* const layout_h;
extern const char* const classic_common_cl;
extern const char* const incremental_cl;
}  // namespace voxfield::cl_sources

namespace voxfield::ocl {
namespace {

// The blocks a GPU work-group of inc_bounds or inc_place takes at most (incremental.cl's
// VF_GROUP, passed as a build option), where one block per work-group would launch too many.
constexpr std::size_t kGroupBlocks = 8;

[[noreturn]] void no_focus_in_exact() {
    throw InputError(
        "exact has no focus to move: only the chunk-local lod and monolithic run FIM in a focus");
}

cl_int4 int4_of(const Int3& v) {
    return {{static_cast<cl_int>(v.x), static_cast<cl_int>(v.y), static_cast<cl_int>(v.z), 0}};
}

// What both updaters share: the host world, the output buffer, staging and uploading the
// changed voxels, and the enqueue helpers.
class Engine {
  public:
    Engine(Context& c, World w, const Palette& palette, const GeneratorOptions& o)
        : ctx(c), world(std::move(w)), options(o) {
        const Dims dims = world.dims();
        if (dims.count() >= 0x7FFFFFFFu) {
            throw InputError("incremental updates index voxels with 31 bits; world " +
                             dims.to_string() + " is too large");
        }
        d = {{static_cast<cl_int>(dims.x), static_cast<cl_int>(dims.y), static_cast<cl_int>(dims.z),
              0}};
        program = ctx.program(
            "incremental",
            {cl_sources::layout_h, cl_sources::classic_common_cl, cl_sources::incremental_cl},
            output_options(o.format) + " -DVF_GROUP=" + std::to_string(kGroupBlocks));
        cl_call("allocating the output of " + dims.to_string(), [&] {
            const auto table = palette.rgb332_table();
            rgb = cl::Buffer(ctx.context(), CL_MEM_READ_ONLY, 256);
            ctx.queue().enqueueWriteBuffer(rgb, CL_TRUE, 0, 256, table.data());
            out =
                cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, dims.count() * element_size(o.format));
        });
    }
    virtual ~Engine() = default;
    Engine(const Engine&) = delete;
    Engine& operator=(const Engine&) = delete;

    virtual double regenerate() = 0;

    // Applies the brushes (in order) or the voxel changes (one edit) to the host world, then
    // updates the device. All or nothing: on a throw the world, the device voxels and the
    // field are those from before the call (see restore()).
    UpdateStats apply(const std::vector<Brush>& batch) {
        require_intact();
        UpdateStats stats;
        try {
            for (const Brush& brush : batch) {
                stats.edits.push_back(apply_brush(world, brush));
            }
            update(stats);
        } catch (...) {
            restore(stats.edits);
            throw;
        }
        return stats;
    }
    UpdateStats apply_changes(const VoxelChanges& voxel_changes) {
        require_intact();
        UpdateStats stats;
        // Throws InputError, changing nothing, when a voxel does not hold its `before` value.
        stats.edits.push_back(voxfield::apply_changes(world, voxel_changes));
        try {
            update(stats);
        } catch (...) {
            restore(stats.edits);
            throw;
        }
        return stats;
    }
    // Moves the focus (chunk-local lod and monolithic), all or nothing like apply().
    UpdateStats set_focus(const std::optional<Focus>& focus) {
        require_intact();
        return move_focus(focus);
    }

    // Regenerates the field from the host world, uploaded whole first when a failed update
    // left the device voxels in doubt; returns the device time in ms.
    double rebuild() {
        if (broken) {
            cl_call("uploading the world " + world.dims().to_string(), [&] {
                ctx.queue().enqueueWriteBuffer(voxels_buffer(), CL_TRUE, 0, world.size(),
                                               world.voxels().data());
            });
        }
        const double ms = regenerate();
        broken = false;
        return ms;
    }

    // Test seam (IncrementalField::fail_next_update_for_testing): the next update throws
    // ClError at check_injected_failure().
    bool fail_next = false;
    // The device world that apply() keeps current.
    virtual const cl::Buffer& voxels_buffer() const = 0;

    Context& ctx;
    World world;
    GeneratorOptions options;
    cl::Buffer out;

  protected:
    using Events = std::vector<cl::Event>;

    Box world_box() const {
        const Dims n = world.dims();
        return Box{{0, 0, 0}, {n.x, n.y, n.z}};
    }

    // Whether a batch whose changes span `changed` is cheaper as a full regeneration: the
    // update recomputes at least the lines through that box, and the full transform runs
    // several times faster per voxel than the update's region passes, so from an eighth of
    // the world on (a step of falling sand all over it, say) the whole transform wins.
    // (For a bounded field the update would touch the voxels within D of the changes: most of
    // the world too. Edits smaller than that stay local, whatever the world's size.)
    bool regenerate_instead(const Box& changed) const {
        return static_cast<std::uint64_t>(changed.volume()) * kRegenerateFraction >=
               static_cast<std::uint64_t>(world.size());
    }
    static constexpr std::uint64_t kRegenerateFraction = 8;

    // Grows a device buffer to hold at least `bytes`.
    void reserve(cl::Buffer& buffer, std::size_t& capacity, std::size_t bytes) {
        if (bytes > capacity) {
            capacity = std::max(bytes, 2 * capacity);
            buffer = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, capacity);
        }
    }

    // Brings the device up to date with stats.edits, already applied to the host world, and
    // fills in the rest of stats.
    virtual void update(UpdateStats& stats) = 0;
    virtual UpdateStats move_focus(const std::optional<Focus>& focus) = 0;

    // Where an update waits for its commands: a failure injected by the test seam is thrown
    // there, after the update enqueued its work and before it waits for it (as a failing
    // enqueue of its last command would).
    void check_injected_failure() {
        if (fail_next) {
            fail_next = false;
            throw ClError("clEnqueueNDRangeKernel", CL_OUT_OF_RESOURCES,
                          "a device failure injected by IncrementalField::"
                          "fail_next_update_for_testing");
        }
    }

    // After a failed update: the host world goes back to its state before the batch (the
    // edits' changes undone in reverse order), then the device voxels and the field are
    // rebuilt from it, so that the object is as before the call. Where the device fails
    // again the object is marked broken: every update throws until rebuild() succeeds.
    void restore(const std::vector<EditResult>& edits) {
        broken = true;
        try {
            ctx.queue().finish();  // nothing in flight reads or writes what is rebuilt below
        } catch (const cl::Error&) {
            // A queue that cannot even finish: rebuild() below reports it, or fails too.
        }
        for (auto e = edits.rbegin(); e != edits.rend(); ++e) {
            for (auto c = e->changes.rbegin(); c != e->changes.rend(); ++c) {
                world.voxels()[c->index] = c->before;
            }
        }
        try {
            rebuild();
        } catch (const std::exception&) {
            // The first error is the one reported; `broken` stays set.
        }
    }

    void require_intact() const {
        if (broken) {
            throw ClError("IncrementalField", CL_INVALID_OPERATION,
                          "a failed update left the device field of " + world.dims().to_string() +
                              " out of step with the world, and restoring it failed too; "
                              "regenerate() rebuilds it");
        }
    }
    bool broken = false;

    // The edits' changed voxels as (index, value) pairs into `staging`, `first` saying where
    // each edit's pairs start. A member, as every host array a transfer reads or writes
    // without blocking: after a failed enqueue the queue may still use it (restore() waits).
    std::vector<cl_uint>& stage(const UpdateStats& stats, std::vector<std::size_t>& first) {
        staging.clear();
        for (const EditResult& edit : stats.edits) {
            first.push_back(staging.size() / 2);
            for (const VoxelChange& c : edit.changes) {
                staging.push_back(static_cast<cl_uint>(c.index));
                staging.push_back(c.after);
            }
        }
        return staging;
    }

    // One write of everything staged; its event starts the batch's event list.
    Events upload() {
        reserve(changes, changes_capacity, 4 * staging.size());
        Events events(1);
        ctx.queue().enqueueWriteBuffer(changes, CL_FALSE, 0, 4 * staging.size(), staging.data(),
                                       nullptr, &events[0]);
        return events;
    }

    // Writes edit e's new voxel values into the device world `vox` (edits in order, so a
    // voxel changed twice in a batch ends with its last value).
    void scatter(Events& events, const cl::Buffer& vox, const UpdateStats& stats,
                 const std::vector<std::size_t>& first, std::size_t e) {
        cl::Kernel& k = kernel("inc_scatter");
        k.setArg(0, vox);
        k.setArg(1, changes);
        k.setArg(2, static_cast<cl_uint>(first[e]));
        k.setArg(3, static_cast<cl_uint>(stats.edits[e].changes.size()));
        enqueue(events, k, cl::NDRange(stats.edits[e].changes.size()));
    }

    // The kernel `name` of `program`, created once: creating one per launch costs an update
    // more than some of its kernels take. (Arguments are captured when a launch is enqueued.)
    cl::Kernel& kernel(const char* name) {
        auto it = kernels.find(name);
        if (it == kernels.end()) {
            it = kernels.emplace(name, cl::Kernel(program, name)).first;
        }
        return it->second;
    }

    // Fixed work-group shapes, the global size rounded up to them (the kernels skip what is
    // outside): edits of every size then reuse one compiled work-group function (PoCL
    // specialises kernels per local size).
    void enqueue(Events& events, cl::Kernel& k, const cl::NDRange& global) {
        static const std::size_t shapes[3][3] = {{64, 1, 1}, {16, 4, 1}, {64, 1, 1}};
        const std::size_t dims = global.dimensions();
        const std::size_t* shape = shapes[dims - 1];
        std::size_t g[3] = {1, 1, 1};
        for (std::size_t i = 0; i < dims; ++i) {
            g[i] = (global[i] + shape[i] - 1) / shape[i] * shape[i];
        }
        const cl::NDRange rounded = dims == 1   ? cl::NDRange(g[0])
                                    : dims == 2 ? cl::NDRange(g[0], g[1])
                                                : cl::NDRange(g[0], g[1], g[2]);
        const cl::NDRange local = dims == 1   ? cl::NDRange(shape[0])
                                  : dims == 2 ? cl::NDRange(shape[0], shape[1])
                                              : cl::NDRange(shape[0], shape[1], shape[2]);
        events.emplace_back();
        ctx.queue().enqueueNDRangeKernel(k, cl::NullRange, rounded, local, nullptr, &events.back());
    }

    // `count` independent work-items in groups of one (each does a whole slice or row).
    void enqueue_items(Events& events, cl::Kernel& k, std::size_t count) {
        events.emplace_back();
        ctx.queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(count), cl::NDRange(1),
                                         nullptr, &events.back());
    }

    static cl::NDRange range_of(const Box& b) {
        return cl::NDRange(static_cast<std::size_t>(b.max.x - b.min.x),
                           static_cast<std::size_t>(b.max.y - b.min.y),
                           static_cast<std::size_t>(b.max.z - b.min.z));
    }

    static Int3 size_of(const Box& b) {
        return {b.max.x - b.min.x, b.max.y - b.min.y, b.max.z - b.min.z};
    }

    cl::Program program;
    std::map<std::string, cl::Kernel, std::less<>> kernels;  // kernel()'s
    std::vector<cl_uint> staging;
    cl::Buffer rgb, changes;
    std::size_t changes_capacity = 0;
    cl_int4 d{};
};

// Global semantics, exact: see incremental.hpp.
class GlobalEngine : public Engine {
  public:
    GlobalEngine(Context& c, World w, const Palette& palette, const GeneratorOptions& o,
                 std::uint32_t margin)
        : Engine(c, std::move(w), palette, o),
          max_margin(std::min<std::uint32_t>(
              margin, std::max({world.dims().x, world.dims().y, world.dims().z}))),
          cpu_layout(o.layout == Layout::automatic ? ctx.is_cpu() : o.layout == Layout::cpu),
          exact(std::make_unique<ExactManhattan>(ctx, world, palette, Format::u32, o.layout,
                                                 Metric::manhattan, o.max_distance)),
          bound(o.max_distance
                    ? static_cast<cl_uint>(std::min(std::floor(*o.max_distance), 4294967294.0))
                    : kFar),
          direct(std::make_unique<ExactManhattan>(ctx, world.dims(), exact->voxels_buffer(), out,
                                                  palette, o.format, o.layout, o.max_distance)) {
        if (bound != kFar) {
            // R lies within floor(D) of B (old distances are capped there): a cap box one block
            // wider holds it, and never sets overflow (its face blocks are farther than D).
            max_margin = static_cast<std::uint32_t>(
                std::min<std::uint64_t>(max_margin, std::uint64_t{bound} + kBlock + 1));
        }
        cl_call("allocating the incremental buffers of " + world.dims().to_string(), [&] {
            tmp = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, 4 * world.size());
            // Written once here, so that its pages are in memory before the first updates
            // (on a CPU device the first write of a page faults it in, a 2 MiB huge page at a
            // time: otherwise the x sweeps of the first edits in each part of the world pay it).
            ctx.queue().enqueueFillBuffer(tmp, cl_uint{0}, 0, 4 * world.size());
            block_max =
                cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, 4 * blocks_of(world_box()).volume());
            ctx.queue().finish();
        });
    }

    double regenerate() override {
        exact_stale = false;
        return cl_call("regenerating the field of " + world.dims().to_string(), [&] {
            exact->run();
            Events events;
            encode_box(events, world_box());
            update_block_max(events, blocks_of(world_box()), -1);
            ctx.queue().finish();
            // The exact transform's own kernels ran first; add their time.
            double ms = elapsed_ms(events.front(), events.back());
            for (const auto& stage : exact->stage_ms()) {
                ms += stage.second;
            }
            return ms;
        });
    }

    void update(UpdateStats& stats) override {
        std::vector<std::size_t> first;
        if (stage(stats, first).empty()) {
            return;
        }
        Box occupancy;
        for (const EditResult& r : stats.edits) {
            if (r.occupancy_changed()) {
                occupancy = hull(occupancy, r.occupancy_bounds);
            }
        }
        const bool regenerate_all = !occupancy.empty() && regenerate_instead(occupancy);
        // Unless the batch regenerates, every edit that changes occupancy has a box field
        // staged after the pairs (one upload): edits that only place solids take inc_place
        // with the field of B's solids, the rest the sweeps, with the field of the voxels whose
        // occupancy they changed.
        std::vector<std::size_t> field_at(stats.edits.size(), 0);
        for (std::size_t e = 0; e < stats.edits.size() && !regenerate_all; ++e) {
            const EditResult& r = stats.edits[e];
            if (r.occupancy_changed()) {
                field_at[e] = staging.size();
                append_box_field(staging, stats.edits, e, places_only(r));
            }
        }
        // Then, 8-aligned, each edit's 8 ints of W (inc_bounds' encoding) zeroed, which its
        // kernels accumulate (atomic_max; atomic_add for the voxels read): slot regions_at + e
        // of the changes buffer.
        const std::size_t regions_at = (staging.size() + 7) / 8;
        if (!regenerate_all) {
            staging.resize(8 * (regions_at + stats.edits.size()), 0);
        }
        cl_call("updating the field of " + world.dims().to_string(), [&] {
            auto& q = ctx.queue();
            Events events = upload();
            if (regenerate_all) {
                // The output straight from the sweeps in its own format; the exact u32 field
                // and its block maxima, which only incremental updates read, are brought up to
                // date before the next one (a run of world-spanning batches skips them).
                for (std::size_t e = 0; e < stats.edits.size(); ++e) {
                    if (stats.edits[e].changed()) {
                        scatter(events, exact->voxels_buffer(), stats, first, e);
                    }
                }
                check_injected_failure();
                q.finish();
                stats.update_ms = elapsed_ms(events.front(), events.back()) + direct->run();
                exact_stale = true;
                stats.full_regeneration = true;
                stats.regions = {world_box()};
                stats.voxels_recomputed = world.size();
                return;
            }
            double refresh_ms = 0;
            if (exact_stale) {
                // The device voxels hold the world before this batch (its changes are only
                // staged): the u32 field and block maxima the sweeps start from are brought
                // to that world first.
                q.finish();
                refresh_ms = refresh_exact();
            }
            std::vector<std::size_t> swept;  // edits whose distances were recomputed
            for (std::size_t e = 0; e < stats.edits.size(); ++e) {
                const EditResult& r = stats.edits[e];
                if (!r.changed()) {
                    continue;
                }
                const std::size_t slot = regions_at + e;
                if (places_only(r)) {
                    // inc_place writes the edit's voxels itself, unless its encoding reads them
                    // (packed32's colours).
                    const bool packed = options.format == Format::packed32;
                    if (packed) {
                        scatter(events, exact->voxels_buffer(), stats, first, e);
                    }
                    enqueue_place(events, r.occupancy_bounds, field_at[e], slot, first[e],
                                  packed ? 0 : r.changes.size());
                    swept.push_back(e);
                } else if (r.occupancy_changed()) {
                    // inc_bounds writes the edit's voxels.
                    enqueue_sweeps(events, r.occupancy_bounds, field_at[e], slot, first[e],
                                   r.changes.size());
                    swept.push_back(e);
                } else {
                    scatter(events, exact->voxels_buffer(), stats, first, e);  // recoloured
                }
                if (options.format == Format::packed32) {
                    encode_box(events, r.bounds);  // colours of recoloured voxels
                }
            }
            found.assign(8 * stats.edits.size(), 0);
            if (!swept.empty()) {
                q.enqueueReadBuffer(changes, CL_FALSE, 4 * 8 * regions_at, 4 * found.size(),
                                    found.data());
            }
            check_injected_failure();
            q.finish();
            stats.update_ms = elapsed_ms(events.front(), events.back()) + refresh_ms;
            for (const std::size_t e : swept) {
                const cl_int* g = found.data() + 8 * e;
                stats.full_regeneration |= g[6] != 0;
                const Box w{{d.s[0] - g[0], d.s[1] - g[1], d.s[2] - g[2]}, {g[3], g[4], g[5]}};
                stats.regions.push_back(w);
                // inc_place counts the voxels it read; the sweeps recompute all of W.
                stats.voxels_recomputed += places_only(stats.edits[e])
                                               ? static_cast<std::uint64_t>(g[7])
                                               : static_cast<std::uint64_t>(w.volume());
            }
            if (stats.full_regeneration) {
                // A region reached past max_margin: what was computed for it is incomplete.
                stats.update_ms += regenerate();
                stats.regions = {world_box()};
                stats.voxels_recomputed = world.size();
            }
        });
    }

    UpdateStats move_focus(const std::optional<Focus>&) override { no_focus_in_exact(); }

    const cl::Buffer& voxels_buffer() const override { return exact->voxels_buffer(); }

  private:
    static bool places_only(const EditResult& r) {
        return r.became_solid != 0 && r.became_empty == 0;
    }

    // Appends to `data` the box field of edit e: the exact L1 distance, inside the edit's
    // occupancy box B (x fastest; VF_FAR without a source), to sources in B, exact from B's
    // voxels alone since an L1 shortest path between two voxels of a box stays in the box;
    // then the 27 minima described below. Sources: `solids`, the solids of B in the world as
    // edit e left it (the host world with the later edits' changes undone); otherwise the
    // voxels whose occupancy edit e changed.
    void append_box_field(std::vector<cl_uint>& data, const std::vector<EditResult>& edits,
                          std::size_t e, bool solids) const {
        const Box b = edits[e].occupancy_bounds;
        const Int3 n = size_of(b);
        const auto nx = static_cast<std::size_t>(n.x), ny = static_cast<std::size_t>(n.y),
                   nz = static_cast<std::size_t>(n.z);
        const Dims dims = world.dims();
        const std::size_t base = data.size();
        data.resize(base + nx * ny * nz + 27);
        cl_uint* f = data.data() + base;
        // The element of f at the voxel with linear index i, or nullptr outside B.
        const auto at = [&](std::size_t i) -> cl_uint* {
            const auto x = static_cast<std::int64_t>(i % dims.x);
            const auto y = static_cast<std::int64_t>(i / dims.x % dims.y);
            const auto z = static_cast<std::int64_t>(i / dims.x / dims.y);
            if (x < b.min.x || x >= b.max.x || y < b.min.y || y >= b.max.y || z < b.min.z ||
                z >= b.max.z) {
                return nullptr;
            }
            return f +
                   (static_cast<std::size_t>(z - b.min.z) * ny +
                    static_cast<std::size_t>(y - b.min.y)) *
                       nx +
                   static_cast<std::size_t>(x - b.min.x);
        };
        if (solids) {
            for (std::size_t z = 0; z < nz; ++z) {
                for (std::size_t y = 0; y < ny; ++y) {
                    const std::size_t src =
                        (static_cast<std::size_t>(b.min.z) + z) * dims.x * dims.y +
                        (static_cast<std::size_t>(b.min.y) + y) * dims.x +
                        static_cast<std::size_t>(b.min.x);
                    for (std::size_t x = 0; x < nx; ++x) {
                        f[(z * ny + y) * nx + x] = world.voxels()[src + x] != 0 ? 0 : kFar;
                    }
                }
            }
            for (std::size_t k = edits.size(); k-- > e + 1;) {
                for (auto c = edits[k].changes.rbegin(); c != edits[k].changes.rend(); ++c) {
                    if (cl_uint* v = at(c->index)) {
                        *v = c->before != 0 ? 0 : kFar;
                    }
                }
            }
        } else {
            std::fill(f, f + nx * ny * nz, kFar);
            for (const VoxelChange& c : edits[e].changes) {
                if ((c.before != 0) != (c.after != 0)) {
                    *at(c.index) = 0;  // inside B, the box of exactly these voxels
                }
            }
        }
        // Forward and backward min-plus sweeps along x, y and z.
        auto sweep = [&](std::size_t start, std::size_t count, std::size_t stride) {
            cl_uint run = kFar;
            for (std::size_t i = 0; i < count; ++i) {
                cl_uint& v = f[start + i * stride];
                run = std::min(v, run == kFar ? kFar : run + 1);
                v = run;
            }
            run = kFar;
            for (std::size_t i = count; i-- > 0;) {
                cl_uint& v = f[start + i * stride];
                run = std::min(v, run == kFar ? kFar : run + 1);
                v = run;
            }
        };
        for (std::size_t z = 0; z < nz; ++z) {
            for (std::size_t y = 0; y < ny; ++y) {
                sweep((z * ny + y) * nx, nx, 1);
            }
        }
        for (std::size_t z = 0; z < nz; ++z) {
            for (std::size_t x = 0; x < nx; ++x) {
                sweep(z * ny * nx + x, ny, nx);
            }
        }
        for (std::size_t y = 0; y < ny; ++y) {
            for (std::size_t x = 0; x < nx; ++x) {
                sweep(y * nx + x, nz, nx * ny);
            }
        }
        // The least f over each part of B's boundary, (side.z * 3 + side.y) * 3 + side.x with
        // per axis side 0: the low face, 1: any coordinate, 2: the high face.
        const std::size_t n_axis[3] = {nx, ny, nz};
        for (std::size_t part = 0; part < 27; ++part) {
            std::size_t lo[3], hi[3];
            for (std::size_t a = 0, side = part; a < 3; ++a, side /= 3) {
                lo[a] = side % 3 == 2 ? n_axis[a] - 1 : 0;
                hi[a] = side % 3 == 0 ? 1 : n_axis[a];
            }
            cl_uint least = kFar;
            for (std::size_t z = lo[2]; z < hi[2]; ++z) {
                for (std::size_t y = lo[1]; y < hi[1]; ++y) {
                    for (std::size_t x = lo[0]; x < hi[0]; ++x) {
                        least = std::min(least, f[(z * ny + y) * nx + x]);
                    }
                }
            }
            f[nx * ny * nz + part] = least;
        }
    }
    static constexpr cl_uint kFar = 0xFFFFFFFFu;  // incremental.cl's VF_FAR

    // inc_place over the blocks of the cap box (B grown by max_margin) for an edit that only
    // placed solids; its box field starts at `f_off` in the changes buffer, its W at slot
    // `slot`, and it writes the `count` voxel changes from pair `first` on.
    void enqueue_place(Events& events, const Box& b, std::size_t f_off, std::size_t slot,
                       std::size_t first, std::size_t count) {
        const Box cap_blocks = cap_blocks_of(b);
        cl::Kernel& k = kernel(cpu_layout ? "inc_place_seq" : "inc_place");
        k.setArg(0, exact->voxels_buffer());
        k.setArg(1, exact->field_buffer());
        k.setArg(2, rgb);
        k.setArg(3, out);
        k.setArg(4, block_max);
        k.setArg(5, changes);
        k.setArg(6, static_cast<cl_uint>(f_off));
        k.setArg(7, d);
        k.setArg(8, int4_of(b.min));
        k.setArg(9, int4_of(b.max));
        k.setArg(10, int4_of(cap_blocks.min));
        k.setArg(11, int4_of(size_of(cap_blocks)));
        k.setArg(12, changes);
        k.setArg(13, static_cast<cl_int>(slot));
        k.setArg(14, changes);
        k.setArg(15, static_cast<cl_uint>(first));
        k.setArg(16, static_cast<cl_uint>(count));
        enqueue_blocks(events, k, 17, cap_blocks);
    }

    // inc_block_max, inc_place or inc_bounds over the blocks of `blocks`. On a CPU their
    // _seq kernels, a work-item per block. On a GPU work-groups of kBlock^2 work-items
    // (incremental.cl's VF_ROWS), argument `arg` saying how many blocks each takes:
    // `per_group` if given, else one while that launches at most kBlockGroups groups, as for
    // a bounded field's small cap box, and beyond that (an unbounded field's whole world,
    // mostly blocks that the test skips) kGroupBlocks. On the H200 at 512^3 a group per block
    // made a place edit's kernel 164 us against 105 us; at 256^3, and with D = 16, the group
    // per block was the faster (27 and 9 us against 33 and 19 us).
    void enqueue_blocks(Events& events, cl::Kernel& k, cl_uint arg, const Box& blocks,
                        std::size_t per_group = 0) {
        if (cpu_layout) {
            enqueue(events, k, range_of(blocks));
            return;
        }
        const auto count = static_cast<std::size_t>(blocks.volume());
        const auto group = static_cast<std::size_t>(kBlock * kBlock);
        if (per_group == 0) {
            per_group = count <= kBlockGroups ? 1 : kGroupBlocks;
        }
        k.setArg(arg, static_cast<cl_int>(per_group));
        events.emplace_back();
        ctx.queue().enqueueNDRangeKernel(k, cl::NullRange,
                                         cl::NDRange((count + per_group - 1) / per_group * group),
                                         cl::NDRange(group), nullptr, &events.back());
    }
    static constexpr std::size_t kBlockGroups = std::size_t{1} << 15;

    // The blocks within max_margin of B, clipped to the world.
    Box cap_blocks_of(const Box& b) const {
        const std::int64_t m = max_margin;
        return intersect(blocks_of(Box{{b.min.x - m, b.min.y - m, b.min.z - m},
                                       {b.max.x + m, b.max.y + m, b.max.z + m}}),
                         blocks_of(world_box()));
    }

    void encode_box(Events& events, const Box& b) {
        cl::Kernel& k = kernel("inc_encode_box");
        k.setArg(0, exact->voxels_buffer());
        k.setArg(1, exact->field_buffer());
        k.setArg(2, rgb);
        k.setArg(3, out);
        k.setArg(4, d);
        k.setArg(5, int4_of(b.min));
        k.setArg(6, int4_of(size_of(b)));
        k.setArg(7, bound);
        enqueue(events, k, range_of(b));
    }

    // The blocks (kBlock^3 voxels, incremental.cl's VF_BLOCK) overlapping a voxel box.
    static constexpr std::int64_t kBlock = 8;
    static Box blocks_of(const Box& v) {
        return Box{
            {floor_div(v.min.x, kBlock), floor_div(v.min.y, kBlock), floor_div(v.min.z, kBlock)},
            {floor_div(v.max.x + kBlock - 1, kBlock), floor_div(v.max.y + kBlock - 1, kBlock),
             floor_div(v.max.z + kBlock - 1, kBlock)}};
    }

    // Block maxima of the blocks in `blocks`; slot >= 0 limits them to that edit's W.
    void update_block_max(Events& events, const Box& blocks, cl_int slot) {
        cl::Kernel& k = kernel(cpu_layout ? "inc_block_max_seq" : "inc_block_max");
        k.setArg(0, exact->field_buffer());
        k.setArg(1, block_max);
        k.setArg(2, d);
        k.setArg(3, int4_of(blocks.min));
        k.setArg(4, int4_of(size_of(blocks)));
        k.setArg(5, slot >= 0 ? changes : block_max);  // unread when slot < 0
        k.setArg(6, slot);
        // The whole world (slot < 0): a work-item per block, which streams through memory.
        enqueue_blocks(events, k, 7, blocks,
                       slot < 0 ? static_cast<std::size_t>(kBlock * kBlock) : 0);
    }

    // inc_bounds over the blocks of the cap box (B grown by max_margin), the three sweeps
    // over its voxels (and W's one-voxel ring), then the block maxima of W; the box field of
    // the edit's changed voxels starts at `f_off` in the changes buffer, its W at slot `slot`;
    // inc_bounds writes the `count` voxel changes from pair `first` on.
    void enqueue_sweeps(Events& events, const Box& b, std::size_t f_off, std::size_t slot,
                        std::size_t first, std::size_t count) {
        const Box cap_blocks = cap_blocks_of(b);
        const Box cap = intersect(Box{{cap_blocks.min.x * kBlock - 1, cap_blocks.min.y * kBlock - 1,
                                       cap_blocks.min.z * kBlock - 1},
                                      {cap_blocks.max.x * kBlock + 1, cap_blocks.max.y * kBlock + 1,
                                       cap_blocks.max.z * kBlock + 1}},
                                  world_box());
        const Int3 size = size_of(cap);
        const cl::Buffer& dist = exact->field_buffer();
        const cl::Buffer& vox = exact->voxels_buffer();
        const auto slot_arg = static_cast<cl_int>(slot);

        cl::Kernel& bounds = kernel(cpu_layout ? "inc_bounds_seq" : "inc_bounds");
        bounds.setArg(0, dist);
        bounds.setArg(1, block_max);
        bounds.setArg(2, changes);
        bounds.setArg(3, static_cast<cl_uint>(f_off));
        bounds.setArg(4, d);
        bounds.setArg(5, int4_of(b.min));
        bounds.setArg(6, int4_of(b.max));
        bounds.setArg(7, int4_of(cap_blocks.min));
        bounds.setArg(8, int4_of(size_of(cap_blocks)));
        bounds.setArg(9, changes);
        bounds.setArg(10, slot_arg);
        bounds.setArg(11, vox);
        bounds.setArg(12, changes);
        bounds.setArg(13, static_cast<cl_uint>(first));
        bounds.setArg(14, static_cast<cl_uint>(count));
        enqueue_blocks(events, bounds, 15, cap_blocks);

        const auto ux = static_cast<std::size_t>(size.x), uy = static_cast<std::size_t>(size.y),
                   uz = static_cast<std::size_t>(size.z);
        cl::Kernel& sx = kernel(cpu_layout ? "inc_sweep_x_slices" : "inc_sweep_x");
        sx.setArg(0, vox);
        sx.setArg(1, dist);
        sx.setArg(2, tmp);
        sx.setArg(3, changes);
        sx.setArg(4, slot_arg);
        sx.setArg(5, d);
        sx.setArg(6, int4_of(b.min));
        sx.setArg(7, int4_of(b.max));
        sx.setArg(8, changes);
        sx.setArg(9, static_cast<cl_uint>(f_off));
        sx.setArg(10, int4_of(cap.min));
        sx.setArg(11, int4_of(size));
        if (cpu_layout) {
            const std::size_t pad = next_pow2(world.dims().x) / 2;
            sx.setArg(12, static_cast<cl_uint>(pad));
            sx.setArg(13, cl::Local(2 * (world.dims().x + 2 * pad) * 4));
            enqueue_items(events, sx, uz);
        } else {
            enqueue(events, sx, cl::NDRange(uy, uz));
        }

        cl::Kernel& sy = kernel(cpu_layout ? "inc_sweep_y_slices" : "inc_sweep_y");
        sy.setArg(0, tmp);
        sy.setArg(1, changes);
        sy.setArg(2, slot_arg);
        sy.setArg(3, d);
        sy.setArg(4, int4_of(cap.min));
        sy.setArg(5, int4_of(size));
        if (cpu_layout) {
            enqueue_items(events, sy, uz);
        } else {
            enqueue(events, sy, cl::NDRange(ux, uz));
        }

        cl::Kernel& sz = kernel(cpu_layout ? "inc_sweep_z_rows" : "inc_sweep_z");
        sz.setArg(0, vox);
        sz.setArg(1, dist);
        sz.setArg(2, tmp);
        sz.setArg(3, rgb);
        sz.setArg(4, out);
        sz.setArg(5, changes);
        sz.setArg(6, slot_arg);
        sz.setArg(7, d);
        sz.setArg(8, int4_of(cap.min));
        sz.setArg(9, int4_of(size));
        sz.setArg(10, bound);
        if (cpu_layout) {
            enqueue_items(events, sz, uy);
        } else {
            enqueue(events, sz, cl::NDRange(ux, uy));
        }

        update_block_max(events, cap_blocks, slot_arg);
    }

    std::uint32_t max_margin;  // the cap box: B grown by this much (bounded: by D and a block)
    // The CPU layout: sweeps with inner loops along x and the block passes' _seq kernels (a
    // work-item per block); else the GPU's (a column or a row per work-item).
    bool cpu_layout;
    std::unique_ptr<ExactManhattan> exact;  // u32: its output is the distance buffer (capped)
    // A bounded field's bound (--max-distance D: floor(D), the integer distances' cap), kFar
    // when unbounded: the distance buffer holds min(exact, bound).
    cl_uint bound;
    // The sweeps over the same voxels writing `out` in the output format (bounded fields
    // saturated at floor(D)), the regeneration of batches that span the world, after which
    // `exact` is stale until refresh_exact().
    std::unique_ptr<ExactManhattan> direct;
    bool exact_stale = false;

    // Recomputes the exact u32 field and the block maxima from the device voxels.
    double refresh_exact() {
        double ms = exact->run();
        Events events;
        update_block_max(events, blocks_of(world_box()), -1);
        ctx.queue().finish();
        exact_stale = false;
        return ms + elapsed_ms(events.front(), events.back());
    }
    cl::Buffer tmp, block_max;
    std::vector<cl_int> found;  // each edit's W, read back
};

// Every other exact field (chebyshev, euclidean, spacing, signed; ExactSeparable): the batch's
// changed voxels are scattered into the device world, then ExactSeparable::update
// recomputes exactly the rows and lines whose input changed, for the hull of the batch's
// edits.
class SeparableEngine : public Engine {
  public:
    SeparableEngine(Context& c, World w, const Palette& palette, const GeneratorOptions& o)
        : Engine(c, std::move(w), palette, o),
          sep(std::make_unique<ExactSeparable>(ctx, world, palette, o, true)) {
        out = sep->field_buffer();
    }

    double regenerate() override { return sep->run(); }

    void update(UpdateStats& stats) override {
        std::vector<std::size_t> first;
        if (stage(stats, first).empty()) {
            return;
        }
        cl_call("updating the field of " + world.dims().to_string(), [&] {
            Events events = upload();
            Box edited;
            for (std::size_t e = 0; e < stats.edits.size(); ++e) {
                const EditResult& r = stats.edits[e];
                if (!r.changed()) {
                    continue;
                }
                scatter(events, sep->voxels_buffer(), stats, first, e);
                edited = hull(edited, r.bounds);
            }
            if (!edited.empty() && regenerate_instead(edited)) {
                check_injected_failure();
                ctx.queue().finish();
                stats.update_ms = elapsed_ms(events.front(), events.back()) + sep->run();
                stats.full_regeneration = true;
                stats.regions = {world_box()};
                stats.voxels_recomputed = world.size();
                return;
            }
            if (!edited.empty()) {
                const ExactSeparable::Update u = sep->update(edited, events);
                stats.voxels_recomputed = u.voxels_recomputed;
                if (!u.changed.empty()) {
                    stats.regions.push_back(u.changed);
                }
            }
            check_injected_failure();
            ctx.queue().finish();
            stats.update_ms = elapsed_ms(events.front(), events.back());
        });
    }

    UpdateStats move_focus(const std::optional<Focus>&) override { no_focus_in_exact(); }

    const cl::Buffer& voxels_buffer() const override { return sep->voxels_buffer(); }

  private:
    std::unique_ptr<ExactSeparable> sep;
};

// Chunk-local algorithms: the dirty chunks of a batch, recomputed by the algorithm's own
// per-chunk work in one launch of the per-chunk batch kernel (monolithic.cl).
class ChunkEngine : public Engine {
  public:
    ChunkEngine(Context& c, World w, const Palette& palette, const GeneratorOptions& o)
        : Engine(c, std::move(w), palette, o), grid(world.dims(), o.chunk) {
        switch (o.algorithm) {
            case Algorithm::brute:
            case Algorithm::brute_chunked:
                mode = kBrute;
                break;
            case Algorithm::fim:
            case Algorithm::fim_host:
                mode = kFimAll;
                break;
            case Algorithm::jfa:
            case Algorithm::jfa_host:
                mode = kJfa;
                break;
            case Algorithm::jfa_fim:
                mode = kJfa | kFimAll;
                break;
            case Algorithm::lod:
            case Algorithm::monolithic:
                mode = kJfa | kFimFocus;
                break;
            case Algorithm::exact:
                throw std::logic_error("exact is global");
        }
        if (o.focus) {
            focus = focus_chunks(grid, *o.focus);
        }
        first_step = static_cast<std::uint32_t>(next_pow2(o.chunk) / 2);
        classic = classic_program(ctx, o.format);
        cl_call("allocating the chunk buffers of " + world.dims().to_string(), [&] {
            const std::size_t n = world.size();
            auto& q = ctx.queue();
            vox = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, n);
            q.enqueueWriteBuffer(vox, CL_TRUE, 0, n, world.voxels().data());
            dist = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, 4 * n);
            seed_a = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, 4 * n);
            seed_b = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, 4 * n);
            iterations = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, 4 * grid.chunk_count());
        });
    }

    double regenerate() override {
        std::vector<cl_uint> all(grid.chunk_count());
        for (std::size_t i = 0; i < all.size(); ++i) {
            all[i] = static_cast<cl_uint>(i);
        }
        return cl_call("regenerating the chunks of " + world.dims().to_string(), [&] {
            Events events;
            run_chunks(events, all);
            ctx.queue().finish();
            return elapsed_ms(events.front(), events.back());
        });
    }

    void update(UpdateStats& stats) override {
        std::vector<std::size_t> first;
        if (stage(stats, first).empty()) {
            return;
        }
        // Chunks are independent: exactly those holding a changed voxel change.
        DirtyTracker dirty(grid);
        for (const EditResult& r : stats.edits) {
            if (r.changed()) {
                dirty.add(r.bounds);
            }
        }
        std::vector<cl_uint> chunks;
        for (const std::size_t c : dirty.dirty_chunks()) {
            chunks.push_back(static_cast<cl_uint>(c));
            const Dims n = grid.chunks();
            const Int3 cc{static_cast<std::int64_t>(c % n.x),
                          static_cast<std::int64_t>(c / n.x % n.y),
                          static_cast<std::int64_t>(c / n.x / n.y)};
            const Box b = grid.voxels_of(cc);
            stats.regions.push_back(b);
            stats.voxels_recomputed += static_cast<std::uint64_t>(b.volume());
        }
        cl_call("updating the chunks of " + world.dims().to_string(), [&] {
            Events events = upload();
            for (std::size_t e = 0; e < stats.edits.size(); ++e) {
                if (stats.edits[e].changed()) {
                    scatter(events, vox, stats, first, e);
                }
            }
            run_chunks(events, chunks);
            check_injected_failure();
            ctx.queue().finish();
            stats.update_ms = elapsed_ms(events.front(), events.back());
        });
    }

    UpdateStats move_focus(const std::optional<Focus>& f) override {
        if ((mode & kFimFocus) == 0) {
            throw InputError(to_string(options.algorithm) +
                             " has no focus to move: only lod and monolithic run FIM in a focus");
        }
        const Box next = f ? focus_chunks(grid, *f) : Box{};  // throws outside the grid
        const std::optional<Focus> old_focus = options.focus;
        const Box old_box = focus;
        // The chunks inside exactly one of the two boxes, in chunk index order.
        auto inside = [](const Box& b, const Int3& c) {
            return c.x >= b.min.x && c.x < b.max.x && c.y >= b.min.y && c.y < b.max.y &&
                   c.z >= b.min.z && c.z < b.max.z;
        };
        const Box both = hull(focus, next);
        UpdateStats stats;
        std::vector<cl_uint> chunks;
        for (std::int64_t z = both.min.z; z < both.max.z; ++z) {
            for (std::int64_t y = both.min.y; y < both.max.y; ++y) {
                for (std::int64_t x = both.min.x; x < both.max.x; ++x) {
                    const Int3 c{x, y, z};
                    if (inside(focus, c) != inside(next, c)) {
                        chunks.push_back(static_cast<cl_uint>(grid.chunk_index(c)));
                        const Box b = grid.voxels_of(c);
                        stats.regions.push_back(b);
                        stats.voxels_recomputed += static_cast<std::uint64_t>(b.volume());
                    }
                }
            }
        }
        options.focus = f;
        focus = next;  // run_chunks reads it
        if (chunks.empty()) {
            return stats;
        }
        try {
            cl_call("moving the focus in " + world.dims().to_string(), [&] {
                Events events;
                run_chunks(events, chunks);
                check_injected_failure();
                ctx.queue().finish();
                stats.update_ms = elapsed_ms(events.front(), events.back());
            });
        } catch (...) {
            // The old focus, and every chunk recomputed with it.
            options.focus = old_focus;
            focus = old_box;
            restore({});
            throw;
        }
        return stats;
    }

    const cl::Buffer& voxels_buffer() const override { return vox; }

  private:
    // monolithic.cl's VF_MODE_* bits.
    static constexpr cl_uint kJfa = 1, kFimAll = 2, kFimFocus = 4, kBrute = 8;

    void run_chunks(Events& events, const std::vector<cl_uint>& chunks) {
        reserve(chunk_list, chunk_capacity, 4 * chunks.size());
        chunk_ids = chunks;  // the upload reads it after this returns
        events.emplace_back();
        ctx.queue().enqueueWriteBuffer(chunk_list, CL_FALSE, 0, 4 * chunk_ids.size(),
                                       chunk_ids.data(), nullptr, &events.back());
        cl::Kernel k(classic, "monolithic");
        const std::size_t limit = std::min<std::size_t>(
            256, k.getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(ctx.info().device));
        const std::size_t volume = std::size_t{options.chunk} * options.chunk * options.chunk;
        const std::size_t group = std::clamp<std::size_t>(volume, 32, limit);
        k.setArg(0, vox);
        k.setArg(1, seed_a);
        k.setArg(2, seed_b);
        k.setArg(3, dist);
        k.setArg(4, rgb);
        k.setArg(5, out);
        k.setArg(6, cl_uint4{{static_cast<cl_uint>(d.s[0]), static_cast<cl_uint>(d.s[1]),
                              static_cast<cl_uint>(d.s[2]), 0}});
        k.setArg(7, cl_uint{options.chunk});
        k.setArg(8, chunk_list);
        // An empty focus (lo > hi) unless the algorithm has one.
        const bool has_focus = !focus.empty();
        k.setArg(9, cl_uint4{{has_focus ? static_cast<cl_uint>(focus.min.x) : 1u,
                              has_focus ? static_cast<cl_uint>(focus.min.y) : 1u,
                              has_focus ? static_cast<cl_uint>(focus.min.z) : 1u, 0}});
        k.setArg(10, cl_uint4{{has_focus ? static_cast<cl_uint>(focus.max.x - 1) : 0u,
                               has_focus ? static_cast<cl_uint>(focus.max.y - 1) : 0u,
                               has_focus ? static_cast<cl_uint>(focus.max.z - 1) : 0u, 0}});
        k.setArg(11, cl_uint{first_step});
        k.setArg(12, cl_uint{options.jfa_extra});
        k.setArg(13, iterations);
        k.setArg(14, mode);
        events.emplace_back();
        ctx.queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(chunks.size() * group),
                                         cl::NDRange(group), nullptr, &events.back());
    }

    ChunkGrid grid;
    cl_uint mode = 0;
    Box focus;
    std::uint32_t first_step = 0;
    cl::Program classic;
    cl::Buffer vox, dist, seed_a, seed_b, iterations, chunk_list;
    std::vector<cl_uint> chunk_ids;
    std::size_t chunk_capacity = 0;
};

}  // namespace

struct IncrementalField::Impl {
    std::unique_ptr<Engine> engine;
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
        impl_->engine = std::make_unique<SeparableEngine>(ctx, std::move(world), palette, options);
    } else if (options.algorithm == Algorithm::exact) {
        impl_->engine =
            std::make_unique<GlobalEngine>(ctx, std::move(world), palette, options, max_margin);
    } else if (options.chunk != 0) {
        impl_->engine = std::make_unique<ChunkEngine>(ctx, std::move(world), palette, options);
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

const World& IncrementalField::world() const {
    return impl_->engine->world;
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
