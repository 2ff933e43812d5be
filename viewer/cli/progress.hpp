#pragma once
// Progress of long work on a terminal (DESIGN §4): one updating line on stderr, shown once
// the work has taken a second and refreshed a few times a second by a thread of its own (so a
// single long kernel shows its elapsed time too), cleared when done. Quiet when stderr is not
// a terminal.
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <string>
#include <thread>

namespace voxfield::cli {

class Progress {
  public:
    // `command` starts the line ("generate", "bench", ...).
    explicit Progress(std::string command);
    ~Progress();  // stops, clearing the line if it was shown
    Progress(const Progress&) = delete;
    Progress& operator=(const Progress&) = delete;

    // What is being done now ("kernels 3/10", "edit 120/400"); shown with the elapsed time.
    void set(std::string what);
    // Stops and clears the line now (before printing results to stderr).
    void stop();
    // Writes `text` (whole lines) to `stream` (stdout or stderr) and flushes it, clearing the
    // line first if it is shown; the line comes back at its next refresh. For results printed
    // while the work goes on.
    void print(std::FILE* stream, const std::string& text);
    // Whether stderr is a terminal (the line is shown at all).
    bool enabled() const { return enabled_; }

  private:
    void loop();

    const std::string command_;
    const bool enabled_;
    const std::chrono::steady_clock::time_point start_;
    std::string what_;
    bool stopping_ = false, shown_ = false;
    std::mutex mutex_;
    std::condition_variable wake_;
    std::thread thread_;
};

}  // namespace voxfield::cli
