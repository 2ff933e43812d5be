// Falling sand and water, host side (kernels: cl/kernels/sand.cl; rules: core/sand.hpp).
// Source: Toffoli & Margolus, "Cellular Automata Machines" (1987), ch. 12 (Margolus blocks).
#include "voxfield/cl/sand.hpp"

#include <algorithm>
#include <string>

#include "util.hpp"
#include "voxfield/core/error.hpp"

namespace voxfield::cl_sources {
extern const char* const sand_cl;
}  // namespace voxfield::cl_sources

namespace voxfield::ocl {

namespace {

// Least-significant-digit radix sort of `keys` (16-bit digits, as many passes as `largest`
// needs; `scratch` is reused between calls): a step's change list holds hundreds of thousands
// of keys, which std::sort took about 10 ms of each step's host time to order.
void radix_sort(std::vector<std::uint64_t>& keys, std::vector<std::uint64_t>& scratch,
                std::uint64_t largest) {
    constexpr int kBits = 16;
    constexpr std::size_t kBuckets = std::size_t{1} << kBits;
    scratch.resize(keys.size());
    std::vector<std::size_t> count(kBuckets);
    for (int shift = 0; shift < 64 && (largest >> shift) != 0; shift += kBits) {
        std::fill(count.begin(), count.end(), 0);
        for (const std::uint64_t k : keys) {
            ++count[(k >> shift) & (kBuckets - 1)];
        }
        std::size_t sum = 0;
        for (std::size_t& c : count) {
            const std::size_t n = c;
            c = sum;
            sum += n;
        }
        for (const std::uint64_t k : keys) {
            scratch[count[(k >> shift) & (kBuckets - 1)]++] = k;
        }
        keys.swap(scratch);
    }
}

}  // namespace

namespace {

// The GPU layout's work-group shape over the block grid.
constexpr std::size_t kGroup[3] = {32, 4, 2};
// Room for this many changes is allocated first (one step changes at most every voxel).
constexpr std::size_t kMinCapacity = 4096;
// sand_sync's work-group size.
constexpr std::size_t kSync = 64;

cl_int4 int4_of(std::int64_t x, std::int64_t y, std::int64_t z) {
    return {{static_cast<cl_int>(x), static_cast<cl_int>(y), static_cast<cl_int>(z), 0}};
}

}  // namespace

SandSimulator::SandSimulator(Context& ctx, const World& world, const SandRules& rules,
                             Layout layout)
    : ctx_(ctx),
      dims_(world.dims()),
      rules_(rules),
      gpu_layout_(layout == Layout::automatic ? !ctx.is_cpu() : layout == Layout::gpu) {
    check_sand_rules(rules);
    const std::size_t n = dims_.count();
    if (n > 0xFFFFFFFFull) {
        throw InputError("the sand simulation indexes voxels with 32 bits; world " +
                         dims_.to_string() + " is too large");
    }
    capacity_ = std::min(n, std::max(kMinCapacity, n / 8));
    const cl::Program program = ctx.program("sand.cl", {cl_sources::sand_cl}, "-cl-std=CL1.2");
    cl_call("allocating the sand simulation of " + dims_.to_string(), [&] {
        auto& q = ctx.queue();
        for (cl::Buffer& b : world_) {
            b = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, n);
            q.enqueueWriteBuffer(b, CL_TRUE, 0, n, world.voxels().data());
        }
        count_ = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, sizeof(cl_uint));
        changes_ = cl::Buffer(ctx.context(), CL_MEM_READ_WRITE, capacity_ * sizeof(cl_uint2));
        kernel_ = cl::Kernel(program, gpu_layout_ ? "sand_step_blocks" : "sand_step_rows");
        sync_ = cl::Kernel(program, "sand_sync");
    });
    // PoCL compiles a kernel for each work-group shape on its first launch: one launch of
    // each here (a step whose result is discarded by uploading the world again, a sync of an
    // empty list) keeps that out of step()'s times.
    cl_call("warming up the sand kernels, world " + dims_.to_string(), [&] {
        std::vector<cl::Event> events;
        launch(events, 0, 0);
        sync(events, 0);
        ctx_.queue().enqueueWriteBuffer(world_[1], CL_TRUE, 0, n, world.voxels().data());
    });
}

