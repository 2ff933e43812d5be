// The chunk-local engine of IncrementalField: the dissertation's algorithms per chunk
// (dissertation ch. 4; kernels: monolithic.cl's per-chunk batch kernel, incremental.cl's
// inc_mark_chunks).
#include "incremental_engine.hpp"

#include <stdexcept>

#include "classic.hpp"

namespace voxfield::ocl::incremental {
namespace {

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
            upload_chunks(events, all);
            run_chunks(events, chunk_list, all.size());
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
        const Dims dims = world.dims();
        std::vector<bool> marked(grid.chunk_count(), false);
        std::vector<cl_uint> chunks;
        for (const EditResult& r : stats.edits) {
            for (const VoxelChange& c : r.changes) {
                const std::size_t i = c.index;
                const std::size_t chunk = grid.chunk_index(
                    {static_cast<std::int64_t>(i % dims.x / options.chunk),
                     static_cast<std::int64_t>(i / dims.x % dims.y / options.chunk),
                     static_cast<std::int64_t>(i / dims.x / dims.y / options.chunk)});
                if (!marked[chunk]) {
                    marked[chunk] = true;
                    chunks.push_back(static_cast<cl_uint>(chunk));
                }
            }
        }
        std::sort(chunks.begin(), chunks.end());
        add_chunks(stats, chunks);
        cl_call("updating the chunks of " + world.dims().to_string(), [&] {
            Events events = upload();
            for (std::size_t e = 0; e < stats.edits.size(); ++e) {
                if (stats.edits[e].changed()) {
                    scatter(events, vox, stats, first, e);
                }
            }
            upload_chunks(events, chunks);
            run_chunks(events, chunk_list, chunks.size());
            check_injected_failure();
            ctx.queue().finish();
            stats.update_ms = elapsed_ms(events.front(), events.back());
        });
    }

    void device_update(const DeviceChanges& c, UpdateStats& stats) override {
        auto& q = ctx.queue();
        if (c.overflow()) {
            check_injected_failure();
            stats.update_ms = regenerate();
            regenerated(stats);
            return;
        }
        // The chunks holding a listed voxel, gathered on the device; their ids come back for
        // the stats (the render field converts those chunks), not to be sent again.
        const std::size_t chunk_count = grid.chunk_count();
        reserve(chunk_list, chunk_capacity, 4 * chunk_count);
        if (chunk_flags_count != chunk_count) {
            chunk_flags = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, 4 * chunk_count);
            q.enqueueFillBuffer(chunk_flags, cl_uint{0}, 0, 4 * chunk_count);
            chunk_marked = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, 4);
            q.enqueueFillBuffer(chunk_marked, cl_uint{0}, 0, 4);
            chunk_flags_count = chunk_count;
        }
        Events events;
        const Dims nc = grid.chunks();
        cl::Kernel& k = kernel("inc_mark_chunks");
        const auto count = static_cast<std::size_t>(c.count);
        k.setArg(0, *c.list);
        k.setArg(1, static_cast<cl_uint>(count));
        k.setArg(2, d);
        k.setArg(3, cl_uint{options.chunk});
        k.setArg(4, int4_of({nc.x, nc.y, nc.z}));
        k.setArg(5, chunk_flags);
        k.setArg(6, chunk_list);
        k.setArg(7, chunk_marked);
        enqueue(events, k, cl::NDRange(count));
        cl_uint marked = 0;
        events.emplace_back();
        q.enqueueReadBuffer(chunk_marked, CL_TRUE, 0, 4, &marked, nullptr, &events.back());
        chunk_ids.resize(marked);
        if (marked != 0) {
            q.enqueueReadBuffer(chunk_list, CL_FALSE, 0, 4 * chunk_ids.size(), chunk_ids.data());
            run_chunks(events, chunk_list, marked);
        }
        events.emplace_back();
        q.enqueueFillBuffer(chunk_flags, cl_uint{0}, 0, 4 * chunk_count, nullptr, &events.back());
        events.emplace_back();
        q.enqueueFillBuffer(chunk_marked, cl_uint{0}, 0, 4, nullptr, &events.back());
        check_injected_failure();
        q.finish();
        stats.update_ms = elapsed_ms(events.front(), events.back());
        std::sort(chunk_ids.begin(), chunk_ids.end());
        add_chunks(stats, chunk_ids);
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
                upload_chunks(events, chunks);
                run_chunks(events, chunk_list, chunks.size());
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

    // The voxel boxes of `chunks` into stats.
    void add_chunks(UpdateStats& stats, const std::vector<cl_uint>& chunks) const {
        const Dims n = grid.chunks();
        for (const cl_uint c : chunks) {
            const Box b = grid.voxels_of({static_cast<std::int64_t>(c % n.x),
                                          static_cast<std::int64_t>(c / n.x % n.y),
                                          static_cast<std::int64_t>(c / n.x / n.y)});
            stats.regions.push_back(b);
            stats.voxels_recomputed += static_cast<std::uint64_t>(b.volume());
        }
    }

    // Writes `chunks` into chunk_list.
    void upload_chunks(Events& events, const std::vector<cl_uint>& chunks) {
        reserve(chunk_list, chunk_capacity, 4 * std::max<std::size_t>(chunks.size(), 1));
        chunk_ids = chunks;  // the upload reads it after this returns
        events.emplace_back();
        ctx.queue().enqueueWriteBuffer(chunk_list, CL_FALSE, 0, 4 * chunk_ids.size(),
                                       chunk_ids.data(), nullptr, &events.back());
    }

    // The per-chunk kernel over the first `count` chunks of `list`.
    void run_chunks(Events& events, const cl::Buffer& list, std::size_t count) {
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
        k.setArg(8, list);
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
        ctx.queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(count * group),
                                         cl::NDRange(group), nullptr, &events.back());
    }

    ChunkGrid grid;
    cl_uint mode = 0;
    Box focus;
    std::uint32_t first_step = 0;
    cl::Program classic;
    cl::Buffer vox, dist, seed_a, seed_b, iterations, chunk_list;
    // Device changes: a flag per chunk (zero between updates) and the count of marked ones.
    cl::Buffer chunk_flags, chunk_marked;
    std::size_t chunk_flags_count = 0;
    std::vector<cl_uint> chunk_ids;  // read or written by a transfer that may be in flight
    std::size_t chunk_capacity = 0;
};

}  // namespace

std::unique_ptr<Engine> make_chunk_engine(Context& ctx, World world, const Palette& palette,
                                          const GeneratorOptions& options) {
    return std::make_unique<ChunkEngine>(ctx, std::move(world), palette, options);
}

}  // namespace voxfield::ocl::incremental
