// Implicit parts discretised into a tile grid of contrees (the reference blog, farfa.dev
// "implicit surface rendering for CAD"), host side; kernels: cl/kernels/implicit.cl.
//
// The tape is interpreted by the kernels (one program for every part) rather than emitted as
// OpenCL source per part: a per-part build costs a compiler run (hundreds of ms on PoCL), more
// than the whole discretisation of a gallery part.
#include "voxfield/cl/implicit.hpp"

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <functional>
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

// The CPU layout's `decided`: a corner whose |f| exceeds it gives its voxel's centre its sign.
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
// Work-group sizes, fixed so that a device compiling per work-group size (PoCL) compiles each
// kernel once: interval tests, and leaves in the CPU layout (one work-item each).
constexpr std::size_t kGroup = 64;
constexpr std::size_t kLeafGroup = 8;

}  // namespace

ImplicitDiscretiser::ImplicitDiscretiser(Context& ctx, const sdf::Part& part,
                                         ImplicitOptions options)
    : ctx_(ctx),
      part_(part),
      options_(options),
      gpu_layout_(options.layout == Layout::automatic ? !ctx.is_cpu()
                                                      : options.layout == Layout::gpu),
      decided_(centre_decided(part)),
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
    }
    return p.data;
}

namespace {

// memcpy of several arrays, split over a few threads when large (page-locked staging to the
// grid's arrays: one thread copies at a fraction of the memory bandwidth).
struct Copy {
    void* dst;
    const void* src;
    std::size_t bytes;
};
void copy_all(const std::vector<Copy>& copies) {
    std::size_t total = 0;
    for (const Copy& c : copies) {
        total += c.bytes;
    }
    constexpr std::size_t kPerThread = std::size_t{2} << 20;
    const unsigned threads = static_cast<unsigned>(std::min<std::size_t>(
        {std::max(1u, std::thread::hardware_concurrency()), 8, total / kPerThread + 1}));
    auto part = [&](unsigned t) {
        // Thread t copies bytes [t total / threads, (t + 1) total / threads) of the concatenation.
        const std::size_t lo = total * t / threads, hi = total * (t + 1) / threads;
        std::size_t at = 0;
        for (const Copy& c : copies) {
            const std::size_t a = std::max(lo, at), b = std::min(hi, at + c.bytes);
            if (a < b) {
                std::memcpy(static_cast<std::uint8_t*>(c.dst) + (a - at),
                            static_cast<const std::uint8_t*>(c.src) + (a - at), b - a);
            }
            at += c.bytes;
        }
    };
    std::vector<std::thread> pool;
    for (unsigned t = 1; t < threads; ++t) {
        pool.emplace_back(part, t);
    }
    part(0);
    for (std::thread& th : pool) {
        th.join();
    }
}

}  // namespace

ImplicitGrid ImplicitDiscretiser::run() {
    ImplicitGrid out;
    run(out);
    return out;
}

void ImplicitDiscretiser::grow(cl::Buffer& buffer, std::size_t& capacity, std::size_t bytes,
                               cl_mem_flags flags) {
    if (bytes > capacity || buffer.get() == nullptr) {
        capacity = std::max(bytes, capacity + capacity / 2);
        buffer = cl::Buffer(ctx_.context(), flags, std::max<std::size_t>(capacity, 1));
    }
}

