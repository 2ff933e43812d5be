// ocl::read_streamed on PoCL: the bytes reach the sink whole and in order, through the map and
// through the pinned staging pieces (odd piece sizes, one piece, a last short piece), after the
// work queued before the read.
#include <gtest/gtest.h>

#include <cstdint>
#include <numeric>
#include <random>
#include <vector>

#include "cl_test_util.hpp"

namespace voxfield {
namespace {

using test::pocl;

std::vector<std::uint8_t> random_bytes(std::size_t n, std::uint32_t seed) {
    std::mt19937 rng(seed);
    std::vector<std::uint8_t> v(n);
    for (auto& b : v) {
        b = static_cast<std::uint8_t>(rng());
    }
    return v;
}

TEST(ReadStreamed, EveryByteInOrderForEveryPieceSize) {
    ocl::Context& ctx = pocl();
    const std::vector<std::uint8_t> want = random_bytes(100003, 7);
    cl::Buffer buffer(ctx.context(), CL_MEM_READ_WRITE, want.size());
    // A non-blocking write: the read must come after the work queued before it.
    ctx.queue().enqueueWriteBuffer(buffer, CL_FALSE, 0, want.size(), want.data());
    for (const bool staged : {false, true}) {
        for (const std::size_t piece : {std::size_t{1}, std::size_t{4093}, std::size_t{50000},
                                        want.size(), want.size() * 2}) {
            std::vector<std::uint8_t> got;
            std::size_t calls = 0;
            ocl::read_streamed(
                ctx, buffer, want.size(),
                [&](std::span<const std::uint8_t> part) {
                    got.insert(got.end(), part.begin(), part.end());
                    ++calls;
                },
                piece, staged);
            EXPECT_EQ(got, want) << "staged " << staged << ", pieces of " << piece;
            if (staged) {
                EXPECT_EQ(calls, (want.size() + piece - 1) / piece);
            } else {
                EXPECT_EQ(calls, 1u);
            }
        }
    }
}

TEST(ReadStreamed, APrefixOfTheBufferAndNothing) {
    ocl::Context& ctx = pocl();
    const std::vector<std::uint8_t> all = random_bytes(5000, 11);
    cl::Buffer buffer(ctx.context(), CL_MEM_READ_WRITE, all.size());
    ctx.queue().enqueueWriteBuffer(buffer, CL_TRUE, 0, all.size(), all.data());
    std::vector<std::uint8_t> got;
    ocl::read_streamed(
        ctx, buffer, 1234,
        [&](std::span<const std::uint8_t> part) {
            got.insert(got.end(), part.begin(), part.end());
        },
        100, true);
    EXPECT_EQ(got, std::vector<std::uint8_t>(all.begin(), all.begin() + 1234));
    std::size_t calls = 0;
    ocl::read_streamed(
        ctx, buffer, 0, [&](std::span<const std::uint8_t>) { ++calls; }, 100, true);
    EXPECT_EQ(calls, 0u);
    EXPECT_THROW(ocl::read_streamed(
                     ctx, buffer, 10, [](std::span<const std::uint8_t>) {}, 0),
                 std::invalid_argument);
}

}  // namespace
}  // namespace voxfield
