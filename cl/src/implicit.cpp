// Implicit parts discretised into a tile grid of contrees (the reference blog, farfa.dev
// "implicit surface rendering for CAD"), host side; kernels: cl/kernels/implicit.cl.
//
// The tape is interpreted by the kernels (one program for every part) rather than emitted as
// OpenCL source per part: a per-part build costs a compiler run (hundreds of ms on PoCL), more
// than the whole discretisation of a gallery part.
#include "voxfield/cl/implicit.hpp"

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>

#include "util.hpp"

namespace voxfield::cl_sources {
extern const char* const sdf_layout_h;
extern const char* const implicit_tape_cl;
extern const char* const implicit_eval_cl;
extern const char* const implicit_cl;
}  // namespace voxfield::cl_sources

namespace voxfield::ocl {
namespace {

// Points the CPU layout evaluates per instruction fetch (one AVX2 register of floats).
constexpr int kLanes = 8;

// implicit.cl after the tape's types and implicit_eval.cl twice: the scalar evaluator
// (eval_f) and the kLanes-wide one (eval_f_v), with the vector types the CPU layout uses.
std::vector<std::string> program_sources() {
    const std::string w = std::to_string(kLanes);
    std::string iota = "(uint" + w + ")(";
    for (int i = 0; i < kLanes; ++i) {
        iota += (i ? ", " : "") + std::to_string(i);
    }
    iota += ")";
    const std::string undef = "#undef FT\n#undef MT\n#undef EV_SUF\n";
    return {cl_sources::sdf_layout_h,
            cl_sources::implicit_tape_cl,
            "#define FT float\n#define MT uint\n#define EV_SUF\n",
            cl_sources::implicit_eval_cl,
            undef,
            "#define FT float" + w + "\n#define MT int" + w + "\n#define EV_SUF _v\n",
            cl_sources::implicit_eval_cl,
            undef,
            "#define EV_W " + w + "\n#define FTV float" + w + "\n#define MTV int" + w +
                "\n#define UTV uint" + w + "\n#define EV_CONVERT convert_float" + w +
                "\n#define EV_STORE vstore" + w + "\n#define EV_LOAD vload" + w +
                "\n#define EV_IOTA " + iota + "\n",
            cl_sources::implicit_cl};
}

struct GridArg {
    cl_float x0, y0, z0, h;
    cl_uint nx, ny, nz, pad;
};
static_assert(sizeof(GridArg) == 32);
static_assert(sizeof(cl_uint4) == 16);

GridArg grid_arg(const sdf::Part& part) {
    return {static_cast<float>(part.lo[0]),
            static_cast<float>(part.lo[1]),
            static_cast<float>(part.lo[2]),
            static_cast<float>(part.voxel_size),
            part.dims.x,
            part.dims.y,
            part.dims.z,
            0};
}

// The leaves' `decided`: a corner whose |f| exceeds it gives its voxel's centre its sign.
// Every primitive and operator of a part is a 1-Lipschitz distance bound (planes' normals are
// normalised, transforms scale uniformly), so f changes by at most half the voxel's diagonal
// between a corner and the centre; the margin covers float rounding: 2^-10 of that distance
// plus 2^-12 of the largest magnitude the evaluation meets (grid coordinates and the tape's
// parameters, each times the scale of the transforms around it).
float centre_decided(const sdf::Part& part) {
    double mag = 0;
    for (int a = 0; a < 3; ++a) {
        const std::uint32_t n = a == 0 ? part.dims.x : (a == 1 ? part.dims.y : part.dims.z);
        mag = std::max({mag, std::abs(part.lo[a]), std::abs(part.lo[a] + n * part.voxel_size)});
    }
    std::vector<double> scale{1.0};
    for (const sdf::Instr& in : part.tape.code) {
        if (in.op == VF_SDF_PUSH_POINT) {
            for (int i = 9; i < 12; ++i) {
                mag = std::max(mag, std::abs(double(in.p[i])) * scale.back());
            }
            const double row = std::sqrt(double(in.p[0]) * in.p[0] + double(in.p[1]) * in.p[1] +
                                         double(in.p[2]) * in.p[2]);
            scale.push_back(scale.back() / row);
        } else if (in.op == VF_SDF_POP_POINT) {
            scale.pop_back();
        } else if (in.op <= VF_SDF_PLANE || in.op == VF_SDF_SHELL) {
            for (int i = 0; i < 7; ++i) {
                mag = std::max(mag, std::abs(double(in.p[i])) * scale.back());
            }
        } else {
            mag = std::max(mag, std::abs(double(in.p[0])) * scale.back());
        }
    }
    const double half_diagonal = 0.5 * std::sqrt(3.0) * part.voxel_size;
    return static_cast<float>(half_diagonal * (1 + 0x1p-10) + mag * 0x1p-12);
}

double event_ms(const cl::Event& e) {
    return elapsed_ms(e, e);
}

constexpr std::uint32_t kMaxDepth = 8;
static_assert(kMaxDepth + 1 == VF_SDF_MAX_LEVELS);
// Work-group sizes, fixed so that a device compiling per work-group size (PoCL) compiles each
// kernel once: interval tests, and leaves in the CPU layout (one work-item each).
constexpr std::size_t kGroup = 64;
constexpr std::size_t kLeafGroup = 8;
// The GPU layout's leaves: a work-group of 128 (125 corners, 64 centres).
constexpr std::size_t kLeafGroupGpu = 128;

}  // namespace

ImplicitDiscretiser::ImplicitDiscretiser(Context& ctx, const sdf::Part& part,
                                         ImplicitOptions options)
    : ctx_(ctx),
      part_(part),
      options_(options),
      gpu_layout_(options.layout == Layout::automatic ? !ctx.is_cpu()
                                                      : options.layout == Layout::gpu),
      decided_(centre_decided(part)),
      host_counters_(VF_SDF_COUNTERS, 0),
      staged_(!ctx.computes_in_host_memory()) {
    if (options.tile_depth > kMaxDepth) {
        throw InputError("implicit tile depth " + std::to_string(options.tile_depth) +
                         " is out of range (0.." + std::to_string(kMaxDepth) + ")");
    }
    program_ = ctx.program("implicit.cl", program_sources(),
                           "-cl-std=CL1.2 -cl-fp32-correctly-rounded-divide-sqrt");
    tape_ = cl_call("uploading the implicit tape", [&] {
        return cl::Buffer(ctx.context(), CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR,
                          part.tape.code.size() * sizeof(sdf::Instr),
                          const_cast<sdf::Instr*>(part.tape.code.data()));
    });
}

ImplicitDiscretiser::~ImplicitDiscretiser() {
    try {
        unmap(small_stage_);
        unmap(out_stage_);
        ctx_.queue().finish();
    } catch (const std::exception&) {
        // a failing device at teardown: the context's release frees what is left
    }
}

void ImplicitDiscretiser::unmap(Pinned& p) {
    if (p.data != nullptr) {
        ctx_.queue().enqueueUnmapMemObject(p.buffer, p.data);
        p.data = nullptr;
    }
}

std::uint8_t* ImplicitDiscretiser::pinned(Pinned& p, std::size_t bytes) {
    if (bytes > p.capacity || p.data == nullptr) {
        unmap(p);
        p.capacity = std::max({bytes, p.capacity + p.capacity / 2, std::size_t{4096}});
        p.buffer =
            cl::Buffer(ctx_.context(), CL_MEM_READ_WRITE | CL_MEM_ALLOC_HOST_PTR, p.capacity);
        p.data = static_cast<std::uint8_t*>(ctx_.queue().enqueueMapBuffer(
            p.buffer, CL_TRUE, CL_MAP_READ | CL_MAP_WRITE, 0, p.capacity));
        timing_.enqueues += 2;  // the unmap (of the smaller stage, if any) and the map
        ++timing_.syncs;
    }
    return p.data;
}

namespace {

// memcpy of several arrays, split over a few threads when large (page-locked staging to the
// grid's arrays: one thread copies at a fraction of the memory bandwidth). The crew's threads
// start when it is made, before the host waits for the device, so that starting them overlaps
// the device's work; they copy when run() hands them the arrays (or nothing, at destruction).
struct Copy {
    void* dst;
    const void* src;
    std::size_t bytes;
};
class CopyCrew {
  public:
    // For about `bytes` in all.
    explicit CopyCrew(std::size_t bytes) {
        constexpr std::size_t kPerThread = std::size_t{2} << 20;
        threads_ = static_cast<unsigned>(std::min<std::size_t>(
            {std::max(1u, std::thread::hardware_concurrency()), 8, bytes / kPerThread + 1}));
        try {
            for (unsigned t = 1; t < threads_; ++t) {
                pool_.emplace_back([this, t] {
                    go_.wait(false);
                    part(t);
                });
            }
        } catch (...) {
            finish();
            throw;
        }
    }
    ~CopyCrew() { finish(); }
    CopyCrew(const CopyCrew&) = delete;
    CopyCrew& operator=(const CopyCrew&) = delete;

