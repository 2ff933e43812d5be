#pragma once
// A sparse .vdb grid too large to view or render dense, shared by the sparse viewer's and the
// sparse renderer's end-to-end tests.
#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "voxfield/core/chunks.hpp"
#include "voxfield/core/output.hpp"
#include "voxfield/core/vdb.hpp"

namespace voxfield::test {

// Writes to `grid` two 4^3 cubes 600000 voxels apart (colours 5 and 9, field 0): a
// 600004 x 4 x 500004 grid of 1.2e12 voxels, 128 of them solid, in 2 tiles.
inline void write_far_cubes_vdb(const std::filesystem::path& grid) {
    const std::vector<std::uint8_t> a(64, 5), b(64, 9), field(64, 0);
    const std::array<Box, 2> boxes = {Box{{0, 0, 0}, {4, 4, 4}},
                                      Box{{600000, 0, 500000}, {600004, 4, 500004}}};
    std::size_t next = 0;
    OutputBatch batch;
    write_vdb(
        batch, grid,
        [&](VdbBox& box) {
            if (next == boxes.size()) {
                return false;
            }
            box = VdbBox{boxes[next], next == 0 ? a : b, field};
            ++next;
            return true;
        },
        Format::u8, VdbFieldSpec{});
    batch.commit();
}

}  // namespace voxfield::test
