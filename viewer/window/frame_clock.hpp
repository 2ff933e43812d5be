#pragma once
// The viewers' frame loop clock: when each frame starts, its time step and its time since the
// loop began.
#include <chrono>

#include "voxfield/core/clock.hpp"

namespace voxfield::cli {

struct FrameTick {
    Clock::time_point t0;  // when the frame started
    double dt = 0;         // seconds since the previous frame started (1/60 when scripted)
    double time_s = 0;     // seconds since the clock was made
};

class FrameClock {
  public:
    // Scripted frames advance by a fixed step: the same views on any machine.
    explicit FrameClock(bool scripted) : scripted_(scripted), start_(Clock::now()), last_(start_) {}

    // Starts a frame.
    FrameTick tick() {
        FrameTick t;
        t.t0 = Clock::now();
        t.dt = scripted_ ? 1.0 / 60 : std::chrono::duration<double>(t.t0 - last_).count();
        last_ = t.t0;
        t.time_s = std::chrono::duration<double>(t.t0 - start_).count();
        return t;
    }

  private:
    bool scripted_;
    Clock::time_point start_, last_;
};

}  // namespace voxfield::cli