    // Copies them all (this thread one share), returning when every thread is done.
    void run(std::vector<Copy> copies) {
        copies_ = std::move(copies);
        for (const Copy& c : copies_) {
            total_ += c.bytes;
        }
        finish();
    }

  private:
    void finish() {
        if (done_) {
            return;
        }
        done_ = true;
        go_ = true;
        go_.notify_all();
        part(0);
        for (std::thread& th : pool_) {
            th.join();
        }
    }
    // Share t: bytes [t total / threads, (t + 1) total / threads) of the concatenation.
    void part(unsigned t) const {
        const std::size_t lo = total_ * t / threads_, hi = total_ * (t + 1) / threads_;
        std::size_t at = 0;
        for (const Copy& c : copies_) {
            const std::size_t a = std::max(lo, at), b = std::min(hi, at + c.bytes);
            if (a < b) {
                std::memcpy(static_cast<std::uint8_t*>(c.dst) + (a - at),
                            static_cast<const std::uint8_t*>(c.src) + (a - at), b - a);
            }
            at += c.bytes;
        }
    }
    unsigned threads_ = 1;
    std::vector<Copy> copies_;
    std::size_t total_ = 0;
    std::atomic<bool> go_{false};
    bool done_ = false;
    std::vector<std::thread> pool_;
};

}  // namespace

ImplicitGrid ImplicitDiscretiser::run() {
    ImplicitGrid out;
    run(out);
    return out;
}

void ImplicitDiscretiser::grow(cl::Buffer& buffer, std::size_t& capacity, std::size_t bytes,
                               std::size_t keep_bytes) {
    if (bytes <= capacity && buffer.get() != nullptr) {
        return;
    }
    const std::size_t grown_capacity = std::max({bytes, capacity + capacity / 2, std::size_t{64}});
    cl::Buffer grown(ctx_.context(), CL_MEM_READ_WRITE, grown_capacity);
    if (keep_bytes > 0) {
        ctx_.queue().enqueueCopyBuffer(buffer, grown, 0, 0, std::min(keep_bytes, capacity));
        ++timing_.enqueues;
    }
    buffer = std::move(grown);
    capacity = grown_capacity;
}

void ImplicitDiscretiser::expect(const ImplicitCounts& expected) {
    if (expected.nodes.size() != options_.tile_depth + 1) {
        throw std::invalid_argument("implicit: expected counts of " +
                                    std::to_string(expected.nodes.size()) + " levels, not " +
                                    std::to_string(options_.tile_depth + 1));
    }
    counts_ = expected;
}

namespace {

enum Stage { kTiles, kLevels, kLeaves, kRead };

double ms_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

void ImplicitDiscretiser::wait() {
    const auto w0 = std::chrono::steady_clock::now();
    ctx_.queue().finish();
    ++timing_.syncs;
    timing_.wait_ms += ms_since(w0);
}

void ImplicitDiscretiser::zero_counters(std::uint32_t first, std::uint32_t count) {
    ctx_.queue().enqueueWriteBuffer(counters_buf_, CL_FALSE, first * sizeof(cl_uint),
                                    count * sizeof(cl_uint), zeros_.data());
    ++timing_.enqueues;
}

const cl_uint* ImplicitDiscretiser::read_counters() {
    const std::size_t bytes = VF_SDF_COUNTERS * sizeof(cl_uint);
    cl_uint* dst =
        staged_ ? reinterpret_cast<cl_uint*>(pinned(small_stage_, bytes)) : host_counters_.data();
    const auto w0 = std::chrono::steady_clock::now();
    ctx_.queue().enqueueReadBuffer(counters_buf_, CL_TRUE, 0, bytes, dst);
    ++timing_.enqueues;
    ++timing_.syncs;
    timing_.wait_ms += ms_since(w0);
    return dst;
}

void ImplicitDiscretiser::enqueue_tiles(const ImplicitGrid& out, std::size_t capacity) {
    cl::Kernel& k = classify_tiles_;
    const std::size_t tiles = out.tiles.count();
    k.setArg(3, out.tiles.x);
    k.setArg(4, out.tiles.y);
    k.setArg(5, static_cast<cl_uint>(tiles));
    k.setArg(6, out.tile_edge);
    k.setArg(7, table_buf_);
    k.setArg(8, origins_buf_[0]);
    k.setArg(9, lists_buf_[0]);
    k.setArg(10, static_cast<cl_uint>(capacity));
    k.setArg(11, counters_buf_);
    cl::Event e;
    ctx_.queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(round_up(tiles, kGroup)),
                                      cl::NDRange(kGroup), nullptr, &e);
    ++timing_.enqueues;
    events_.emplace_back(kTiles, std::move(e));
}

void ImplicitDiscretiser::enqueue_level(std::uint32_t level, std::size_t capacity,
                                        std::size_t next_capacity, std::size_t node_capacity,
                                        std::size_t groups) {
    const std::uint32_t at = level % 2, next = at ^ 1;
    const cl_uint edge = (1u << (2 * (options_.tile_depth + 1))) >> (2 * level);
    cl::Kernel& k = classify_children_;
    k.setArg(3, origins_buf_[at]);
    k.setArg(4, lists_buf_[at]);
    k.setArg(5, static_cast<cl_uint>(level));
    k.setArg(6, static_cast<cl_uint>(capacity));
    k.setArg(7, edge);
    k.setArg(8, origins_buf_[next]);
    k.setArg(9, lists_buf_[next]);
    k.setArg(10, static_cast<cl_uint>(next_capacity));
    k.setArg(11, counters_buf_);
    k.setArg(12, nodes_buf_);
    k.setArg(13, static_cast<cl_uint>(node_capacity));
    cl::Event e;
    ctx_.queue().enqueueNDRangeKernel(k, cl::NullRange,
                                      cl::NDRange(std::max<std::size_t>(groups, 1) * kGroup),
                                      cl::NDRange(kGroup), nullptr, &e);
    ++timing_.enqueues;
    events_.emplace_back(kLevels, std::move(e));
}

void ImplicitDiscretiser::enqueue_leaves(std::size_t capacity, std::size_t node_capacity,
                                         std::size_t vertices, std::size_t voxels,
                                         std::size_t groups) {
    const std::uint32_t level = options_.tile_depth, at = level % 2;
    cl::Kernel& k = sample_leaves_;
    k.setArg(3, origins_buf_[at]);
    k.setArg(4, lists_buf_[at]);
    k.setArg(5, static_cast<cl_uint>(level));
    k.setArg(6, static_cast<cl_uint>(capacity));
    k.setArg(7, nodes_buf_);
    k.setArg(8, static_cast<cl_uint>(node_capacity));
    k.setArg(9, voxels_buf_);
    k.setArg(10, static_cast<cl_uint>(voxels));
    k.setArg(11, vertices_buf_);
    k.setArg(12, static_cast<cl_uint>(vertices));
    k.setArg(13, counters_buf_);
    k.setArg(14, decided_);
    groups = std::max<std::size_t>(groups, 1);
    cl::Event e;
    if (gpu_layout_) {
        ctx_.queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(groups * kLeafGroupGpu),
                                          cl::NDRange(kLeafGroupGpu), nullptr, &e);
    } else {
        ctx_.queue().enqueueNDRangeKernel(k, cl::NullRange,
                                          cl::NDRange(round_up(groups, kLeafGroup)),
                                          cl::NDRange(kLeafGroup), nullptr, &e);
    }
    ++timing_.enqueues;
    ++timing_.passes;
    events_.emplace_back(kLeaves, std::move(e));
}

