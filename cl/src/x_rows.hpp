#pragma once
// The GPU layout's x pass of exact_manhattan.cl, shared by ExactManhattan and by
// ExactSeparable's banded GPU transform (whose first pass is the same 1-D distance).
#include "voxfield/cl/generator.hpp"

namespace voxfield::ocl {

// Every row's 1-D distance along x to its nearest solid, into `work` (the work type of
// `format`: uchar for u8/packed32, ushort for u16, uint for u32; its maximum where a row has
// no solid or the distance does not fit): x_rows_map where X is a multiple of 16 (and a row's
// X / 16 work-items fit a work-group), else x_rows_local, else (rows too long for its local
// memory) x_rows_long; saturated at `cap` below the work type's maximum. With
// `empty_targets` the zero voxels are the targets (a signed field's inner transform, SciPy's
// zero targets), read from `voxels` as they are: no inverted copy.
KernelLaunch gpu_x_rows(Context& ctx, Dims dims, Format format, const cl::Buffer& voxels,
                        const cl::Buffer& work, std::uint32_t cap = 0xFFFFFFFFu,
                        bool empty_targets = false);

}  // namespace voxfield::ocl
