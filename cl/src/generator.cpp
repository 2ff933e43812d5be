// Algorithm names, option checks and the pieces every generator shares.
#include "voxfield/cl/generator.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "classic.hpp"
#include "util.hpp"
#include "voxfield/cl/exact.hpp"
#include "voxfield/cl/separable.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/reference.hpp"

namespace voxfield::ocl {
namespace {

struct Named {
    Algorithm algorithm;
    const char* name;
};

constexpr Named kNames[] = {
    {Algorithm::exact, "exact"},
    {Algorithm::brute, "brute"},
    {Algorithm::brute_chunked, "brute-chunked"},
    {Algorithm::fim, "fim"},
    {Algorithm::fim_host, "fim-host"},
    {Algorithm::jfa, "jfa"},
    {Algorithm::jfa_host, "jfa-host"},
    {Algorithm::jfa_fim, "jfa-fim"},
    {Algorithm::lod, "lod"},
    {Algorithm::monolithic, "monolithic"},
};

bool uses_jfa(Algorithm a) {
    return a == Algorithm::jfa || a == Algorithm::jfa_host || a == Algorithm::jfa_fim ||
           a == Algorithm::lod || a == Algorithm::monolithic;
}

}  // namespace

const std::vector<std::string>& algorithm_names() {
    static const std::vector<std::string> names = [] {
        std::vector<std::string> v;
        for (const Named& n : kNames) {
            v.emplace_back(n.name);
        }
        return v;
    }();
    return names;
}

Algorithm parse_algorithm(const std::string& name) {
    for (const Named& n : kNames) {
        if (name == n.name) {
            return n.algorithm;
        }
    }
    std::string known;
    for (const auto& n : algorithm_names()) {
        known += (known.empty() ? "" : ", ") + n;
    }
    throw InputError("unknown algorithm '" + name + "': expected one of " + known);
}

std::string to_string(Algorithm a) {
    for (const Named& n : kNames) {
        if (n.algorithm == a) {
            return n.name;
        }
    }
    throw std::invalid_argument("unknown Algorithm value");
}

bool is_approximate(Algorithm a) {
    return a == Algorithm::jfa || a == Algorithm::jfa_host || a == Algorithm::lod;
}

bool always_chunked(Algorithm a) {
    return a == Algorithm::brute_chunked || a == Algorithm::lod || a == Algorithm::monolithic;
}

Format default_format(Metric metric, const Spacing& spacing, bool signed_field) {
    if (metric == Metric::euclidean || !spacing.unit()) {
        return Format::f32;
    }
    return signed_field ? Format::i16 : Format::u16;
}

GeneratorOptions resolve_options(const GeneratorOptions& options, Dims world) {
    GeneratorOptions o = options;
    const std::string name = to_string(o.algorithm);
    if (o.algorithm != Algorithm::exact) {
        if (o.metric != Metric::manhattan) {
            throw InputError("--metric " + to_string(o.metric) + ": " + name +
                             " (the dissertation's) computes manhattan distances only; use "
                             "--algorithm exact for " +
                             to_string(o.metric));
        }
        if (!o.spacing.unit()) {
            throw InputError("--spacing: " + name +
                             " works on unit spacing only; use --algorithm exact");
        }
        if (o.signed_field || o.indices) {
            throw InputError(std::string(o.signed_field ? "--signed" : "--indices") + ": " + name +
                             " has no " + (o.signed_field ? "signed fields" : "feature transform") +
                             "; use --algorithm exact");
        }
        if (holds_sign(o.format)) {
            throw InputError("--format " + to_string(o.format) + ": " + name +
                             " writes u8, u16, u32 or packed32 only");
        }
    }
    if (o.max_distance && !(std::isfinite(*o.max_distance) && *o.max_distance > 0)) {
        std::ostringstream text;
        text << *o.max_distance;
        throw InputError("--max-distance must be a positive number, not " + text.str());
    }
    // The kernels and a .vdb's background hold the bound as a float.
    if (o.max_distance && *o.max_distance > std::numeric_limits<float>::max()) {
        std::ostringstream text;
        text << *o.max_distance;
        throw InputError("--max-distance " + text.str() +
                         " is beyond float range (at most 3.4e38); leave it out for an "
                         "unbounded field");
    }
    if (o.max_distance && o.algorithm != Algorithm::exact) {
        throw InputError("--max-distance: " + name +
                         " has no bounded fields; use --algorithm exact");
    }
    if (o.max_distance && !is_float(o.format) && *o.max_distance < 1) {
        std::ostringstream text;
        text << *o.max_distance;
        throw InputError("--max-distance " + text.str() + " with --format " + to_string(o.format) +
                         ": integer formats round distances down, so every voxel would be 0; "
                         "give a bound of at least 1 or a float format (f32, f64)");
    }
    if (o.max_distance && o.indices) {
        throw InputError(
            "--indices with --max-distance: a bounded field stops looking for solids beyond "
            "the bound, so the indices there would not name the nearest solid; drop one of "
            "them");
    }
    check_spacing_range(o.spacing, o.metric, world);
    if (o.signed_field && !holds_sign(o.format)) {
        throw InputError("--signed needs a signed format (i8, i16, i32, f32 or f64), not " +
                         to_string(o.format));
    }
    if (o.signed_field && o.indices) {
        throw InputError(
            "--indices needs an unsigned field: the feature transform names the nearest solid "
            "voxel, which a signed field's solid voxels do not have; drop --signed or --indices");
    }
    if (o.algorithm == Algorithm::exact && o.chunk != 0) {
        throw InputError(
            "--chunk does not apply to exact, which computes the global field; chunk-local "
            "semantics belong to the dissertation's algorithms (brute-chunked, fim, jfa, ...)");
    }
    if (o.chunk == 0 && always_chunked(o.algorithm)) {
        o.chunk = kDefaultChunk;
    }
    if (o.chunk != 0) {
        require_chunk_fits(world, o.chunk);
    }
    const bool focused = o.algorithm == Algorithm::lod || o.algorithm == Algorithm::monolithic;
    if (o.focus && !focused) {
        throw InputError("--focus applies to lod and monolithic only, not to " + name);
    }
    if (focused) {
        const ChunkGrid grid(world, o.chunk);
        if (!o.focus) {
            const Dims n = grid.chunks();
            o.focus = Focus{{n.x / 2, n.y / 2, n.z / 2}, 1};
        }
        focus_chunks(grid, *o.focus);  // throws when outside the grid
    }
    if (o.jfa_extra > 2) {
        throw InputError("--jfa-extra " + std::to_string(o.jfa_extra) +
                         ": JFA+1 and JFA+2 are supported (0, 1 or 2 extra passes)");
    }
    if (o.jfa_extra != 0 && !uses_jfa(o.algorithm)) {
        throw InputError("--jfa-extra applies to the JFA-based algorithms, not to " + name);
    }
    return o;
}

std::vector<std::int32_t> Generator::read_indices() {
    if (indices_() == nullptr) {
        throw std::logic_error("read_indices: this generator was made without indices");
    }
    return cl_call("reading the feature transform of " + dims_.to_string(), [&] {
        std::vector<std::int32_t> idx(3 * dims_.count());
        ctx_.queue().enqueueReadBuffer(indices_, CL_TRUE, 0, idx.size() * 4, idx.data());
        return idx;
    });
}

namespace {

// A region of a buffer mapped for reading; unmapped when destroyed (a failing unmap has no one
// left to report to: the exception that ends the read is the one to report).
class MappedSlab {
  public:
    MappedSlab(cl::CommandQueue& queue, const cl::Buffer& buffer, std::size_t offset,
               std::size_t bytes)
        : queue_(queue), buffer_(buffer), offset_(offset), size_(bytes) {
        data_ = static_cast<const std::uint8_t*>(queue_.enqueueMapBuffer(
            buffer_, CL_FALSE, CL_MAP_READ, offset, bytes, nullptr, &ready_));
    }
    ~MappedSlab() {
        try {
            queue_.enqueueUnmapMemObject(buffer_, const_cast<std::uint8_t*>(data_));
        } catch (const cl::Error&) {
        }
    }
    MappedSlab(const MappedSlab&) = delete;
    MappedSlab& operator=(const MappedSlab&) = delete;