std::size_t ImplicitDiscretiser::list_bytes() const {
    const std::size_t n = part_.tape.code.size();
    return n <= VF_SDF_SPECIALISE_MAX ? (n + 1) * sizeof(cl_ushort) : 0;
}

void ImplicitDiscretiser::size_levels(const Caps& caps, std::size_t tiles) {
    grow(counters_buf_, counters_cap_, VF_SDF_COUNTERS * sizeof(cl_uint));
    grow(table_buf_, table_cap_, tiles * sizeof(cl_uint));
    std::size_t nodes = 0;
    for (std::size_t l = 0; l < caps.level.size(); ++l) {
        const std::size_t at = l % 2;
        grow(origins_buf_[at], origins_cap_[at], caps.level[l] * sizeof(cl_uint4));
        grow(lists_buf_[at], lists_cap_[at], caps.level[l] * list_bytes());
        nodes += caps.level[l];
    }
    for (int at = 0; at < 2; ++at) {
        grow(origins_buf_[at], origins_cap_[at], sizeof(cl_uint4));
        grow(lists_buf_[at], lists_cap_[at], sizeof(cl_ushort));
    }
    grow(nodes_buf_, nodes_cap_, nodes * VF_SDF_NODE_WORDS * sizeof(cl_uint));
    grow(voxels_buf_, voxels_cap_, caps.voxels * VF_SDF_VOXEL_WORDS * sizeof(cl_uint));
    grow(vertices_buf_, vertices_cap_, caps.vertices * VF_SDF_VERTEX_FLOATS * sizeof(cl_float));
}

