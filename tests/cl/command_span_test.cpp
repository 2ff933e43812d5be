// command_span's interval arithmetic on made-up profiling times (ns): the span from the first
// start to the last end, and the part of it no command covered, whatever the order and overlap.
#include <gtest/gtest.h>

#include <utility>
#include <vector>

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

}  // namespace
}  // namespace voxfield
