// The dissertation's generators on OpenCL, host side (kernels: cl/kernels/classic_common.cl,
// brute.cl, fim.cl, jfa.cl, monolithic.cl; algorithms of chapter 4).
#include "classic.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "util.hpp"
#include "voxfield/core/error.hpp"

namespace voxfield::cl_sources {
extern const char* const layout_h;
extern const char* const classic_common_cl;
extern const char* const brute_cl;
extern const char* const fim_cl;
extern const char* const jfa_cl;
extern const char* const monolithic_cl;
}  // namespace voxfield::cl_sources

namespace voxfield::ocl {
namespace {

// Voxel pairs per second and compute unit that brute force sustains, measured with
// `voxfield bench --algorithms brute` (PoCL on a 2-core x86: ~2.5e9 per core; H200: ~3e10
// per SM). Used only to refuse grids that would take more than kBruteLimitS.
constexpr double kBrutePairsPerUnitCpu = 2e9;
constexpr double kBrutePairsPerUnitGpu = 2e10;
constexpr double kBruteLimitS = 60;
// What loading one voxel into a work-group's local memory costs brute_global, in voxel pairs
// compared (an all-solid world, which compares none, measured as above).
constexpr double kBruteTileLoadPairs = 3;

class Classic : public Generator {
  public:
    Classic(Context& ctx, const World& world, const Palette& palette, const GeneratorOptions& o);
    double run() override;
    std::string variant() const override;

  private:
    using Events = std::vector<std::pair<std::string, cl::Event>>;
    void enqueue(Events& events, const char* name, cl::Kernel& kernel, const cl::NDRange& global,
                 const cl::NDRange& local);
    // Algorithm 1, staging rows of the world in local memory.
    void enqueue_brute_global(Events& events);
    // Algorithm 3; also `brute` with --chunk, which is the same thing.
    void enqueue_brute_chunked(Events& events);
    void enqueue_jfa(Events& events, bool wait_each_pass);
    // Enqueues FIM passes over fim_box_; the host reads the change counter after each pass
    // (fim-host) or enqueues every pass up front (the others). Returns the passes that
    // changed something.
    std::uint32_t enqueue_fim(Events& events, bool host_loop);
    void refuse_slow_brute(const World& world) const;