void ImplicitDiscretiser::read_output(ImplicitGrid& out, std::size_t node_words,
                                      std::size_t voxel_words, std::size_t vertex_floats) {
    auto& q = ctx_.queue();
    const std::size_t counter_bytes = VF_SDF_COUNTERS * sizeof(cl_uint);
    struct Part {
        const cl::Buffer* src;
        std::size_t bytes;
    };
    const Part parts[5] = {{&counters_buf_, counter_bytes},
                           {&table_buf_, out.tile_table.size() * sizeof(cl_uint)},
                           {&nodes_buf_, node_words * sizeof(cl_uint)},
                           {&voxels_buf_, voxel_words * sizeof(cl_uint)},
                           {&vertices_buf_, vertex_floats * sizeof(cl_float)}};
    std::size_t total = 0;
    for (const Part& p : parts) {
        total += p.bytes;
    }
    std::uint8_t* stage = staged_ ? pinned(out_stage_, total) : nullptr;
    std::optional<CopyCrew> crew;  // started now, to copy the stage after the wait
    void* direct[5] = {host_counters_.data(), out.tile_table.data(), nullptr, nullptr, nullptr};
    if (!staged_) {
        out.nodes.resize(node_words);
        out.voxels.resize(voxel_words);
        out.vertices.resize(vertex_floats);
        direct[2] = out.nodes.data();
        direct[3] = out.voxels.data();
        direct[4] = out.vertices.data();
    }
    std::size_t offset[5];
    std::size_t at = 0;
    for (int i = 0; i < 5; ++i) {
        offset[i] = at;
        if (parts[i].bytes == 0) {
            continue;
        }
        cl::Event e;
        q.enqueueReadBuffer(*parts[i].src, CL_FALSE, 0, parts[i].bytes,
                            staged_ ? stage + at : direct[i], nullptr, &e);
        ++timing_.enqueues;
        events_.emplace_back(kRead, std::move(e));
        at += parts[i].bytes;
    }
    if (staged_) {
        crew.emplace(total);
    }
    wait();
    const auto c0 = std::chrono::steady_clock::now();
    // What the run produced: no more than the counters say.
    {
        const auto* c = reinterpret_cast<const cl_uint*>(staged_ ? stage : direct[0]);
        std::size_t nodes = 0;
        for (std::uint32_t l = 0; l <= options_.tile_depth; ++l) {
            nodes += c[l];
        }
        if (staged_) {
            std::memcpy(host_counters_.data(), c, counter_bytes);
        }
        node_words = std::min(node_words, nodes * VF_SDF_NODE_WORDS);
        voxel_words =
            std::min(voxel_words, std::size_t{c[VF_SDF_COUNT_VOXELS]} * VF_SDF_VOXEL_WORDS);
        vertex_floats =
            std::min(vertex_floats, std::size_t{c[VF_SDF_COUNT_VERTICES]} * VF_SDF_VERTEX_FLOATS);
    }
    out.nodes.resize(node_words);
    out.voxels.resize(voxel_words);
    out.vertices.resize(vertex_floats);
    if (staged_) {
        crew->run({{out.tile_table.data(), stage + offset[1], parts[1].bytes},
                   {out.nodes.data(), stage + offset[2], node_words * sizeof(cl_uint)},
                   {out.voxels.data(), stage + offset[3], voxel_words * sizeof(cl_uint)},
                   {out.vertices.data(), stage + offset[4], vertex_floats * sizeof(cl_float)}});
    }
    timing_.copy_ms += ms_since(c0);
}

