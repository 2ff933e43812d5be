// Atomic output files: temporary file + rename.
#include "output_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <filesystem>
#include <string>
#include <system_error>

#include "voxfield/core/error.hpp"

namespace voxfield::detail {

namespace {

namespace fs = std::filesystem;

std::string errno_text(int e) {
    return std::generic_category().message(e);
}

}  // namespace

void write_file_atomic(const std::filesystem::path& path,
                       std::initializer_list<std::span<const std::uint8_t>> parts) {
    const std::string file = path.string();
    fs::path dir = path.parent_path();
    if (dir.empty()) {
        dir = ".";
    }
    std::error_code ec;
    if (!fs::is_directory(dir, ec)) {
        throw InputError("cannot write '" + file + "': folder '" + dir.string() +
                         "' does not exist");
    }
    if (fs::is_directory(path, ec)) {
        throw InputError("cannot write '" + file + "': it is a directory");
    }

    // Temporary file in the same folder, then rename: readers never see a partial file.
    // O_EXCL with a unique name; mode 0666 minus the umask, like any new file.
    static std::atomic<std::uint64_t> counter{0};
    int fd = -1;
    std::string tmp;
    for (int attempt = 0; fd < 0; ++attempt) {
        // Built by append: GCC 12 gives a false -Wrestrict on "." + std::string.
        std::string leaf(".");
        leaf.append(path.filename().string());
        leaf.append(".tmp-");
        leaf.append(std::to_string(::getpid()));
        leaf.append("-");
        leaf.append(std::to_string(counter.fetch_add(1)));
        tmp = (dir / leaf).string();
        fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (fd < 0 && (errno != EEXIST || attempt > 100)) {
            throw InputError("cannot write '" + file + "': cannot create a temporary file in '" +
                             dir.string() + "' (" + errno_text(errno) + ")");
        }
    }
    auto fail = [&](const std::string& what, int e) {
        ::close(fd);
        ::unlink(tmp.c_str());
        throw InputError("cannot write '" + file + "': " + what + " (" + errno_text(e) + ")");
    };
    auto write_all = [&](const std::uint8_t* p, std::size_t n) {
        while (n > 0) {
            const ssize_t w = ::write(fd, p, n);
            if (w < 0) {
                if (errno == EINTR) {
                    continue;
                }
                fail("write failed", errno);
            }
            p += w;
            n -= static_cast<std::size_t>(w);
        }
    };
    for (const auto& part : parts) {
        write_all(part.data(), part.size());
    }
    // Not forced to disk (no fsync, as numpy.save and cp do not): the rename makes the file
    // whole or absent for readers; its data reach the disk with the page cache's writeback.
    if (::close(fd) != 0) {
        const int e = errno;
        ::unlink(tmp.c_str());
        throw InputError("cannot write '" + file + "': close failed (" + errno_text(e) + ")");
    }
    if (::rename(tmp.c_str(), file.c_str()) != 0) {
        const int e = errno;
        ::unlink(tmp.c_str());
        throw InputError("cannot write '" + file + "': rename failed (" + errno_text(e) + ")");
    }
}

}  // namespace voxfield::detail
