// Progress of long work on a terminal (see progress.hpp).
#include "progress.hpp"

#include <unistd.h>

#include <cstdio>
#include <utility>

namespace voxfield::cli {

namespace {

constexpr auto kShowAfter = std::chrono::seconds(1);
constexpr auto kRefresh = std::chrono::milliseconds(250);

}  // namespace

Progress::Progress(std::string command)
    : command_(std::move(command)),
      enabled_(::isatty(STDERR_FILENO) == 1),
      start_(std::chrono::steady_clock::now()) {
    if (enabled_) {
        thread_ = std::thread([this] { loop(); });
    }
}

Progress::~Progress() {
    stop();
}

void Progress::set(std::string what) {
    const std::lock_guard lock(mutex_);
    what_ = std::move(what);
}

void Progress::stop() {
    {
        const std::lock_guard lock(mutex_);
        if (stopping_) {
            return;
        }
        stopping_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable()) {
        thread_.join();
    }
    if (shown_) {
        std::fputs("\r\033[K", stderr);
        std::fflush(stderr);
    }
}

void Progress::print(std::FILE* stream, const std::string& text) {
    const std::lock_guard lock(mutex_);
    if (shown_) {
        std::fputs("\r\033[K", stderr);
        std::fflush(stderr);
        shown_ = false;
    }
    std::fputs(text.c_str(), stream);
    std::fflush(stream);
}

void Progress::loop() {
    std::unique_lock lock(mutex_);
    if (wake_.wait_until(lock, start_ + kShowAfter, [this] { return stopping_; })) {
        return;
    }
    while (!stopping_) {
        const double s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
        // \r, the line, then erase what a longer previous line left on the right.
        std::fprintf(stderr, "\r%s: %s%s%.1f s\033[K", command_.c_str(), what_.c_str(),
                     what_.empty() ? "" : ", ", s);
        std::fflush(stderr);
        shown_ = true;
        wake_.wait_for(lock, kRefresh, [this] { return stopping_; });
    }
}

}  // namespace voxfield::cli