bool ImplicitDiscretiser::attempt_at_once(ImplicitGrid& out, const Caps& caps) {
    const std::uint32_t depth = options_.tile_depth;
    size_levels(caps, out.tiles.count());
    std::size_t node_capacity = 0;
    for (std::size_t c : caps.level) {
        node_capacity += c;
    }
    zero_counters(0, VF_SDF_COUNTERS);
    enqueue_tiles(out, caps.level[0]);
    for (std::uint32_t l = 0; l < depth; ++l) {
        enqueue_level(l, caps.level[l], caps.level[l + 1], node_capacity, caps.level[l]);
    }
    enqueue_leaves(caps.level[depth], node_capacity, caps.vertices, caps.voxels, caps.level[depth]);
    read_output(out, node_capacity * VF_SDF_NODE_WORDS, caps.voxels * VF_SDF_VOXEL_WORDS,
                caps.vertices * VF_SDF_VERTEX_FLOATS);
    const cl_uint* c = host_counters_.data();
    bool fits = c[VF_SDF_COUNT_VERTICES] <= caps.vertices && c[VF_SDF_COUNT_VOXELS] <= caps.voxels;
    for (std::uint32_t l = 0; l <= depth; ++l) {
        fits = fits && c[l] <= caps.level[l];
    }
    if (fits) {
        counts_.nodes.assign(c, c + depth + 1);
        counts_.vertices = c[VF_SDF_COUNT_VERTICES];
        counts_.voxels = c[VF_SDF_COUNT_VOXELS];
    }
    return fits;
}

