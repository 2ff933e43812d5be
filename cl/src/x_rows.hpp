#pragma once
// The GPU layout's x pass of exact_manhattan.cl, shared by ExactManhattan and by
// ExactSeparable's banded GPU transform (whose first pass is the same 1-D distance).
#include "voxfield/cl/generator.hpp"

#include <vector>

namespace voxfield::ocl {

// Every row's 1-D distance along x to its nearest solid, into `work` (the work type of
// `format`: uchar for u8/packed32, ushort for u16, uint for u32; its maximum where a row has
// no solid or the distance does not fit): x_rows_map where X is a multiple of 16 (and a row's
// X / 16 work-items fit a work-group; longer rows in chunks, x_rows_ends then x_rows_chunks),
// else x_rows_local, else (ragged rows too long for its local memory) x_rows_long; saturated at
// `cap` below the work type's maximum. With `empty_targets` the zero voxels are the targets (a
// signed field's inner transform, SciPy's zero targets), read from `voxels` as they are: no
// inverted copy. The launches, in order, and the buffer of the chunks' ends they use (empty for
// whole rows), which the caller keeps while it runs them.
struct XRows {
    std::vector<KernelLaunch> launches;
    cl::Buffer ends;
};
XRows gpu_x_rows(Context& ctx, Dims dims, Format format, const cl::Buffer& voxels,
                 const cl::Buffer& work, std::uint32_t cap = 0xFFFFFFFFu,
                 bool empty_targets = false);

}  // namespace voxfield::ocl
