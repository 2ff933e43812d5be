#pragma once
// Wall-clock intervals for the timings the front ends and benchmarks report.
#include <chrono>

namespace voxfield {

using Clock = std::chrono::steady_clock;

// Milliseconds from t to now.
inline double ms_since(Clock::time_point t) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
}

}  // namespace voxfield