void ImplicitDiscretiser::attempt_counted(ImplicitGrid& out) {
    timing_.counted = true;
    const std::uint32_t depth = options_.tile_depth;
    const std::size_t tiles = out.tiles.count();
    // First guesses of the room a level needs (a larger expected count when there is one);
    // a level whose count passes its room runs again at that count.
    auto expected = [&](std::uint32_t l) -> std::size_t {
        return counts_.nodes.size() == depth + 1 ? counts_.nodes[l] : 0;
    };
    Caps caps;
    caps.level.assign(depth + 1, 0);
    size_levels(caps, tiles);
    std::vector<std::size_t> count(depth + 1, 0);
    std::size_t nodes = 0;  // nodes of the levels counted so far

    std::size_t room = std::min(tiles, std::max({std::size_t{1024}, tiles / 2, expected(0)}));
    auto tiles_at = [&](std::size_t r) {
        grow(origins_buf_[0], origins_cap_[0], r * sizeof(cl_uint4));
        grow(lists_buf_[0], lists_cap_[0], r * list_bytes());
        zero_counters(0, VF_SDF_COUNTERS);
        enqueue_tiles(out, r);
        return read_counters()[0];
    };
    count[0] = tiles_at(room);
    if (count[0] > room) {
        ++timing_.level_reruns;
        count[0] = tiles_at(count[0]);
    }
    nodes = count[0];
    for (std::uint32_t l = 0; l < depth && count[l] > 0; ++l) {
        const std::uint32_t next = (l + 1) % 2;
        // This level's records go after the levels above it (kept when the buffer grows).
        grow(nodes_buf_, nodes_cap_, nodes * VF_SDF_NODE_WORDS * sizeof(cl_uint),
             (nodes - count[l]) * VF_SDF_NODE_WORDS * sizeof(cl_uint));
        auto level_at = [&](std::size_t r) {
            grow(origins_buf_[next], origins_cap_[next], r * sizeof(cl_uint4));
            grow(lists_buf_[next], lists_cap_[next], r * list_bytes());
            zero_counters(l + 1, 1);
            enqueue_level(l, count[l], r, nodes, count[l]);
            return read_counters()[l + 1];
        };
        room =
            std::min(64 * count[l], std::max({std::size_t{1024}, 48 * count[l], expected(l + 1)}));
        count[l + 1] = level_at(room);
        if (count[l + 1] > room) {
            ++timing_.level_reruns;
            count[l + 1] = level_at(count[l + 1]);
        }
        nodes += count[l + 1];
    }

    std::size_t vertices = 0, voxels = 0;
    const std::size_t leaves = count[depth];
    if (leaves > 0) {
        grow(nodes_buf_, nodes_cap_, nodes * VF_SDF_NODE_WORDS * sizeof(cl_uint),
             (nodes - leaves) * VF_SDF_NODE_WORDS * sizeof(cl_uint));
        // Room for the crossed voxels and kept corners: a guess per leaf, or the expected
        // counts when larger (a second pass when even those overflow).
        std::size_t vcap =
            std::max({std::size_t{1024}, leaves * 48, std::size_t{counts_.vertices}});
        std::size_t xcap = std::max({std::size_t{1024}, leaves * 24, std::size_t{counts_.voxels}});
        while (true) {
            grow(voxels_buf_, voxels_cap_, xcap * VF_SDF_VOXEL_WORDS * sizeof(cl_uint));
            grow(vertices_buf_, vertices_cap_, vcap * VF_SDF_VERTEX_FLOATS * sizeof(cl_float));
            zero_counters(VF_SDF_COUNT_VERTICES, 2);
            enqueue_leaves(leaves, nodes, vcap, xcap, leaves);
            const cl_uint* c = read_counters();
            vertices = c[VF_SDF_COUNT_VERTICES];
            voxels = c[VF_SDF_COUNT_VOXELS];
            if (vertices <= vcap && voxels <= xcap) {
                break;
            }
            vcap = std::max(vcap, vertices);
            xcap = std::max(xcap, voxels);
        }
    }
    read_output(out, nodes * VF_SDF_NODE_WORDS, voxels * VF_SDF_VOXEL_WORDS,
                vertices * VF_SDF_VERTEX_FLOATS);
    counts_.nodes.assign(count.begin(), count.end());
    counts_.vertices = static_cast<std::uint32_t>(vertices);
    counts_.voxels = static_cast<std::uint32_t>(voxels);
}

void ImplicitDiscretiser::run(ImplicitGrid& out) {
    const auto t0 = std::chrono::steady_clock::now();
    timing_ = {};
    events_.clear();
    const cl_uint n = static_cast<cl_uint>(part_.tape.code.size());
    const GridArg g = grid_arg(part_);
    out.dims = part_.dims;
    out.tile_depth = options_.tile_depth;
    out.tile_edge = 1u << (2 * (options_.tile_depth + 1));
    const std::uint32_t edge = out.tile_edge;
    out.tiles = {(out.dims.x + edge - 1) / edge, (out.dims.y + edge - 1) / edge,
                 (out.dims.z + edge - 1) / edge};
    out.tile_table.resize(out.tiles.count());
    cl_call("implicit discretisation (" + std::to_string(n) + " instructions, grid " +
                out.dims.to_string() + ", tile depth " + std::to_string(options_.tile_depth) + ")",
            [&] {
                if (!kernels_made_) {
                    classify_tiles_ = cl::Kernel(program_, "classify_tiles");
                    classify_children_ = cl::Kernel(program_, "classify_children");
                    sample_leaves_ = cl::Kernel(
                        program_, gpu_layout_ ? "sample_leaves_group" : "sample_leaves_seq");
                    for (cl::Kernel* k : {&classify_tiles_, &classify_children_, &sample_leaves_}) {
                        k->setArg(0, tape_);
                        k->setArg(1, n);
                        k->setArg(2, g);
                    }
                    kernels_made_ = true;
                }
                bool done = false;
                if (counts_.nodes.size() == options_.tile_depth + 1) {
                    Caps caps;
                    caps.level.assign(counts_.nodes.begin(), counts_.nodes.end());
                    caps.vertices = counts_.vertices;
                    caps.voxels = counts_.voxels;
                    done = attempt_at_once(out, caps);
                }
                if (!done) {
                    attempt_counted(out);
                }
                out.leaves = counts_.nodes.back();
                for (const auto& [stage, e] : events_) {
                    const double ms = event_ms(e);
                    (stage == kTiles    ? timing_.tiles_ms
                     : stage == kLevels ? timing_.levels_ms
                     : stage == kLeaves ? timing_.leaves_ms
                                        : timing_.read_ms) += ms;
                    if (stage != kRead) {
                        timing_.kernel_ms += ms;
                    }
                }
            });
    timing_.total_ms = ms_since(t0);
    timing_.host_ms = timing_.total_ms - timing_.wait_ms - timing_.copy_ms;
}

