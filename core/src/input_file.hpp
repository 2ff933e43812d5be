#pragma once
// Opening an input file with the project's messages (internal to core/).
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

namespace voxfield::detail {

// Opens `path` for binary reading and sets `size` to its length; InputError for a missing,
// directory, unreadable or unseekable path.
std::ifstream open_input(const std::filesystem::path& path, std::uint64_t& size);

// The same checks and messages, for reading by file descriptor straight into the caller's
// memory (no stream buffer in between). Closed when destroyed.
class InputFd {
  public:
    explicit InputFd(const std::filesystem::path& path);
    ~InputFd();
    InputFd(const InputFd&) = delete;
    InputFd& operator=(const InputFd&) = delete;

    std::uint64_t size() const { return size_; }
    // Reads exactly `n` bytes at `offset` into `dst`; InputError naming the file otherwise.
    void read_at(std::uint64_t offset, void* dst, std::size_t n) const;

  private:
    std::string file_;
    int fd_ = -1;
    std::uint64_t size_ = 0;
};

}  // namespace voxfield::detail
