#pragma once
// The city scene built tile by tile (core's CityScene into a SparseWorld), the world the sparse
// tracer's update tests (sparse_update_test.cpp, tests/pipeline/shared_trees_test.cpp) edit.
#include <cstdint>
#include <span>

#include "voxfield/core/scenes.hpp"
#include "voxfield/core/sparse.hpp"

namespace voxfield::test {

inline SparseWorld city(Dims dims, std::uint64_t seed) {
    const CityScene scene(dims, seed);
    return SparseWorld::from_fill(
        dims, [&](const Box& box, std::span<std::uint8_t> out) { scene.fill(box, out); });
}

}  // namespace voxfield::test