std::vector<float> ImplicitDiscretiser::sample_corners() {
    const Dims d = part_.dims;
    const std::size_t count = std::size_t{d.x + 1} * (d.y + 1) * (d.z + 1);
    std::vector<float> out(count);
    cl_call("implicit sample_corners", [&] {
        cl::Buffer buf(ctx_.context(), CL_MEM_WRITE_ONLY, count * sizeof(float));
        cl::Kernel k(program_, "sample_corners");
        k.setArg(0, tape_);
        k.setArg(1, static_cast<cl_uint>(part_.tape.code.size()));
        k.setArg(2, grid_arg(part_));
        k.setArg(3, buf);
        ctx_.queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(round_up(count, kGroup)),
                                          cl::NDRange(kGroup));
        ctx_.queue().enqueueReadBuffer(buf, CL_TRUE, 0, count * sizeof(float), out.data());
    });
    return out;
}

std::vector<float> ImplicitDiscretiser::sample_centres() {
    const Dims d = part_.dims;
    std::vector<float> out(d.count());
    cl_call("implicit sample_centres", [&] {
        cl::Buffer buf(ctx_.context(), CL_MEM_WRITE_ONLY, d.count() * sizeof(float));
        cl::Kernel k(program_, "sample_centres");
        k.setArg(0, tape_);
        k.setArg(1, static_cast<cl_uint>(part_.tape.code.size()));
        k.setArg(2, grid_arg(part_));
        k.setArg(3, buf);
        ctx_.queue().enqueueNDRangeKernel(
            k, cl::NullRange, cl::NDRange(round_up(d.count(), kGroup)), cl::NDRange(kGroup));
        ctx_.queue().enqueueReadBuffer(buf, CL_TRUE, 0, d.count() * sizeof(float), out.data());
    });
    return out;
}

std::size_t ImplicitGrid::bytes() const {
    return (tile_table.size() + nodes.size() + voxels.size()) * sizeof(std::uint32_t) +
           vertices.size() * sizeof(float);
}

namespace {

// Visits every node of a grid: (node index, voxel origin, node edge in voxels).
void walk(
    const ImplicitGrid& g,
    const std::function<void(std::uint32_t, std::uint32_t, std::uint32_t, std::uint32_t,
                             std::uint32_t)>& leaf,
    const std::function<void(std::uint32_t, std::uint32_t, std::uint32_t, std::uint32_t)>& full) {
    std::function<void(std::uint32_t, std::uint32_t, std::uint32_t, std::uint32_t, std::uint32_t)>
        node = [&](std::uint32_t index, std::uint32_t x, std::uint32_t y, std::uint32_t z,
                   std::uint32_t edge) {
            const std::uint32_t* rec = &g.nodes[std::size_t{index} * VF_SDF_NODE_WORDS];
            if (rec[1] != VF_SDF_NOT_LEAF) {
                leaf(index, x, y, z, edge);
                return;
            }
            const std::uint64_t occ = rec[2] | std::uint64_t{rec[3]} << 32;
            const std::uint64_t solid = rec[4] | std::uint64_t{rec[5]} << 32;
            const std::uint32_t e = edge / 4;
            for (std::uint32_t c = 0; c < 64; ++c) {
                const std::uint32_t cx = x + (c & 3) * e, cy = y + (c >> 2 & 3) * e,
                                    cz = z + (c >> 4) * e;
                if (solid >> c & 1) {
                    full(cx, cy, cz, e);
                } else if (occ >> c & 1) {
                    const auto rank = static_cast<std::uint32_t>(
                        std::popcount(occ & ((std::uint64_t{1} << c) - 1)));
                    node(rec[0] + rank, cx, cy, cz, e);
                }
            }
        };
    for (std::uint32_t t = 0; t < g.tile_table.size(); ++t) {
        const std::uint32_t x = t % g.tiles.x * g.tile_edge,
                            y = t / g.tiles.x % g.tiles.y * g.tile_edge,
                            z = t / g.tiles.x / g.tiles.y * g.tile_edge;
        if (g.tile_table[t] == VF_SDF_TILE_FULL) {
            full(x, y, z, g.tile_edge);
        } else if (g.tile_table[t] != VF_SDF_TILE_EMPTY) {
            node(g.tile_table[t], x, y, z, g.tile_edge);
        }
    }
}

}  // namespace

