// The exact L1 engine of IncrementalField: unit-spacing Manhattan fields, bounded or not, by
// min-plus sweeps over each edit's region (the method: cl/include/voxfield/cl/incremental.hpp;
// kernels: cl/kernels/incremental.cl).
#include "incremental_engine.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "voxfield/cl/exact.hpp"
#include "voxfield/core/box_field.hpp"

namespace voxfield::ocl::incremental {
namespace {

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
        Box occupancy, changed;
        for (const EditResult& r : stats.edits) {
            if (r.occupancy_changed()) {
                occupancy = hull(occupancy, r.occupancy_bounds);
            }
            changed = hull(changed, r.bounds);
        }
        if (changed.empty()) {
            return;
        }
        if (!occupancy.empty() && regenerate_instead(occupancy)) {
            // The output straight from the sweeps in its own format, the changed box uploaded
            // from the host world (nothing staged per voxel); the exact u32 field and its block
            // maxima, which only incremental updates read, are brought up to date before the
            // next one (a run of world-spanning batches skips them).
            cl_call("regenerating the field of " + world.dims().to_string(), [&] {
                Events events;
                upload_box(events, exact->voxels_buffer(), changed);
                check_injected_failure();
                ctx.queue().finish();
                stats.update_ms = elapsed_ms(events.front(), events.back()) + direct->run();
            });
            exact_stale = true;
            regenerated(stats);
            return;
        }
        std::vector<std::size_t> first;
        stage(stats, first);
        // Every edit that changes occupancy has a box field staged after the pairs (one
        // upload): edits that only place solids take inc_place with the field of B's solids,
        // the rest the sweeps, with the field of the voxels whose occupancy they changed.
        std::vector<std::size_t> field_at(stats.edits.size(), 0);
        for (std::size_t e = 0; e < stats.edits.size(); ++e) {
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
        staging.resize(8 * (regions_at + stats.edits.size()), 0);
        cl_call("updating the field of " + world.dims().to_string(), [&] {
            auto& q = ctx.queue();
            Events events = upload();
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
                // inc_place counts the voxels it read; the sweeps recompute all of W.
                add_region(stats, found.data() + 8 * e, places_only(stats.edits[e]));
            }
            if (stats.full_regeneration) {
                // A region reached past max_margin: what was computed for it is incomplete.
                stats.update_ms += regenerate();
                regenerated(stats);
            }
        });
    }