    std::size_t end() const { return offset_ + size_; }
    // Waits for the map; the slab's bytes.
    std::span<const std::uint8_t> bytes() {
        ready_.wait();
        return {data_, size_};
    }

  private:
    cl::CommandQueue& queue_;
    const cl::Buffer& buffer_;
    std::size_t offset_, size_;
    const std::uint8_t* data_ = nullptr;
    cl::Event ready_;
};

}  // namespace

void Generator::read_indices(const IndexSink& sink, std::size_t slab_bytes) {
    if (indices_() == nullptr) {
        throw std::logic_error("read_indices: this generator was made without indices");
    }
    if (slab_bytes == 0) {
        throw std::invalid_argument("read_indices: slab_bytes must be positive");
    }
    const std::size_t total = 3 * dims_.count() * sizeof(std::int32_t);
    cl_call("reading the feature transform of " + dims_.to_string(), [&] {
        auto& q = ctx_.queue();
        auto map_from = [&](std::size_t offset) {
            return offset < total ? std::make_unique<MappedSlab>(
                                        q, indices_, offset, std::min(slab_bytes, total - offset))
                                  : nullptr;
        };
        std::unique_ptr<MappedSlab> slab = map_from(0);
        while (slab) {
            const std::span<const std::uint8_t> bytes = slab->bytes();
            std::unique_ptr<MappedSlab> next = map_from(slab->end());
            sink(bytes);
            slab = std::move(next);  // unmaps the slab just written
        }
        q.finish();
    });
}

std::vector<std::uint32_t> exact_reference(const World& world, const GeneratorOptions& options) {
    return options.chunk == 0 ? reference_manhattan(world)
                              : reference_manhattan_chunked(world, options.chunk);
}

std::vector<std::uint8_t> Generator::read(double* download_ms) {
    return cl_call("reading the field of " + dims_.to_string(), [&] {
        std::vector<std::uint8_t> bytes(dims_.count() * element_size(format_));
        cl::Event ev;
        ctx_.queue().enqueueReadBuffer(out_, CL_TRUE, 0, bytes.size(), bytes.data(), nullptr, &ev);
        if (download_ms != nullptr) {
            *download_ms = elapsed_ms(ev, ev);
        }
        return bytes;
    });
}

Generator::~Generator() {
    if (!host_memory_.empty()) {
        // The host memory is freed after this; nothing queued may still use it.
        try {
            ctx_.queue().finish();
        } catch (const cl::Error&) {
        }
    }
}

cl::Buffer Generator::make_buffer(std::size_t bytes, cl_mem_flags flags) {
    if (!ctx_.computes_in_host_memory()) {
        return cl::Buffer(ctx_.context(), flags, bytes);
    }
    host_memory_.emplace_back(bytes);
    return cl::Buffer(ctx_.context(), flags | CL_MEM_USE_HOST_PTR, bytes,
                      host_memory_.back().data());
}

void Generator::enqueue_stages(std::span<const KernelLaunch> stages,
                               std::vector<std::pair<std::string, cl::Event>>& events,
                               bool with_events) {
    last_enqueued_ = stages.size();
    for (const KernelLaunch& stage : stages) {
        ctx_.queue().enqueueNDRangeKernel(stage.kernel, cl::NullRange, stage.global, stage.local,
                                          nullptr,
                                          stage_event(with_events ? &events : nullptr, stage.name));
    }
}

void Generator::record_stages(const std::vector<std::pair<std::string, cl::Event>>& events) {
    stage_ms_.clear();
    for (const auto& [name, event] : events) {
        const double ms = elapsed_ms(event, event);
        auto it = std::find_if(stage_ms_.begin(), stage_ms_.end(),
                               [&](const auto& s) { return s.first == name; });
        if (it == stage_ms_.end()) {
            stage_ms_.emplace_back(name, ms);
        } else {
            it->second += ms;
        }
    }
}

std::unique_ptr<Generator> make_generator(Context& ctx, const World& world, const Palette& palette,
                                          const GeneratorOptions& options) {
    const GeneratorOptions o = resolve_options(options, world.dims());
    if (o.algorithm == Algorithm::exact) {
        if (ExactManhattan::handles(ctx, o, world.dims())) {
            return std::make_unique<ExactManhattan>(ctx, world, palette, o.format, o.layout,
                                                    o.metric, o.max_distance);
        }
        return std::make_unique<ExactSeparable>(ctx, world, palette, o);
    }
    return make_classic(ctx, world, palette, o);
}

FieldResult generate(Context& ctx, const World& world, const Palette& palette,
                     const GeneratorOptions& options) {
    auto job = make_generator(ctx, world, palette, options);
    FieldResult result;
    result.timing.upload_ms = job->upload_ms();
    result.timing.kernel_ms = job->run();
    result.iterations = job->iterations();
    result.bytes = job->read(&result.timing.download_ms);
    if (options.indices) {
        result.indices = job->read_indices();
    }
    return result;
}

}  // namespace voxfield::ocl
