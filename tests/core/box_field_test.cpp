// The incremental update's box field on the CPU (core/box_field.hpp) against brute force: the
// least L1 distance to a source, and the least value over each part of the boundary.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <random>
#include <vector>

#include "voxfield/core/box_field.hpp"

namespace voxfield {
namespace {

TEST(BoxField, EqualsBruteForceOnRandomBoxes) {
    std::mt19937_64 rng(12);
    for (int trial = 0; trial < 200; ++trial) {
        const Int3 n{static_cast<std::int64_t>(1 + rng() % 9),
                     static_cast<std::int64_t>(1 + rng() % 7),
                     static_cast<std::int64_t>(1 + rng() % 8)};
        const std::size_t count = static_cast<std::size_t>(n.x * n.y * n.z);
        std::vector<std::uint32_t> f(count, kBoxFieldFar);
        std::vector<std::size_t> sources;
        const std::uint64_t density = 1 + rng() % 40;  // 1 in density, or none at all
        for (std::size_t i = 0; i < count; ++i) {
            if (trial % 10 != 0 && rng() % density == 0) {
                f[i] = 0;
                sources.push_back(i);
            }
        }
        const auto at = [&](std::size_t i) {
            return Int3{static_cast<std::int64_t>(i) % n.x,
                        static_cast<std::int64_t>(i) / n.x % n.y,
                        static_cast<std::int64_t>(i) / (n.x * n.y)};
        };
        std::vector<std::uint32_t> want(count, kBoxFieldFar);
        for (std::size_t i = 0; i < count; ++i) {
            const Int3 p = at(i);
            for (const std::size_t s : sources) {
                const Int3 q = at(s);
                const auto d = static_cast<std::uint32_t>(
                    std::abs(p.x - q.x) + std::abs(p.y - q.y) + std::abs(p.z - q.z));
                want[i] = std::min(want[i], d);
            }
        }
        box_field_transform(f.data(), n);
        ASSERT_EQ(f, want) << "trial " << trial;
        const auto least = box_field_boundary_minima(f.data(), n);
        for (int part = 0; part < 27; ++part) {
            const int side[3] = {part % 3, part / 3 % 3, part / 9};
            const std::int64_t size[3] = {n.x, n.y, n.z};
            std::uint32_t m = kBoxFieldFar;
            for (std::size_t i = 0; i < count; ++i) {
                const Int3 p = at(i);
                const std::int64_t c[3] = {p.x, p.y, p.z};
                bool in = true;
                for (int a = 0; a < 3; ++a) {
                    in &= side[a] == 1 || (side[a] == 0 ? c[a] == 0 : c[a] == size[a] - 1);
                }
                if (in) {
                    m = std::min(m, want[i]);
                }
            }
            ASSERT_EQ(least[static_cast<std::size_t>(part)], m)
                << "trial " << trial << ", part " << part;
        }
    }
}

}  // namespace
}  // namespace voxfield
