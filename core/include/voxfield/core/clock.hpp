#pragma once
// Wall-clock intervals for the timings the front ends and benchmarks report.
#include <chrono>

namespace voxfield {

using Clock = std::chrono::steady_clock;

// Milliseconds from `from` to `to`.
inline double ms_between(Clock::time_point from, Clock::time_point to) {
    return std::chrono::duration<double, std::milli>(to - from).count();
}

// Milliseconds from t to now.
inline double ms_since(Clock::time_point t) {
    return ms_between(t, Clock::now());
}

}  // namespace voxfield