void SandSimulator::launch(std::vector<cl::Event>& events, std::uint64_t step, std::uint64_t key) {
    const Int3 o = sand_block_offset(step);
    const std::size_t nb[3] = {(dims_.x + static_cast<std::size_t>(o.x) + 1) / 2,
                               (dims_.y + static_cast<std::size_t>(o.y) + 1) / 2,
                               (dims_.z + static_cast<std::size_t>(o.z) + 1) / 2};
    auto& q = ctx_.queue();
    events.emplace_back();
    q.enqueueFillBuffer(count_, cl_uint{0}, 0, sizeof(cl_uint), nullptr, &events.back());
    kernel_.setArg(0, world_[current_]);
    kernel_.setArg(1, world_[1 - current_]);
    kernel_.setArg(2, int4_of(dims_.x, dims_.y, dims_.z));
    kernel_.setArg(3, int4_of(o.x, o.y, o.z));
    kernel_.setArg(4, int4_of(static_cast<std::int64_t>(nb[0]), static_cast<std::int64_t>(nb[1]),
                              static_cast<std::int64_t>(nb[2])));
    kernel_.setArg(5, static_cast<cl_ulong>(key));
    // `wall` marks cells outside the world: a value other than air, sand and water.
    const cl_uint wall = rules_.sand != 1 && rules_.water != 1   ? 1
                         : rules_.sand != 2 && rules_.water != 2 ? 2
                                                                 : 3;
    kernel_.setArg(6, static_cast<cl_uint>(rules_.sand));
    kernel_.setArg(7, static_cast<cl_uint>(rules_.water));
    kernel_.setArg(8, wall);
    kernel_.setArg(9, count_);
    kernel_.setArg(10, changes_);
    kernel_.setArg(11, static_cast<cl_uint>(capacity_));
    events.emplace_back();
    if (gpu_layout_) {
        q.enqueueNDRangeKernel(kernel_, cl::NullRange,
                               cl::NDRange(round_up(nb[0], kGroup[0]), round_up(nb[1], kGroup[1]),
                                           round_up(nb[2], kGroup[2])),
                               cl::NDRange(kGroup[0], kGroup[1], kGroup[2]), nullptr,
                               &events.back());
    } else {
        q.enqueueNDRangeKernel(kernel_, cl::NullRange, cl::NDRange(nb[1], nb[2]), cl::NDRange(1, 1),
                               nullptr, &events.back());
    }
}

void SandSimulator::sync(std::vector<cl::Event>& events, std::size_t count) {
    sync_.setArg(0, world_[current_]);
    sync_.setArg(1, changes_);
    sync_.setArg(2, static_cast<cl_uint>(count));
    events.emplace_back();
    ctx_.queue().enqueueNDRangeKernel(sync_, cl::NullRange,
                                      cl::NDRange(round_up(std::max<std::size_t>(count, 1), kSync)),
                                      cl::NDRange(kSync), nullptr, &events.back());
}

SandStepResult SandSimulator::step(std::uint64_t seed, std::uint64_t step) {
    return cl_call("sand step " + std::to_string(step) + ", world " + dims_.to_string(), [&] {
        auto& q = ctx_.queue();
        const std::uint64_t key = sand_step_key(seed, step);
        std::vector<cl::Event> events;
        cl_uint count = 0;
        auto read_count = [&] {
            events.emplace_back();
            q.enqueueReadBuffer(count_, CL_TRUE, 0, sizeof count, &count, nullptr, &events.back());
        };
        launch(events, step, key);
        read_count();
        if (count > capacity_) {
            // The list overflowed: grow it and run the same step again from the same world.
            capacity_ = std::min(dims_.count(), std::max<std::size_t>(count, 2 * capacity_));
            changes_ = cl::Buffer(ctx_.context(), CL_MEM_READ_WRITE, capacity_ * sizeof(cl_uint2));
            launch(events, step, key);
            read_count();
        }
        staged_.resize(count);
        if (count != 0) {
            sync(events, count);  // the copy the step read from gets its changes too
            events.emplace_back();
            q.enqueueReadBuffer(changes_, CL_TRUE, 0, count * sizeof(cl_uint2), staged_.data(),
                                nullptr, &events.back());
        }
        current_ = 1 - current_;
        SandStepResult result;
        for (const cl::Event& e : events) {
            result.simulate_ms += elapsed_ms(e, e);
        }
        // Slots were taken in whatever order the work-items ran: sorted by index as
        // (index << 16 | before | after << 8) keys.
        keys_.resize(count);
        std::uint64_t largest = 0;
        for (std::size_t i = 0; i < count; ++i) {
            keys_[i] = std::uint64_t{staged_[i].s[0]} << 16 | (staged_[i].s[1] & 0xFFFFu);
            largest = std::max(largest, keys_[i]);
        }
        radix_sort(keys_, sort_scratch_, largest);
        result.changes.resize(count);
        for (std::size_t i = 0; i < count; ++i) {
            result.changes[i] = {static_cast<std::size_t>(keys_[i] >> 16),
                                 static_cast<std::uint8_t>(keys_[i] & 0xFFu),
                                 static_cast<std::uint8_t>((keys_[i] >> 8) & 0xFFu)};
        }
        return result;
    });
}

std::vector<std::uint8_t> SandSimulator::read_world() {
    return cl_call("reading the sand world " + dims_.to_string(), [&] {
        std::vector<std::uint8_t> voxels(dims_.count());
        ctx_.queue().enqueueReadBuffer(world_[current_], CL_TRUE, 0, voxels.size(), voxels.data());
        return voxels;
    });
}

std::string SandSimulator::variant() const {
    return gpu_layout_ ? "gpu layout" : "cpu layout";
}

}  // namespace voxfield::ocl
