#pragma once
// Summary statistics of repeated measurements.
#include <cstddef>
#include <span>

namespace voxfield {

struct Summary {
    std::size_t n = 0;
    double mean = 0, median = 0, std = 0, min = 0, max = 0;
    // mean -/+ 1.96 * std / sqrt(n); the low end clipped at 0 when no sample is negative
    double ci95_lo = 0, ci95_hi = 0;
};

// std is the sample standard deviation (n - 1); n == 0 gives all zeros, n == 1 std 0.
Summary summarize(std::span<const double> samples);

}  // namespace voxfield
