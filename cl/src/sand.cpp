// Falling sand and water, host side (kernels: cl/kernels/sand.cl; rules: core/sand.hpp).
// Source: Toffoli & Margolus, "Cellular Automata Machines" (1987), ch. 12 (Margolus blocks).
#include "voxfield/cl/sand.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "util.hpp"
#include "voxfield/core/error.hpp"

namespace voxfield::cl_sources {
extern const char* const sand_cl;
}  // namespace voxfield::cl_sources

namespace voxfield::ocl {

namespace {

// The GPU layout's work-group shape over the (x, z) grid of block columns.
constexpr std::size_t kGroup[2] = {32, 4};
// The change list's room unless the caller gives it: an eighth of the voxels, at least this.
constexpr std::size_t kMinCapacity = 4096;
// sand.cl's summary: a count and two boxes (VF_SUMMARY_*), padded.
constexpr std::size_t kSummaryWords = 16;
constexpr std::size_t kChangedAt = 1, kOccupancyAt = 7;

cl_int4 int4_of(std::int64_t x, std::int64_t y, std::int64_t z) {
    return {{static_cast<cl_int>(x), static_cast<cl_int>(y), static_cast<cl_int>(z), 0}};
}

// A box of the summary (d - lo, hi per axis; hi = 0: empty).
Box box_of(const cl_uint* s, Dims d) {
    if (s[3] == 0) {
        return Box{};
    }
    return Box{{static_cast<std::int64_t>(d.x) - s[0], static_cast<std::int64_t>(d.y) - s[1],
                static_cast<std::int64_t>(d.z) - s[2]},
               {s[3], s[4], s[5]}};
}

}  // namespace

SandSimulator::SandSimulator(Context& ctx, const cl::Buffer& voxels, Dims dims,
                             const SandRules& rules, Layout layout, std::size_t capacity)
    : ctx_(ctx),
      voxels_(voxels),
      dims_(dims),
      rules_(rules),
      gpu_layout_(layout == Layout::automatic ? !ctx.is_cpu() : layout == Layout::gpu),
      summary_read_(kSummaryWords, 0) {
    check_sand_rules(rules);
    const std::size_t n = dims_.count();
    if (n > 0xFFFFFFFFull) {
        throw InputError("the sand simulation indexes voxels with 32 bits; world " +
                         dims_.to_string() + " is too large");
    }
    capacity_ = capacity != 0 ? capacity : std::max(kMinCapacity, n / 8);
    const cl::Program program = ctx.program("sand.cl", {cl_sources::sand_cl}, "-cl-std=CL1.2");
    cl_call("allocating the sand simulation of " + dims_.to_string(), [&] {
        summary_ = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, kSummaryWords * sizeof(cl_uint));
        changes_ = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, capacity_ * sizeof(cl_uint2));
        kernel_ = cl::Kernel(program, gpu_layout_ ? "sand_step_blocks" : "sand_step_rows");
    });
    last_.list = &changes_;
    last_.capacity = capacity_;
    // PoCL compiles a kernel for each work-group shape on its first launch: one launch on a
    // scratch world of one block (the shape does not depend on the world) keeps that out of
    // step()'s times.
    cl_call("warming up the sand kernel", [&] {
        const cl::Buffer scratch(ctx.context(), CL_MEM_READ_WRITE, 8);
        ctx.queue().enqueueFillBuffer(scratch, cl_uchar{0}, 0, 8);
        std::vector<cl::Event> events;
        launch(events, scratch, Dims{2, 2, 2}, 0, 0);
        ctx.queue().finish();
    });
}

