#pragma once
// Small host-side helpers shared by the generators.
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <CL/opencl.hpp>

#include "voxfield/core/format.hpp"

namespace voxfield::ocl {

inline std::size_t round_up(std::size_t v, std::size_t m) {
    return (v + m - 1) / m * m;
}

// The event a launch named `name` returns into `events` (appended), or none (null) when
// `events` is null: profiled stages, or launches without events (set_stage_events(false)).
inline cl::Event* stage_event(std::vector<std::pair<std::string, cl::Event>>* events,
                              const std::string& name) {
    return events != nullptr ? &events->emplace_back(name, cl::Event()).second : nullptr;
}

inline std::size_t next_pow2(std::size_t v) {
    std::size_t p = 1;
    while (p < v) {
        p <<= 1;
    }
    return p;
}

// The padding on each side of a row that the CPU layout's doubling sweeps take (xy_slices_seq,
// xy_bytes, row_doubling): their largest step, half the row rounded up to a power of two, and
// at least 1 (a row of one voxel still takes the step to its padding: a signed field's
// outside).
inline std::size_t row_pad(std::size_t x) {
    return std::max<std::size_t>(1, next_pow2(x) / 2);
}

// Build options of the kernels that write a field: OUT_T (the element type), OUT_MAX (its
// largest distance) and PACKED (1 for packed32), shared by classic_common.cl's users.
inline std::string output_options(Format f) {
    const char* t = f == Format::u8 ? "uchar" : f == Format::u16 ? "ushort" : "uint";
    const char* max = f == Format::u8 ? "255u" : f == Format::u16 ? "65535u" : "4294967295u";
    return std::string("-DOUT_T=") + t + " -DOUT_MAX=" + max +
           " -DPACKED=" + (f == Format::packed32 ? "1" : "0") + " -cl-std=CL1.2";
}

}  // namespace voxfield::ocl
