#pragma once
// What the engines of ocl::IncrementalField share (cl/include/voxfield/cl/incremental.hpp): the
// host world, the output buffer, staging and uploading the changed voxels, the all-or-nothing
// protocol, and the enqueue helpers. One engine per file: incremental_global.cpp (exact L1
// sweeps), incremental_separable.cpp (ExactSeparable's incremental passes),
// incremental_chunks.cpp (the dissertation's chunk-local algorithms).
#include <algorithm>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "util.hpp"
#include "voxfield/cl/incremental.hpp"
#include "voxfield/core/dirty.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/undo.hpp"

namespace voxfield::cl_sources {
extern const char* const layout_h;
extern const char* const classic_common_cl;
extern const char* const incremental_cl;
}  // namespace voxfield::cl_sources

namespace voxfield::ocl::incremental {

// The blocks a GPU work-group of inc_bounds or inc_place takes at most (incremental.cl's
// VF_GROUP, passed as a build option), where one block per work-group would launch too many.
inline constexpr std::size_t kGroupBlocks = 8;

[[noreturn]] inline void no_focus_in_exact() {
    throw InputError(
        "exact has no focus to move: only the chunk-local lod and monolithic run FIM in a focus");
}

inline cl_int4 int4_of(const Int3& v) {
    return {{static_cast<cl_int>(v.x), static_cast<cl_int>(v.y), static_cast<cl_int>(v.z), 0}};
}

// What both updaters share: the host world, the output buffer, staging and uploading the
// changed voxels, and the enqueue helpers.
class Engine {
  public:
    // `own_output`: allocate `out`, the field in the output format (an engine whose generator
    // writes its own output takes that instead).
    Engine(Context& c, World w, const Palette& palette, const GeneratorOptions& o,
           bool own_output = true)
        : ctx(c), world(std::move(w)), options(o), host_stale(ChunkGrid(world.dims(), 8)) {
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
        cl_call("uploading the palette for " + dims.to_string(), [&] {
            const auto table = palette.rgb332_table();
            rgb = cl::Buffer(ctx.context(), CL_MEM_READ_ONLY, 256);
            ctx.queue().enqueueWriteBuffer(rgb, CL_TRUE, 0, 256, table.data());
        });
        if (own_output) {
            allocate_out();
        }
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
        sync_host();
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
        sync_host();
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
    // Changes made on the device (IncrementalField::apply_device_changes).
    UpdateStats apply_device_changes(const DeviceChanges& c) {
        require_intact();
        UpdateStats stats;
        if (c.count == 0) {
            return stats;
        }
        host_stale.add(c.bounds);
        try {
            cl_call("updating the field of " + world.dims().to_string() + " after " +
                        std::to_string(c.count) + " device changes",
                    [&] { device_update(c, stats); });
        } catch (...) {
            // The changes stay made: the field is regenerated from the device voxels.
            broken = true;
            try {
                ctx.queue().finish();
                regenerate();
                broken = false;
            } catch (const std::exception&) {
                // The first error is the one reported; `broken` stays set.
            }
            throw;
        }
        return stats;
    }

    // The host world, with the voxels that device changes made read back first.
    const World& current_world() {
        sync_host();
        return world;
    }

    // Moves the focus (chunk-local lod and monolithic), all or nothing like apply().
    UpdateStats set_focus(const std::optional<Focus>& focus) {
        require_intact();
        return move_focus(focus);
    }

    // Regenerates the field from the host world, uploaded whole first when a failed update
    // left the device voxels in doubt; returns the device time in ms.
    double rebuild() {
        if (broken && host_stale.empty()) {  // else the device voxels are the world
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
        return regenerate_instead(changed.volume());
    }
    bool regenerate_instead(std::int64_t volume) const {
        return static_cast<std::uint64_t>(volume) * kRegenerateFraction >=
               static_cast<std::uint64_t>(world.size());
    }
    // Consecutive edits share an update of their hull while it holds at most this many times
    // the voxels of their boxes.
    static constexpr std::int64_t kRunSlack = 2;
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
    // Brings the field up to date with changes made on the device (IncrementalField::
    // apply_device_changes), within cl_call; fills in stats.
    virtual void device_update(const DeviceChanges& c, UpdateStats& stats) = 0;

    // The output buffer in options.format, for engines that write their own.
    void allocate_out() {
        cl_call("allocating the output of " + world.dims().to_string(), [&] {
            out = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE,
                             world.size() * element_size(options.format));
        });
    }

    // stats after a full regeneration.
    void regenerated(UpdateStats& stats) const {
        stats.full_regeneration = true;
        stats.regions = {world_box()};
        stats.voxels_recomputed = world.size();
    }

    // The boxes of voxels that device changes made since the host world was last read back
    // (none: the host world is current), and reading them back.
    DirtyTracker host_stale;
    void sync_host() {
        if (host_stale.empty()) {
            return;
        }
        cl_call(
            "reading back the voxels changed on the device in " + world.dims().to_string(), [&] {
                const Dims n = world.dims();
                for (const Box& b : host_stale.regions()) {
                    const cl::array<cl::size_type, 3> at = {static_cast<cl::size_type>(b.min.x),
                                                            static_cast<cl::size_type>(b.min.y),
                                                            static_cast<cl::size_type>(b.min.z)};
                    const Int3 s = size_of(b);
                    const cl::array<cl::size_type, 3> region = {static_cast<cl::size_type>(s.x),
                                                                static_cast<cl::size_type>(s.y),
                                                                static_cast<cl::size_type>(s.z)};
                    ctx.queue().enqueueReadBufferRect(
                        voxels_buffer(), CL_TRUE, at, at, region, n.x, std::size_t{n.x} * n.y, n.x,
                        std::size_t{n.x} * n.y, world.voxels().data());
                }
            });
        host_stale.take();
    }
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

    // Writes the voxels of box `b` of the host world into the device world `vox`.
    void upload_box(Events& events, const cl::Buffer& vox, const Box& b) {
        const Dims n = world.dims();
        const Int3 s = size_of(b);
        const cl::array<cl::size_type, 3> at = {static_cast<cl::size_type>(b.min.x),
                                                static_cast<cl::size_type>(b.min.y),
                                                static_cast<cl::size_type>(b.min.z)};
        const cl::array<cl::size_type, 3> region = {static_cast<cl::size_type>(s.x),
                                                    static_cast<cl::size_type>(s.y),
                                                    static_cast<cl::size_type>(s.z)};
        events.emplace_back();
        ctx.queue().enqueueWriteBufferRect(vox, CL_FALSE, at, at, region, n.x,
                                           std::size_t{n.x} * n.y, n.x, std::size_t{n.x} * n.y,
                                           world.voxels().data(), nullptr, &events.back());
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

// The engines, each in its own file. Global semantics, exact L1 (unit spacing, bounded or
// not) by min-plus sweeps; `max_margin` as IncrementalField's.
std::unique_ptr<Engine> make_global_engine(Context& ctx, World world, const Palette& palette,
                                           const GeneratorOptions& options,
                                           std::uint32_t max_margin);
// Every other exact field, by ExactSeparable's incremental passes.
std::unique_ptr<Engine> make_separable_engine(Context& ctx, World world, const Palette& palette,
                                              const GeneratorOptions& options);
// Chunk-local algorithms (options.chunk != 0).
std::unique_ptr<Engine> make_chunk_engine(Context& ctx, World world, const Palette& palette,
                                          const GeneratorOptions& options);

}  // namespace voxfield::ocl::incremental