void SandSimulator::launch(std::vector<cl::Event>& events, const cl::Buffer& voxels, Dims dims,
                           std::uint64_t step, std::uint64_t key) {
    const Int3 o = sand_block_offset(step);
    const std::size_t nb[3] = {(dims.x + static_cast<std::size_t>(o.x) + 1) / 2,
                               (dims.y + static_cast<std::size_t>(o.y) + 1) / 2,
                               (dims.z + static_cast<std::size_t>(o.z) + 1) / 2};
    auto& q = ctx_.queue();
    events.emplace_back();
    q.enqueueFillBuffer(summary_, cl_uint{0}, 0, kSummaryWords * sizeof(cl_uint), nullptr,
                        &events.back());
    kernel_.setArg(0, voxels);
    kernel_.setArg(1, int4_of(dims.x, dims.y, dims.z));
    kernel_.setArg(2, int4_of(o.x, o.y, o.z));
    kernel_.setArg(3, int4_of(static_cast<std::int64_t>(nb[0]), static_cast<std::int64_t>(nb[1]),
                              static_cast<std::int64_t>(nb[2])));
    kernel_.setArg(4, static_cast<cl_ulong>(key));
    // `wall` marks cells outside the world: a value other than air, sand and water.
    const cl_uint wall = rules_.sand != 1 && rules_.water != 1   ? 1
                         : rules_.sand != 2 && rules_.water != 2 ? 2
                                                                 : 3;
    kernel_.setArg(5, static_cast<cl_uint>(rules_.sand));
    kernel_.setArg(6, static_cast<cl_uint>(rules_.water));
    kernel_.setArg(7, wall);
    kernel_.setArg(8, summary_);
    kernel_.setArg(9, changes_);
    kernel_.setArg(10, static_cast<cl_uint>(std::min<std::size_t>(capacity_, 0xFFFFFFFFu)));
    events.emplace_back();
    if (gpu_layout_) {
        q.enqueueNDRangeKernel(kernel_, cl::NullRange,
                               cl::NDRange(round_up(nb[0], kGroup[0]), round_up(nb[2], kGroup[1])),
                               cl::NDRange(kGroup[0], kGroup[1]), nullptr, &events.back());
    } else {
        q.enqueueNDRangeKernel(kernel_, cl::NullRange, cl::NDRange(nb[2]), cl::NDRange(1), nullptr,
                               &events.back());
    }
}

SandStepResult SandSimulator::step(std::uint64_t seed, std::uint64_t step) {
    return cl_call("sand step " + std::to_string(step) + ", world " + dims_.to_string(), [&] {
        std::vector<cl::Event> events;
        launch(events, voxels_, dims_, step, sand_step_key(seed, step));
        // Only the summary comes back: the list's length and the boxes size the update.
        events.emplace_back();
        ctx_.queue().enqueueReadBuffer(summary_, CL_TRUE, 0, kSummaryWords * sizeof(cl_uint),
                                       summary_read_.data(), nullptr, &events.back());
        SandStepResult result;
        result.simulate_ms = elapsed_ms(events.front(), events.back());
        last_.count = summary_read_[0];
        last_.bounds = box_of(summary_read_.data() + kChangedAt, dims_);
        last_.occupancy_bounds = box_of(summary_read_.data() + kOccupancyAt, dims_);
        result.changes = last_;
        return result;
    });
}

VoxelChanges SandSimulator::read_changes() {
    if (last_.overflow()) {
        throw std::logic_error(
            "the last sand step's change list overflowed: " + std::to_string(last_.count) +
            " changes, room for " + std::to_string(last_.capacity));
    }
    std::vector<cl_uint2> list(last_.count);
    if (!list.empty()) {
        cl_call("reading the sand step's changes", [&] {
            ctx_.queue().enqueueReadBuffer(changes_, CL_TRUE, 0, list.size() * sizeof(cl_uint2),
                                           list.data());
        });
    }
    VoxelChanges changes;
    changes.reserve(list.size());
    for (const cl_uint2& c : list) {
        changes.push_back({c.s[0], static_cast<std::uint8_t>(c.s[1] & 0xFFu),
                           static_cast<std::uint8_t>((c.s[1] >> 8) & 0xFFu)});
    }
    std::sort(changes.begin(), changes.end(),
              [](const VoxelChange& a, const VoxelChange& b) { return a.index < b.index; });
    return changes;
}

std::string SandSimulator::variant() const {
    return gpu_layout_ ? "gpu layout" : "cpu layout";
}

}  // namespace voxfield::ocl
