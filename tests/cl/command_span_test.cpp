// command_span's interval arithmetic on made-up profiling times (ns): the span from the first
// start to the last end, and the part of it no command covered, whatever the order and overlap;
// and Context::Unprofiled's queue, whose commands have no profiling times.
#include <gtest/gtest.h>

#include <cstdint>
#include <utility>
#include <vector>

#include "cl_test_util.hpp"
#include "voxfield/cl/runtime.hpp"

namespace voxfield {
namespace {

using Runs = std::vector<std::pair<cl_ulong, cl_ulong>>;

TEST(CommandSpan, SpanAndIdleOfKnownRuns) {
    const ocl::CommandSpan none = ocl::command_span(Runs{});
    EXPECT_EQ(none.span_ms, 0.0);
    EXPECT_EQ(none.idle_ms, 0.0);
    // Back to back: no idle time.
    ocl::CommandSpan s = ocl::command_span(Runs{{1'000'000, 2'000'000}, {2'000'000, 5'000'000}});
    EXPECT_DOUBLE_EQ(s.span_ms, 4.0);
    EXPECT_DOUBLE_EQ(s.idle_ms, 0.0);
    // Gaps of 1 ms and 0.5 ms, given out of order.
    s = ocl::command_span(
        Runs{{4'500'000, 6'000'000}, {1'000'000, 2'000'000}, {3'000'000, 4'000'000}});
    EXPECT_DOUBLE_EQ(s.span_ms, 5.0);
    EXPECT_DOUBLE_EQ(s.idle_ms, 1.5);
    // Overlaps and a run inside another count their union once; the last end is not the last
    // run's.
    s = ocl::command_span(Runs{{0, 10'000'000},
                               {2'000'000, 3'000'000},
                               {9'000'000, 12'000'000},
                               {14'000'000, 15'000'000}});
    EXPECT_DOUBLE_EQ(s.span_ms, 15.0);
    EXPECT_DOUBLE_EQ(s.idle_ms, 2.0);
    s = ocl::command_span(Runs{{0, 10'000'000}, {2'000'000, 3'000'000}});
    EXPECT_DOUBLE_EQ(s.span_ms, 10.0);
    EXPECT_DOUBLE_EQ(s.idle_ms, 0.0);
}

TEST(Unprofiled, AQueueWithoutProfilingWhileTheGuardLives) {
    ocl::Context& ctx = test::pocl();
    const std::size_t n = 1 << 16;
    const cl::Buffer buffer(ctx.context(), CL_MEM_READ_WRITE, n);
    const std::vector<std::uint8_t> ones(n, 1), twos(n, 2);
    cl::Event profiled, unprofiled;
    ctx.queue().enqueueWriteBuffer(buffer, CL_TRUE, 0, n, ones.data(), nullptr, &profiled);
    EXPECT_GT(ocl::command_span({profiled}).span_ms, 0.0);
    const cl_command_queue before = ctx.queue()();
    {
        ocl::Context::Unprofiled guard(ctx);
        EXPECT_NE(ctx.queue()(), before);
        EXPECT_EQ(ctx.queue().getInfo<CL_QUEUE_PROPERTIES>() & CL_QUEUE_PROFILING_ENABLE, 0u);
        {
            ocl::Context::Unprofiled nested(ctx);  // changes nothing
            EXPECT_NE(ctx.queue()(), before);
        }
        EXPECT_NE(ctx.queue()(), before);
        // Not waited for here: the guard's end waits for it.
        ctx.queue().enqueueWriteBuffer(buffer, CL_FALSE, 0, n, twos.data(), nullptr, &unprofiled);
    }
    EXPECT_EQ(ctx.queue()(), before);
    EXPECT_EQ(unprofiled.getInfo<CL_EVENT_COMMAND_EXECUTION_STATUS>(), CL_COMPLETE);
    EXPECT_EQ(ocl::elapsed_ms(unprofiled, unprofiled), 0.0);
    EXPECT_EQ(ocl::command_span({profiled, unprofiled}).span_ms, 0.0);
    std::vector<std::uint8_t> back(n);
    ctx.queue().enqueueReadBuffer(buffer, CL_TRUE, 0, n, back.data());
    EXPECT_EQ(back, twos);
}

}  // namespace
}  // namespace voxfield