    void device_update(const DeviceChanges& c, UpdateStats& stats) override {
        auto& q = ctx.queue();
        const bool packed = options.format == Format::packed32;
        Events events;
        if (c.occupancy_bounds.empty()) {
            // Recoloured voxels only: the distances stand; packed32 encodes their colours (from
            // the exact field, brought up to date first if a regeneration left it stale).
            if (packed) {
                const double refresh_ms = exact_stale ? refresh_exact() : 0;
                encode_box(events, c.bounds);
                check_injected_failure();
                q.finish();
                stats.update_ms = refresh_ms + elapsed_ms(events.front(), events.back());
            }
            return;
        }
        if (c.overflow() || regenerate_instead(c.occupancy_bounds)) {
            check_injected_failure();
            stats.update_ms = direct->run();
            exact_stale = true;
            regenerated(stats);
            return;
        }
        if (exact_stale) {
            // The u32 field the sweeps start from would be that of the world before the
            // changes, which the device voxels no longer hold: recomputed from them, it is the
            // new field, encoded whole.
            stats.update_ms = refresh_exact();
            encode_box(events, world_box());
            check_injected_failure();
            q.finish();
            stats.update_ms += elapsed_ms(events.front(), events.back());
            regenerated(stats);
            return;
        }
        // The box field of the changed voxels over B from the device list, W's slot after it,
        // then the sweeps as for a host edit (inc_bounds writes no voxels: they are written).
        const Box& b = c.occupancy_bounds;
        const Int3 n = size_of(b);
        const auto volume = static_cast<std::size_t>(b.volume());
        const std::size_t slot = (volume + 27 + 7) / 8;
        reserve(changes, changes_capacity, 4 * 8 * (slot + 1));
        events.emplace_back();
        q.enqueueFillBuffer(changes, kFar, 0, 4 * (volume + 27), nullptr, &events.back());
        events.emplace_back();
        q.enqueueFillBuffer(changes, cl_uint{0}, 4 * 8 * slot, 4 * 8, nullptr, &events.back());
        const auto count = static_cast<std::size_t>(c.count);
        cl::Kernel& mark = kernel("inc_field_mark");
        mark.setArg(0, changes);
        mark.setArg(1, *c.list);
        mark.setArg(2, static_cast<cl_uint>(count));
        mark.setArg(3, d);
        mark.setArg(4, int4_of(b.min));
        mark.setArg(5, int4_of(b.max));
        enqueue(events, mark, cl::NDRange(count));
        const auto nx = static_cast<std::size_t>(n.x), ny = static_cast<std::size_t>(n.y),
                   nz = static_cast<std::size_t>(n.z);
        const std::size_t lines[3] = {ny * nz, nx * nz, nx * ny};
        for (cl_int axis = 0; axis < 3; ++axis) {
            cl::Kernel& sweep = kernel("inc_field_sweep");
            sweep.setArg(0, changes);
            sweep.setArg(1, int4_of(n));
            sweep.setArg(2, axis);
            enqueue(events, sweep, cl::NDRange(lines[axis]));
        }
        cl::Kernel& least = kernel("inc_field_least");
        least.setArg(0, changes);
        least.setArg(1, int4_of(n));
        // Lanes per part: about 32 voxels each over all of B, 64 to 16384 of them.
        const std::size_t lanes =
            std::clamp<std::size_t>((volume / 32 + 63) / 64 * 64, 64, std::size_t{16384});
        least.setArg(2, static_cast<cl_uint>(lanes));
        enqueue(events, least, cl::NDRange(27 * lanes));
        enqueue_sweeps(events, b, 0, slot, 0, 0);
        if (packed) {
            encode_box(events, c.bounds);  // colours of recoloured voxels
        }
        found.assign(8, 0);
        q.enqueueReadBuffer(changes, CL_FALSE, 4 * 8 * slot, 4 * 8, found.data());
        check_injected_failure();
        q.finish();
        stats.update_ms = elapsed_ms(events.front(), events.back());
        add_region(stats, found.data(), false);
        if (stats.full_regeneration) {
            stats.update_ms += regenerate();
            regenerated(stats);
        }
    }

    UpdateStats move_focus(const std::optional<Focus>&) override { no_focus_in_exact(); }

    const cl::Buffer& voxels_buffer() const override { return exact->voxels_buffer(); }

  private:
    static bool places_only(const EditResult& r) {
        return r.became_solid != 0 && r.became_empty == 0;
    }

    // An edit's W as its kernels left it (g: inc_bounds' 8 ints) into stats: its region, the
    // voxels recomputed (inc_place's count of voxels read where `placed`, else W's volume) and
    // whether it overflowed the cap box.
    void add_region(UpdateStats& stats, const cl_int* g, bool placed) const {
        stats.full_regeneration |= g[6] != 0;
        const Box w{{d.s[0] - g[0], d.s[1] - g[1], d.s[2] - g[2]}, {g[3], g[4], g[5]}};
        stats.regions.push_back(w);
        stats.voxels_recomputed +=
            placed ? static_cast<std::uint64_t>(g[7]) : static_cast<std::uint64_t>(w.volume());
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
        box_field_transform(f, n);
        const std::array<std::uint32_t, 27> least = box_field_boundary_minima(f, n);
        std::copy(least.begin(), least.end(), f + nx * ny * nz);
    }
    static constexpr cl_uint kFar = kBoxFieldFar;  // incremental.cl's VF_FAR

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

}  // namespace

std::unique_ptr<Engine> make_global_engine(Context& ctx, World world, const Palette& palette,
                                           const GeneratorOptions& options,
                                           std::uint32_t max_margin) {
    return std::make_unique<GlobalEngine>(ctx, std::move(world), palette, options, max_margin);
}

}  // namespace voxfield::ocl::incremental
