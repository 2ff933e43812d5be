#include "input_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <string>
#include <string_view>
#include <system_error>

#include "voxfield/core/error.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield::detail {

namespace fs = std::filesystem;

namespace {

// InputError unless `path` names something that exists and is not a directory.
void require_file(const fs::path& path) {
    std::error_code ec;
    const auto st = fs::status(path, ec);
    if (!fs::exists(st)) {
        throw InputError("'" + path.string() + "': no such file");
    }
    if (fs::is_directory(st)) {
        throw InputError("'" + path.string() + "': is a directory, not a file");
    }
}

std::string cannot_open(const fs::path& path, int e) {
    return "'" + path.string() + "': cannot open for reading (" +
           std::generic_category().message(e) + ")";
}

std::string cannot_read(const fs::path& path) {
    return "'" + path.string() + "': cannot read (not a regular file?)";
}

}  // namespace

std::ifstream open_input(const fs::path& path, std::uint64_t& size) {
    require_file(path);
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        throw InputError(cannot_open(path, errno));
    }
    in.seekg(0, std::ios::end);
    const auto end = in.tellg();
    in.seekg(0, std::ios::beg);
    if (end < 0 || !in) {
        throw InputError(cannot_read(path));
    }
    size = static_cast<std::uint64_t>(end);
    return in;
}

InputFd::InputFd(const fs::path& path) : file_(path.string()) {
    require_file(path);
    fd_ = ::open(file_.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd_ < 0) {
        throw InputError(cannot_open(path, errno));
    }
    struct stat st {};
    if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) {
        ::close(fd_);
        throw InputError(cannot_read(path));
    }
    size_ = static_cast<std::uint64_t>(st.st_size);
}

InputFd::~InputFd() {
    ::close(fd_);
}

void InputFd::read_at(std::uint64_t offset, void* dst, std::size_t n) const {
    auto* p = static_cast<char*>(dst);
    std::size_t done = 0;
    while (done < n) {
        const ssize_t r = ::pread(fd_, p + done, n - done, static_cast<off_t>(offset + done));
        if (r < 0 && errno == EINTR) {
            continue;
        }
        if (r < 0) {
            throw InputError(file_ + ": read error (" + std::generic_category().message(errno) +
                             ", " + std::to_string(done) + " of " + std::to_string(n) + " bytes)");
        }
        if (r == 0) {
            throw InputError(file_ + ": read error (" + std::to_string(done) + " of " +
                             std::to_string(n) + " bytes)");
        }
        done += static_cast<std::size_t>(r);
    }
}

}  // namespace voxfield::detail

namespace voxfield {

namespace {

VoxModel load_vox(const std::filesystem::path& path, const InputOptions&) {
    return read_vox(path);
}

VoxModel load_npy(const std::filesystem::path& path, const InputOptions&) {
    const NpyArray array = read_npy(path);
    try {
        return VoxModel{world_from_npy(array), Palette()};
    } catch (const InputError& e) {
        throw InputError(path.string() + ": " + e.what());
    }
}

// The input formats, by lower-case extension.
struct InputFormat {
    std::string_view extension;
    VoxModel (*load)(const std::filesystem::path&, const InputOptions&);
};
constexpr InputFormat kInputFormats[] = {
    {".vox", load_vox},
    {".npy", load_npy},
};

}  // namespace

VoxModel load_world(const std::filesystem::path& path, const InputOptions& options) {
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    std::string accepted;
    for (const InputFormat& f : kInputFormats) {
        if (ext == f.extension) {
            return f.load(path, options);
        }
        accepted += (accepted.empty() ? "" : ", ") + std::string(f.extension);
    }
    throw InputError("'" + path.string() + "': unsupported file type " +
                     (ext.empty() ? std::string("(no extension)") : "'" + ext + "'") +
                     " (expected one of " + accepted + ")");
}

}  // namespace voxfield
