#pragma once
// The brush the sparse tracer tests edit with (sparse_trace_test.cpp, sparse_update_test.cpp).
#include <cstdint>

#include "voxfield/core/brush.hpp"

namespace voxfield::test {

inline Brush brush(BrushOp op, BrushShape shape, Int3 centre, std::int64_t radius,
                   std::uint8_t material) {
    Brush b;
    b.op = op;
    b.shape = shape;
    b.centre = centre;
    b.radius = radius;
    b.material = material;
    return b;
}

}  // namespace voxfield::test