    GeneratorOptions o_;
    cl::Program program_;
    cl::Buffer vox_, rgb_, dist_, seed_a_, seed_b_, changes_, chunk_list_, chunk_iterations_;
    cl_uint4 d_{};
    cl_uint4 fim_lo_{}, fim_size_{};
    std::uint32_t fim_bound_ = 0;  // passes that certainly reach the fixed point, +1 to see it
    std::vector<int> jfa_steps_;
    std::size_t chunk_count_ = 0;
    cl::NDRange grid3_, local3_, grid1_, local1_, fim_global_, fim_local_;
};

Classic::Classic(Context& ctx, const World& world, const Palette& palette,
                 const GeneratorOptions& o)
    : Generator(ctx, world.dims(), o.format), o_(o) {
    const auto& info = ctx.info();
    const std::size_t n = dims_.count();
    const std::string what = to_string(o.algorithm) + " on " + dims_.to_string() +
                             (o.chunk != 0 ? " in chunks of " + std::to_string(o.chunk) : "") +
                             ", format " + to_string(o.format);
    if (n >= 0xFFFFFFFFu) {
        throw InputError(what +
                         ": the dissertation's kernels index voxels with 32 bits; use "
                         "a world of fewer than 4294967295 voxels or the exact algorithm");
    }
    if (4 * n > info.max_alloc) {
        throw ClError("clCreateBuffer", CL_INVALID_BUFFER_SIZE,
                      what + " needs " + std::to_string((4 * n) >> 20) + " MiB buffers; " +
                          info.name + " allows at most " + std::to_string(info.max_alloc >> 20) +
                          " MiB per buffer");
    }
    if (o.algorithm == Algorithm::brute || o.algorithm == Algorithm::brute_chunked) {
        refuse_slow_brute(world);
    }
    d_ = {{dims_.x, dims_.y, dims_.z, 0}};

    program_ = classic_program(ctx, o.format);

    // JFA steps: half the extent rounded up to a power of two, halving to 1; then JFA+1 (1)
    // or JFA+2 (2, 1).
    const std::uint32_t extent = o.chunk != 0 ? o.chunk : std::max({dims_.x, dims_.y, dims_.z});
    for (auto s = static_cast<std::uint32_t>(next_pow2(extent) / 2); s >= 1; s /= 2) {
        jfa_steps_.push_back(static_cast<int>(s));
    }
    for (std::uint32_t e = o.jfa_extra; e >= 1; --e) {
        jfa_steps_.push_back(static_cast<int>(1u << (e - 1)));
    }

    // FIM over the whole world, or over lod's focus chunks. Distances stay below the
    // world's (or a chunk's) L1 diameter, so that many Jacobi passes reach the fixed point
    // and one more sees no change; in-place passes are never slower.
    fim_size_ = d_;
    if (o.algorithm == Algorithm::lod) {
        const ChunkGrid grid(dims_, o.chunk);
        const Box f = focus_chunks(grid, *o.focus);
        const std::int64_t c = o.chunk;
        const Box voxels = intersect(
            Box{{f.min.x * c, f.min.y * c, f.min.z * c}, {f.max.x * c, f.max.y * c, f.max.z * c}},
            Box{{0, 0, 0}, {dims_.x, dims_.y, dims_.z}});
        fim_lo_ = {{static_cast<cl_uint>(voxels.min.x), static_cast<cl_uint>(voxels.min.y),
                    static_cast<cl_uint>(voxels.min.z), 0}};
        fim_size_ = {{static_cast<cl_uint>(voxels.max.x - voxels.min.x),
                      static_cast<cl_uint>(voxels.max.y - voxels.min.y),
                      static_cast<cl_uint>(voxels.max.z - voxels.min.z), 1}};
    }
    fim_bound_ = o.chunk != 0 ? o.chunk / 2 + 2 : dims_.x + dims_.y + dims_.z;

    const bool cpu = ctx.is_cpu();
    const std::size_t max_group = std::min<std::size_t>(256, info.max_work_group);
    local3_ = cpu ? cl::NDRange(16, 4, 2) : cl::NDRange(8, 8, 4);
    if (local3_[0] * local3_[1] * local3_[2] > max_group) {
        local3_ = cl::NDRange(std::min<std::size_t>(8, max_group), 1, 1);
    }
    grid3_ = cl::NDRange(round_up(dims_.x, local3_[0]), round_up(dims_.y, local3_[1]),
                         round_up(dims_.z, local3_[2]));
    local1_ = cl::NDRange(max_group);
    grid1_ = cl::NDRange(round_up(n, max_group));
    const std::size_t fim_n = std::size_t{fim_size_.s[0]} * fim_size_.s[1] * fim_size_.s[2];
    const std::size_t groups = std::size_t{info.compute_units} * (cpu ? 4 : 16);
    fim_local_ = local1_;
    fim_global_ = cl::NDRange(std::min(groups * max_group, round_up(fim_n, max_group)));

    cl_call("allocating and uploading, " + what, [&] {
        auto& q = ctx.queue();
        auto& c = ctx.context();
        vox_ = cl::Buffer(c, CL_MEM_READ_ONLY, n);
        rgb_ = cl::Buffer(c, CL_MEM_READ_ONLY, 256);
        out_ = cl::Buffer(c, CL_MEM_READ_WRITE, n * element_size(o.format));
        dist_ = cl::Buffer(c, CL_MEM_READ_WRITE, 4 * n);
        if (o.algorithm != Algorithm::brute && o.algorithm != Algorithm::brute_chunked &&
            o.algorithm != Algorithm::fim && o.algorithm != Algorithm::fim_host) {
            seed_a_ = cl::Buffer(c, CL_MEM_READ_WRITE, 4 * n);
            seed_b_ = cl::Buffer(c, CL_MEM_READ_WRITE, 4 * n);
        }
        changes_ = cl::Buffer(c, CL_MEM_READ_WRITE, 4 * (std::size_t{fim_bound_} + 1));
        const auto table = palette.rgb332_table();
        cl::Event up_vox, up_rgb;
        q.enqueueWriteBuffer(vox_, CL_FALSE, 0, n, world.voxels().data(), nullptr, &up_vox);
        q.enqueueWriteBuffer(rgb_, CL_FALSE, 0, table.size(), table.data(), nullptr, &up_rgb);
        if (o.algorithm == Algorithm::monolithic) {
            const ChunkGrid grid(dims_, o.chunk);
            chunk_count_ = grid.chunk_count();
            std::vector<cl_uint> all(chunk_count_);
            for (std::size_t i = 0; i < all.size(); ++i) {
                all[i] = static_cast<cl_uint>(i);
            }
            chunk_list_ = cl::Buffer(c, CL_MEM_READ_ONLY, 4 * chunk_count_);
            chunk_iterations_ = cl::Buffer(c, CL_MEM_READ_WRITE, 4 * chunk_count_);
            q.enqueueWriteBuffer(chunk_list_, CL_TRUE, 0, 4 * chunk_count_, all.data());
        }
        q.finish();
        upload_ms_ = elapsed_ms(up_vox, up_rgb);
    });
}

void Classic::refuse_slow_brute(const World& world) const {
    const auto& info = ctx_.info();
    const double n = static_cast<double>(world.size());
    double pairs = 0;
    if (o_.algorithm == Algorithm::brute) {
        // brute_global: each work-group loads the whole world through local memory, solid or
        // not (kBruteTileLoadPairs pair-equivalents a voxel), and each of its work-items with
        // an empty voxel (or past the end, the last group's padding) compares it with every
        // voxel; on a GPU a group's items run in lock step, so one empty voxel costs them all.
        const std::size_t group = std::min<std::size_t>(256, info.max_work_group);
        const auto& voxels = world.voxels();
        const std::size_t count = voxels.size();
        for (std::size_t g0 = 0; g0 < count; g0 += group) {
            const std::size_t g1 = std::min(count, g0 + group);
            std::size_t scanning = group - (g1 - g0);
            for (std::size_t i = g0; i < g1; ++i) {
                scanning += voxels[i] == 0 ? 1 : 0;
            }
            if (!ctx_.is_cpu() && scanning != 0) {
                scanning = group;
            }
            pairs += n * (static_cast<double>(scanning) + kBruteTileLoadPairs);
        }
    } else {
        // brute_chunked: each empty voxel scans its chunk; a solid one returns at once.
        const double empty = n - static_cast<double>(world.solid_count());
        pairs = empty * std::pow(static_cast<double>(o_.chunk), 3) + n;
    }
    const double rate = static_cast<double>(info.compute_units) *
                        (ctx_.is_cpu() ? kBrutePairsPerUnitCpu : kBrutePairsPerUnitGpu);
    const double seconds = pairs / rate;
    if (seconds > kBruteLimitS) {
        char estimate[64];
        std::snprintf(estimate, sizeof estimate, "%.2g voxel pairs, about %.0f s", pairs, seconds);
        throw InputError(to_string(o_.algorithm) + " on " + dims_.to_string() +
                         (o_.chunk != 0 ? " in chunks of " + std::to_string(o_.chunk) : "") +
                         " would scan " + estimate + " on " + info.name +
                         "; use --algorithm exact (the same global field in milliseconds)" +
                         (o_.algorithm == Algorithm::brute_chunked ? " or a smaller --chunk"
                                                                   : " or a smaller world"));
    }
}

std::string Classic::variant() const {
    return o_.chunk != 0 ? "chunk-local, chunk " + std::to_string(o_.chunk) : "global";
}

void Classic::enqueue(Events& events, const char* name, cl::Kernel& kernel,
                      const cl::NDRange& global, const cl::NDRange& local) {
    events.emplace_back(name, cl::Event());
    ctx_.queue().enqueueNDRangeKernel(kernel, cl::NullRange, global, local, nullptr,
                                      &events.back().second);
}

void Classic::enqueue_brute_global(Events& events) {
    // Whole rows staged per group, about 4 KiB of them.
    const std::uint32_t rows = std::max<std::uint32_t>(1, 4096 / dims_.x);
    const std::size_t tile = std::size_t{rows} * dims_.x;
    if (tile > ctx_.info().local_mem) {
        throw ClError("clEnqueueNDRangeKernel", CL_OUT_OF_RESOURCES,
                      to_string(o_.algorithm) + " on " + dims_.to_string() + ": a row of " +
                          std::to_string(dims_.x) + " voxels does not fit the local memory of " +
                          ctx_.info().name);
    }
    cl::Kernel k(program_, "brute_global");
    k.setArg(0, vox_);
    k.setArg(1, dist_);
    k.setArg(2, d_);
    k.setArg(3, cl_uint{rows});
    k.setArg(4, cl::Local(tile));
    enqueue(events, "brute_global", k, grid1_, local1_);
}

void Classic::enqueue_brute_chunked(Events& events) {
    cl::Kernel k(program_, "brute_chunked");
    k.setArg(0, vox_);
    k.setArg(1, dist_);
    k.setArg(2, d_);
    k.setArg(3, cl_uint{o_.chunk});
    enqueue(events, "brute_chunked", k, grid3_, local3_);
}

void Classic::enqueue_jfa(Events& events, bool wait_each_pass) {
    cl::Kernel init(program_, "jfa_init");
    init.setArg(0, vox_);
    init.setArg(1, seed_a_);
    init.setArg(2, static_cast<cl_uint>(dims_.count()));
    enqueue(events, "jfa_init", init, grid1_, local1_);
    cl::Kernel step(program_, "jfa_step");
    step.setArg(2, d_);
    step.setArg(3, cl_uint{o_.chunk});
    bool in_a = true;
    for (const int s : jfa_steps_) {
        step.setArg(0, in_a ? seed_a_ : seed_b_);
        step.setArg(1, in_a ? seed_b_ : seed_a_);
        step.setArg(4, cl_int{s});
        enqueue(events, "jfa_step", step, grid3_, local3_);
        if (wait_each_pass) {
            ctx_.queue().finish();  // Algorithm 6's host loop: one pass per submission
        }
        in_a = !in_a;
    }
    cl::Kernel to_dist(program_, "jfa_dist");
    to_dist.setArg(0, in_a ? seed_a_ : seed_b_);
    to_dist.setArg(1, dist_);
    to_dist.setArg(2, d_);
    to_dist.setArg(3, cl_uint{o_.chunk});
    enqueue(events, "jfa_dist", to_dist, grid3_, local3_);
}

std::uint32_t Classic::enqueue_fim(Events& events, bool host_loop) {
    auto& q = ctx_.queue();
    q.enqueueFillBuffer(changes_, cl_uint{0}, 0, 4 * (std::size_t{fim_bound_} + 1));
    cl::Kernel step(program_, "fim_step");
    step.setArg(0, dist_);
    step.setArg(1, d_);
    step.setArg(2, cl_uint{o_.chunk});
    step.setArg(3, fim_lo_);
    step.setArg(4, fim_size_);
    step.setArg(5, changes_);
    std::vector<cl_uint> changes(fim_bound_ + 1, 0);
    std::uint32_t passes = 0;
    for (std::uint32_t it = 0; it < fim_bound_; ++it) {
        step.setArg(6, cl_uint{it});
        enqueue(events, "fim_step", step, fim_global_, fim_local_);
        if (host_loop) {
            // Algorithm 5's host loop: wait for the pass, read its change counter.
            q.enqueueReadBuffer(changes_, CL_TRUE, 4 * std::size_t{it}, 4, &changes[it]);
            if (changes[it] == 0) {
                return passes;
            }
            ++passes;
        }
    }
    if (host_loop) {
        throw std::logic_error("FIM did not converge within " + std::to_string(fim_bound_) +
                               " passes");
    }
    return fim_bound_;  // counted after the run (run() reads changes_)
}

double Classic::run() {
    const std::string what = to_string(o_.algorithm) + " on " + dims_.to_string();
    return cl_call("running " + what, [&] {
        auto& q = ctx_.queue();
        Events events;
        const cl_uint n = static_cast<cl_uint>(dims_.count());
        bool count_fim_after = false;
        iterations_ = 0;
        switch (o_.algorithm) {
            case Algorithm::brute:
                if (o_.chunk != 0) {
                    enqueue_brute_chunked(events);
                } else {
                    enqueue_brute_global(events);
                }
                break;
            case Algorithm::brute_chunked:
                enqueue_brute_chunked(events);
                break;
            case Algorithm::fim_host:
            case Algorithm::fim: {
                cl::Kernel init(program_, "fim_init");
                init.setArg(0, vox_);
                init.setArg(1, dist_);
                init.setArg(2, n);
                enqueue(events, "fim_init", init, grid1_, local1_);
                iterations_ = enqueue_fim(events, o_.algorithm == Algorithm::fim_host);
                count_fim_after = o_.algorithm == Algorithm::fim;
                break;
            }
            case Algorithm::jfa_host:
            case Algorithm::jfa:
                enqueue_jfa(events, o_.algorithm == Algorithm::jfa_host);
                break;
            case Algorithm::jfa_fim:
            case Algorithm::lod:
                enqueue_jfa(events, false);
                iterations_ = enqueue_fim(events, false);
                count_fim_after = true;
                break;
            case Algorithm::monolithic: {
                const ChunkGrid grid(dims_, o_.chunk);
                const Box f = focus_chunks(grid, *o_.focus);
                cl::Kernel k(program_, "monolithic");
                const std::size_t limit = std::min<std::size_t>(
                    256, k.getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(ctx_.info().device));
                const std::size_t volume = std::size_t{o_.chunk} * o_.chunk * o_.chunk;
                const std::size_t group = std::clamp<std::size_t>(volume, 32, limit);
                const std::uint32_t first = jfa_steps_.size() > o_.jfa_extra
                                                ? static_cast<std::uint32_t>(jfa_steps_.front())
                                                : 0u;
                k.setArg(0, vox_);
                k.setArg(1, seed_a_);
                k.setArg(2, seed_b_);
                k.setArg(3, dist_);
                k.setArg(4, rgb_);
                k.setArg(5, out_);
                k.setArg(6, d_);
                k.setArg(7, cl_uint{o_.chunk});
                k.setArg(8, chunk_list_);
                k.setArg(9, cl_uint4{{static_cast<cl_uint>(f.min.x), static_cast<cl_uint>(f.min.y),
                                      static_cast<cl_uint>(f.min.z), 0}});
                k.setArg(10, cl_uint4{{static_cast<cl_uint>(f.max.x - 1),
                                       static_cast<cl_uint>(f.max.y - 1),
                                       static_cast<cl_uint>(f.max.z - 1), 0}});
                k.setArg(11, cl_uint{first});
                k.setArg(12, cl_uint{o_.jfa_extra});
                k.setArg(13, chunk_iterations_);
                k.setArg(14, cl_uint{5});  // VF_MODE_JFA | VF_MODE_FIM_FOCUS: Algorithm 10
                enqueue(events, "monolithic", k, cl::NDRange(chunk_count_ * group),
                        cl::NDRange(group));
                break;
            }
            case Algorithm::exact:
                throw std::logic_error("exact is not one of the dissertation's generators");
        }
        if (o_.algorithm != Algorithm::monolithic) {
            cl::Kernel encode(program_, "encode");
            encode.setArg(0, dist_);
            encode.setArg(1, vox_);
            encode.setArg(2, rgb_);
            encode.setArg(3, out_);
            encode.setArg(4, n);
            enqueue(events, "encode", encode, grid1_, local1_);
        }
        q.finish();
        if (count_fim_after) {
            std::vector<cl_uint> changes(fim_bound_ + 1);
            q.enqueueReadBuffer(changes_, CL_TRUE, 0, 4 * changes.size(), changes.data());
            if (changes[fim_bound_ - 1] != 0) {
                throw std::logic_error("FIM did not converge within " + std::to_string(fim_bound_) +
                                       " passes");
            }
            iterations_ = static_cast<std::uint32_t>(std::find(changes.begin(), changes.end(), 0u) -
                                                     changes.begin());
        }
        if (o_.algorithm == Algorithm::monolithic) {
            std::vector<cl_uint> per_chunk(chunk_count_);
            q.enqueueReadBuffer(chunk_iterations_, CL_TRUE, 0, 4 * per_chunk.size(),
                                per_chunk.data());
            iterations_ = *std::max_element(per_chunk.begin(), per_chunk.end());
        }
        record_stages(events);
        return elapsed_ms(events.front().second, events.back().second);
    });
}

}  // namespace

cl::Program classic_program(Context& ctx, Format format) {
    return ctx.program("classic",
                       {cl_sources::layout_h, cl_sources::classic_common_cl, cl_sources::brute_cl,
                        cl_sources::fim_cl, cl_sources::jfa_cl, cl_sources::monolithic_cl},
                       output_options(format));
}

std::unique_ptr<Generator> make_classic(Context& ctx, const World& world, const Palette& palette,
                                        const GeneratorOptions& options) {
    return std::make_unique<Classic>(ctx, world, palette, options);
}

}  // namespace voxfield::ocl