std::vector<std::uint8_t> ImplicitGrid::flags() const {
    std::vector<std::uint8_t> f(dims.count(), 0);
    walk(
        *this,
        [&](std::uint32_t index, std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint32_t) {
            const std::uint32_t* rec = &nodes[std::size_t{index} * VF_SDF_NODE_WORDS];
            const std::uint64_t occ = rec[2] | std::uint64_t{rec[3]} << 32;
            const std::uint64_t solid = rec[4] | std::uint64_t{rec[5]} << 32;
            for (std::uint32_t v = 0; v < 64; ++v) {
                const std::uint32_t vx = x + (v & 3), vy = y + (v >> 2 & 3), vz = z + (v >> 4);
                if (vx < dims.x && vy < dims.y && vz < dims.z) {
                    f[dims.index(vx, vy, vz)] =
                        static_cast<std::uint8_t>((solid >> v & 1) | (occ >> v & 1) << 1);
                }
            }
        },
        [&](std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint32_t e) {
            for (std::uint32_t vz = z; vz < std::min(z + e, dims.z); ++vz) {
                for (std::uint32_t vy = y; vy < std::min(y + e, dims.y); ++vy) {
                    for (std::uint32_t vx = x; vx < std::min(x + e, dims.x); ++vx) {
                        f[dims.index(vx, vy, vz)] = 1;
                    }
                }
            }
        });
    return f;
}

std::uint64_t ImplicitGrid::solid_count() const {
    std::uint64_t n = 0;
    walk(
        *this,
        [&](std::uint32_t index, std::uint32_t, std::uint32_t, std::uint32_t, std::uint32_t) {
            const std::uint32_t* rec = &nodes[std::size_t{index} * VF_SDF_NODE_WORDS];
            n += static_cast<std::uint64_t>(std::popcount(rec[4]) + std::popcount(rec[5]));
        },
        [&](std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint32_t e) {
            n += std::uint64_t{std::min(x + e, dims.x) - x} * (std::min(y + e, dims.y) - y) *
                 (std::min(z + e, dims.z) - z);
        });
    return n;
}

std::vector<ImplicitGrid::Crossed> ImplicitGrid::crossed() const {
    std::vector<Crossed> out;
    walk(
        *this,
        [&](std::uint32_t index, std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint32_t) {
            const std::uint32_t* rec = &nodes[std::size_t{index} * VF_SDF_NODE_WORDS];
            const std::uint64_t occ = rec[2] | std::uint64_t{rec[3]} << 32;
            std::uint32_t r = 0;
            for (std::uint32_t v = 0; v < 64; ++v) {
                if (!(occ >> v & 1)) {
                    continue;
                }
                const std::uint32_t* vox = &voxels[std::size_t{rec[0] + r++} * VF_SDF_VOXEL_WORDS];
                Crossed c{x + (v & 3), y + (v >> 2 & 3), z + (v >> 4), vox[2], {}};
                for (std::uint32_t k = 0; k < 8; ++k) {
                    const std::uint32_t local = vox[k / 4] >> (8 * (k % 4)) & 0xFFu;
                    const float* vert =
                        &vertices[std::size_t{rec[1] + local} * VF_SDF_VERTEX_FLOATS];
                    for (int w = 0; w < 4; ++w) {
                        c.corner[k][w] = vert[w];
                    }
                }
                out.push_back(c);
            }
        },
        [](std::uint32_t, std::uint32_t, std::uint32_t, std::uint32_t) {});
    return out;
}

std::size_t ImplicitGrid::drop_crossed(
    const std::function<bool(std::uint32_t, std::uint32_t, std::uint32_t)>& drop) {
    // Leaves' voxel records are rewritten in walk order, each leaf's kept ones contiguous in
    // mask order as before.
    std::vector<std::uint32_t> kept;
    kept.reserve(voxels.size());
    std::size_t dropped = 0;
    walk(
        *this,
        [&](std::uint32_t index, std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint32_t) {
            std::uint32_t* rec = &nodes[std::size_t{index} * VF_SDF_NODE_WORDS];
            const std::uint64_t occ = rec[2] | std::uint64_t{rec[3]} << 32;
            std::uint64_t left = occ;
            const std::uint32_t first = rec[0];
            rec[0] = static_cast<std::uint32_t>(kept.size() / VF_SDF_VOXEL_WORDS);
            std::uint32_t r = 0;
            for (std::uint32_t v = 0; v < 64; ++v) {
                if (!(occ >> v & 1)) {
                    continue;
                }
                const std::uint32_t* vox = &voxels[std::size_t{first + r++} * VF_SDF_VOXEL_WORDS];
                if (drop(x + (v & 3), y + (v >> 2 & 3), z + (v >> 4))) {
                    left &= ~(std::uint64_t{1} << v);
                    ++dropped;
                } else {
                    kept.insert(kept.end(), vox, vox + VF_SDF_VOXEL_WORDS);
                }
            }
            rec[2] = static_cast<std::uint32_t>(left);
            rec[3] = static_cast<std::uint32_t>(left >> 32);
        },
        [](std::uint32_t, std::uint32_t, std::uint32_t, std::uint32_t) {});
    voxels = std::move(kept);
    return dropped;
}

}  // namespace voxfield::ocl