void ImplicitDiscretiser::run(ImplicitGrid& out) {
    const auto t0 = std::chrono::steady_clock::now();
    timing_ = {};
    const cl_uint n = static_cast<cl_uint>(part_.tape.code.size());
    const GridArg g = grid_arg(part_);
    if (!kernels_made_) {
        classify_tiles_ = cl::Kernel(program_, "classify_tiles");
        classify_children_ = cl::Kernel(program_, "classify_children");
        sample_leaves_ =
            cl::Kernel(program_, gpu_layout_ ? "sample_leaves_group" : "sample_leaves_seq");
        kernels_made_ = true;
    }
    out.dims = part_.dims;
    out.tile_depth = options_.tile_depth;
    out.tile_edge = 1u << (2 * (options_.tile_depth + 1));
    const std::uint32_t edge = out.tile_edge;
    out.tiles = {(out.dims.x + edge - 1) / edge, (out.dims.y + edge - 1) / edge,
                 (out.dims.z + edge - 1) / edge};
    const std::size_t tiles = out.tiles.count();
    auto& q = ctx_.queue();
    auto ctx_of = [&](const std::string& what) {
        return "implicit " + what + " (" + std::to_string(n) + " instructions, grid " +
               out.dims.to_string() + ", tile depth " + std::to_string(options_.tile_depth) + ")";
    };

    // Blocking reads of the cells' classes: into `classes` (through the pinned stage on a GPU).
    const cl_uchar* classes = nullptr;
    auto read_classes = [&](const cl::Buffer& buf, std::size_t bytes) {
        std::uint8_t* dst = nullptr;
        if (staged_) {
            dst = pinned(small_stage_, bytes);
        } else {
            classes_.resize(bytes);
            dst = classes_.data();
        }
        q.enqueueReadBuffer(buf, CL_TRUE, 0, bytes, dst);
        ++timing_.syncs;
        classes = dst;
    };

    // Tiles: one interval test each.
    std::vector<cl_uint4>& frontier = frontier_;
    std::vector<cl_uint>& parents = parents_;
    frontier.clear();
    parents.clear();
    std::uint32_t nodes = 0;
    cl_call(ctx_of("classify_tiles"), [&] {
        grow(classes_buf_, classes_cap_, tiles, CL_MEM_WRITE_ONLY);
        cl::Buffer& buf = classes_buf_;
        cl::Kernel& k = classify_tiles_;
        k.setArg(0, tape_);
        k.setArg(1, n);
        k.setArg(2, g);
        k.setArg(3, out.tiles.x);
        k.setArg(4, out.tiles.y);
        k.setArg(5, static_cast<cl_uint>(tiles));
        k.setArg(6, edge);
        k.setArg(7, buf);
        cl::Event e;
        q.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(round_up(tiles, kGroup)),
                               cl::NDRange(kGroup), nullptr, &e);
        read_classes(buf, tiles);
        timing_.kernel_ms += event_ms(e);
    });
    out.tile_table.resize(tiles);
    out.nodes.clear();
    for (std::size_t t = 0; t < tiles; ++t) {
        if (classes[t] == VF_SDF_CELL_EMPTY) {
            out.tile_table[t] = VF_SDF_TILE_EMPTY;
        } else if (classes[t] == VF_SDF_CELL_FULL) {
            out.tile_table[t] = VF_SDF_TILE_FULL;
        } else {
            out.tile_table[t] = nodes;
            const auto x = static_cast<cl_uint>(t % out.tiles.x * edge);
            const auto y = static_cast<cl_uint>(t / out.tiles.x % out.tiles.y * edge);
            const auto z = static_cast<cl_uint>(t / out.tiles.x / out.tiles.y * edge);
            frontier.push_back({{x, y, z, nodes++}});
            parents.push_back(VF_SDF_NO_PARENT);
        }
    }

    // The frontier's origins and parents' slots, to the device before each level's kernel.
    auto upload_frontier = [&] {
        const std::size_t count = frontier.size();
        grow(origins_buf_, origins_cap_, count * sizeof(cl_uint4), CL_MEM_READ_ONLY);
        grow(parents_buf_, parents_cap_, count * sizeof(cl_uint), CL_MEM_READ_ONLY);
        q.enqueueWriteBuffer(origins_buf_, CL_FALSE, 0, count * sizeof(cl_uint4), frontier.data());
        q.enqueueWriteBuffer(parents_buf_, CL_FALSE, 0, count * sizeof(cl_uint), parents.data());
    };
    // Specialised tapes: the level being classified writes lists_buf_[cur], reading its
    // parents' from lists_buf_[cur ^ 1].
    const std::size_t list_bytes = VF_SDF_LIST_STRIDE * sizeof(cl_ushort);
    const bool special = n <= VF_SDF_SPECIALISE_MAX;
    std::size_t cur = 0;
    for (int i = 0; i < 2; ++i) {
        grow(lists_buf_[i], lists_cap_[i], list_bytes, CL_MEM_READ_WRITE);
    }

    // Interior levels: every node specialises its tape and tests its 64 children; ambiguous
    // children become nodes of the next level, densely packed in mask order.
    for (std::uint32_t level = 0; level < options_.tile_depth && !frontier.empty(); ++level) {
        const cl_uint node_edge = edge >> (2 * level);
        const cl_uint child_edge = node_edge / 4;
        const std::size_t count = frontier.size();
        cl_call(ctx_of("classify_children"), [&] {
            upload_frontier();
            grow(classes_buf_, classes_cap_, count * 64, CL_MEM_WRITE_ONLY);
            if (special) {
                grow(lists_buf_[cur], lists_cap_[cur], count * list_bytes, CL_MEM_READ_WRITE);
            }
            cl::Buffer& buf = classes_buf_;
            cl::Kernel& k = classify_children_;
            k.setArg(0, tape_);
            k.setArg(1, n);
            k.setArg(2, g);
            k.setArg(3, origins_buf_);
            k.setArg(4, parents_buf_);
            k.setArg(5, lists_buf_[cur ^ 1]);
            k.setArg(6, static_cast<cl_uint>(count));
            k.setArg(7, node_edge);
            k.setArg(8, lists_buf_[cur]);
            k.setArg(9, buf);
            cl::Event e;
            q.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(count * 64), cl::NDRange(64),
                                   nullptr, &e);
            read_classes(buf, count * 64);
            timing_.kernel_ms += event_ms(e);
        });
        std::vector<cl_uint4>& next = next_;
        std::vector<cl_uint>& next_parents = next_parents_;
        next.clear();
        next_parents.clear();
        out.nodes.resize(std::size_t{nodes} * VF_SDF_NODE_WORDS);
        for (std::size_t f = 0; f < count; ++f) {
            std::uint64_t occ = 0, solid = 0;
            const std::uint32_t first = nodes;
            for (std::uint32_t c = 0; c < 64; ++c) {
                const cl_uchar cls = classes[f * 64 + c];
                if (cls == VF_SDF_CELL_FULL) {
                    solid |= std::uint64_t{1} << c;
                } else if (cls == VF_SDF_CELL_AMBIGUOUS) {
                    occ |= std::uint64_t{1} << c;
                    const cl_uint4& o = frontier[f];
                    next.push_back(
                        {{o.s[0] + (c & 3) * child_edge, o.s[1] + (c >> 2 & 3) * child_edge,
                          o.s[2] + (c >> 4) * child_edge, nodes++}});
                    next_parents.push_back(static_cast<cl_uint>(f));
                }
            }
            std::uint32_t* rec = &out.nodes[std::size_t{frontier[f].s[3]} * VF_SDF_NODE_WORDS];
            rec[0] = first;
            rec[1] = VF_SDF_NOT_LEAF;
            rec[2] = static_cast<std::uint32_t>(occ);
            rec[3] = static_cast<std::uint32_t>(occ >> 32);
            rec[4] = static_cast<std::uint32_t>(solid);
            rec[5] = static_cast<std::uint32_t>(solid >> 32);
        }
        std::swap(frontier, next);
        std::swap(parents, next_parents);
        cur ^= 1;
    }

    // Leaves: the nodes of the last level, allocated last (indices first_leaf..nodes).
    out.leaves = frontier.size();
    if (frontier.empty()) {
        out.voxels.clear();
        out.vertices.clear();
    }
    out.nodes.resize(std::size_t{nodes} * VF_SDF_NODE_WORDS);
    if (!frontier.empty()) {
        const std::size_t count = frontier.size();
        const std::uint32_t first_leaf = frontier.front().s[3];
        for (auto& o : frontier) {
            o.s[3] -= first_leaf;
        }
        // Room for the crossed voxels and kept corners: the last run's counts when they were
        // larger than the estimate (a second pass only when even those overflow).
        std::size_t vcap = std::max({std::size_t{1024}, count * 48, last_vertices_});
        std::size_t xcap = std::max({std::size_t{1024}, count * 24, last_voxels_});
        cl_call(ctx_of(gpu_layout_ ? "sample_leaves_group" : "sample_leaves_seq"), [&] {
            upload_frontier();
            grow(leaf_nodes_buf_, leaf_nodes_cap_, count * VF_SDF_NODE_WORDS * sizeof(cl_uint),
                 CL_MEM_WRITE_ONLY);
            const cl::Buffer& leaf_nodes = leaf_nodes_buf_;
            grow(counters_buf_, counters_cap_, 2 * sizeof(cl_uint), CL_MEM_READ_WRITE);
            const cl::Buffer& counters = counters_buf_;
            cl::Kernel& k = sample_leaves_;
            cl_uint reached[2] = {0, 0};
            while (true) {
                grow(voxels_buf_, voxels_cap_, xcap * VF_SDF_VOXEL_WORDS * sizeof(cl_uint),
                     CL_MEM_WRITE_ONLY);
                grow(vertices_buf_, vertices_cap_, vcap * VF_SDF_VERTEX_FLOATS * sizeof(cl_float),
                     CL_MEM_WRITE_ONLY);
                const cl::Buffer& voxels = voxels_buf_;
                const cl::Buffer& vertices = vertices_buf_;
                const cl_uint zero[2] = {0, 0};
                q.enqueueWriteBuffer(counters, CL_FALSE, 0, sizeof(zero), zero);
                k.setArg(0, tape_);
                k.setArg(1, n);
                k.setArg(2, g);
                k.setArg(3, origins_buf_);
                k.setArg(4, parents_buf_);
                k.setArg(5, lists_buf_[cur ^ 1]);
                k.setArg(6, static_cast<cl_uint>(count));
                k.setArg(7, leaf_nodes);
                k.setArg(8, voxels);
                k.setArg(9, static_cast<cl_uint>(xcap));
                k.setArg(10, vertices);
                k.setArg(11, static_cast<cl_uint>(vcap));
                k.setArg(12, counters);
                cl::Event e;
                if (gpu_layout_) {
                    q.enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(count * 128),
                                           cl::NDRange(128), nullptr, &e);
                } else {
                    k.setArg(13, decided_);
                    q.enqueueNDRangeKernel(k, cl::NullRange,
                                           cl::NDRange(round_up(count, kLeafGroup)),
                                           cl::NDRange(kLeafGroup), nullptr, &e);
                }
                cl_uint* got =
                    staged_ ? reinterpret_cast<cl_uint*>(pinned(small_stage_, sizeof(reached)))
                            : reached;
                q.enqueueReadBuffer(counters, CL_TRUE, 0, sizeof(reached), got);
                ++timing_.syncs;
                reached[0] = got[0];
                reached[1] = got[1];
                timing_.kernel_ms += event_ms(e);
                ++timing_.passes;
                if (reached[0] <= vcap && reached[1] <= xcap) {
                    break;
                }
                vcap = std::max<std::size_t>(vcap, reached[0]);
                xcap = std::max<std::size_t>(xcap, reached[1]);
            }
            last_vertices_ = reached[0];
            last_voxels_ = reached[1];
            const cl::Buffer& voxels = voxels_buf_;
            const cl::Buffer& vertices = vertices_buf_;
            out.voxels.resize(std::size_t{reached[1]} * VF_SDF_VOXEL_WORDS);
            out.vertices.resize(std::size_t{reached[0]} * VF_SDF_VERTEX_FLOATS);
            // The leaves' node records, voxel records and vertices: three reads, one wait.
            const std::vector<Copy> parts = {
                {&out.nodes[std::size_t{first_leaf} * VF_SDF_NODE_WORDS], nullptr,
                 count * VF_SDF_NODE_WORDS * sizeof(cl_uint)},
                {out.voxels.data(), nullptr, out.voxels.size() * sizeof(cl_uint)},
                {out.vertices.data(), nullptr, out.vertices.size() * sizeof(cl_float)}};
            const cl::Buffer* sources[3] = {&leaf_nodes, &voxels, &vertices};
            std::size_t total = 0;
            for (const Copy& c : parts) {
                total += c.bytes;
            }
            std::uint8_t* stage = staged_ ? pinned(out_stage_, total) : nullptr;
            std::vector<Copy> copies;
            std::size_t at = 0;
            for (int i = 0; i < 3; ++i) {
                if (parts[i].bytes == 0) {
                    continue;
                }
                void* dst = staged_ ? stage + at : parts[i].dst;
                q.enqueueReadBuffer(*sources[i], CL_FALSE, 0, parts[i].bytes, dst);
                copies.push_back({parts[i].dst, dst, parts[i].bytes});
                at += parts[i].bytes;
            }
            q.finish();
            ++timing_.syncs;
            if (staged_) {
                copy_all(copies);
            }
        });
    }
    timing_.total_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
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
