// The output writer (see voxfield/core/output.hpp).
#include "output_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <random>
#include <string>
#include <system_error>
#include <utility>

#include "voxfield/core/error.hpp"

namespace voxfield {

namespace {

namespace fs = std::filesystem;

std::string errno_text(int e) {
    return std::generic_category().message(e);
}

// A failure on `file`: the user's (exit 2) for what a different path or permission mends,
// a runtime failure (exit 1) for the rest (no space, I/O error, a reader gone).
[[noreturn]] void fail(const std::string& file, const std::string& what, int e) {
    const std::string message = "cannot write '" + file + "': " + what + " (" + errno_text(e) + ")";
    switch (e) {
        case EACCES:
        case EPERM:
        case EROFS:
        case ENOENT:
        case ENOTDIR:
        case EISDIR:
        case ENAMETOOLONG:
        case ELOOP:
        case ENXIO:
            throw InputError(message);
        default:
            throw OutputError(message);
    }
}

// The temporaries of every batch not yet renamed or removed, for remove_output_temporaries (a
// signal handler): each name is written once into a slot of its own that is never reused, and
// published by its flag after, so that a handler never reads a name being written. A name
// longer than a slot, or past the last slot, goes untracked (the batch still removes it).
constexpr std::size_t kTrackedSlots = 256;
constexpr std::size_t kTrackedName = 1024;
char g_tracked_names[kTrackedSlots][kTrackedName];
std::atomic<bool> g_tracked[kTrackedSlots];
std::atomic<std::size_t> g_tracked_used{0};

void track_temporary(const std::string& tmp) {
    if (tmp.size() >= kTrackedName) {
        return;
    }
    const std::size_t i = g_tracked_used.fetch_add(1);
    if (i < kTrackedSlots) {
        std::memcpy(g_tracked_names[i], tmp.c_str(), tmp.size() + 1);
        g_tracked[i].store(true);
    }
}

void untrack_temporary(const std::string& tmp) {
    const std::size_t n = std::min(g_tracked_used.load(), kTrackedSlots);
    for (std::size_t i = 0; i < n; ++i) {
        if (g_tracked[i].load() && tmp == g_tracked_names[i]) {
            g_tracked[i].store(false);
            return;
        }
    }
}

// A file to create or replace through a temporary, or a device or FIFO written directly.
enum class Target { file, direct };

// `path` with the symbolic links at its end followed, dangling ones too (a relative target is
// taken from the link's folder): the file that writing through it creates or replaces.
fs::path follow_links(const fs::path& path) {
    fs::path p = path;
    for (int hops = 0; hops < 40; ++hops) {
        std::error_code ec;
        if (!fs::is_symlink(fs::symlink_status(p, ec))) {
            return p;
        }
        const fs::path to = fs::read_symlink(p, ec);
        if (ec) {
            return p;
        }
        p = to.is_absolute() ? to : p.parent_path() / to;
    }
    throw InputError("cannot write '" + path.string() + "': too many levels of symbolic links");
}

// What writing `path` means (see output.hpp); InputError for a refused target. `resolved` is
// the file to create or replace (the target of a symbolic link, dangling or not).
Target classify(const fs::path& path, std::string& resolved) {
    const std::string file = path.string();
    if (file.empty()) {
        throw InputError("cannot write '': an output needs a file name");
    }
    resolved = file;
    struct stat st {};
    if (::stat(file.c_str(), &st) == 0) {
        if (S_ISDIR(st.st_mode)) {
            throw InputError("cannot write '" + file + "': it is a directory");
        }
        if (S_ISCHR(st.st_mode) || S_ISFIFO(st.st_mode)) {
            return Target::direct;
        }
        if (S_ISSOCK(st.st_mode)) {
            throw InputError("cannot write '" + file + "': it is a socket; give a file name");
        }
        if (S_ISBLK(st.st_mode)) {
            throw InputError("cannot write '" + file +
                             "': it is a block device (a disk); give a file name");
        }
        if (!S_ISREG(st.st_mode)) {
            throw InputError("cannot write '" + file + "': it is not a regular file");
        }
        std::error_code ec;
        const fs::path real = fs::canonical(path, ec);
        if (!ec) {
            resolved = real.string();
        }
        if (::access(resolved.c_str(), W_OK) != 0) {
            fail(file, "the existing file is not writable", errno);
        }
    } else if (errno == ENOENT) {
        resolved = follow_links(path).string();
    } else if (errno != ENOTDIR) {
        fail(file, "cannot examine the path", errno);
    }
    fs::path dir = fs::path(resolved).parent_path();
    if (dir.empty()) {
        dir = ".";
    }
    struct stat ds {};
    if (::stat(dir.c_str(), &ds) != 0) {
        if (errno == ENOENT) {
            throw InputError("cannot write '" + file + "': folder '" + dir.string() +
                             "' does not exist");
        }
        fail(file, "cannot examine folder '" + dir.string() + "'", errno);
    }
    if (!S_ISDIR(ds.st_mode)) {
        throw InputError("cannot write '" + file + "': '" + dir.string() + "' is not a folder");
    }
    if (::access(dir.c_str(), W_OK | X_OK) != 0) {
        fail(file, "folder '" + dir.string() + "' is not writable", errno);
    }
    return Target::file;
}

// Closes its descriptor when a write fails or a producer throws part-way.
class Fd {
  public:
    explicit Fd(int fd) : fd_(fd) {}
    ~Fd() {
        if (fd_ >= 0) {
            ::close(fd_);
        }
    }
    Fd(const Fd&) = delete;
    Fd& operator=(const Fd&) = delete;
    int get() const { return fd_; }
    // Gives the descriptor up without closing it.
    int release() { return std::exchange(fd_, -1); }
    // Closes it now; the close's errno when it fails, else 0.
    int close() {
        const int rc = ::close(fd_);
        fd_ = -1;
        return rc == 0 ? 0 : errno;
    }

  private:
    int fd_;
};

void write_all(int fd, const std::string& file, std::span<const std::uint8_t> part) {
    const std::uint8_t* p = part.data();
    std::size_t n = part.size();
    while (n > 0) {
        const ssize_t w = ::write(fd, p, n);
        if (w < 0 && errno == EINTR) {
            continue;
        }
        if (w <= 0) {
            fail(file, "write failed", w < 0 ? errno : EIO);
        }
        p += w;
        n -= static_cast<std::size_t>(w);
    }
}

// A unique temporary beside `target` (O_EXCL, random name, mode 0666 minus the umask like
// any new file); its name in `tmp`.
int create_temporary(const std::string& file, const std::string& target, std::string& tmp) {
    static thread_local std::mt19937_64 random{std::random_device{}()};
    const fs::path t(target);
    fs::path dir = t.parent_path();
    for (int attempt = 0;; ++attempt) {
        char suffix[20];
        std::snprintf(suffix, sizeof suffix, "%016llx", static_cast<unsigned long long>(random()));
        // Built by append: GCC 12 gives a false -Wrestrict on "." + std::string.
        std::string leaf(".");
        leaf.append(t.filename().string());
        leaf.append(".tmp-");
        leaf.append(suffix);
        tmp = (dir / leaf).string();
        const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (fd >= 0) {
            track_temporary(tmp);
            return fd;
        }
        if (errno != EEXIST || attempt > 100) {
            fail(file,
                 "cannot create a temporary file in '" + (dir.empty() ? "." : dir.string()) + "'",
                 errno);
        }
    }
}

}  // namespace

void check_output_path(const fs::path& path) {
    std::string resolved;
    classify(path, resolved);
}

void check_outputs(const std::vector<NamedPath>& outputs, const std::vector<NamedPath>& inputs) {
    struct Key {
        bool exists = false, device = false;
        dev_t dev = 0;
        ino_t ino = 0;
        fs::path path;
    };
    auto key_of = [](const fs::path& p) {
        Key k;
        struct stat st {};
        if (::stat(p.c_str(), &st) == 0) {
            k.exists = true;
            k.device = S_ISCHR(st.st_mode);
            k.dev = st.st_dev;
            k.ino = st.st_ino;
        }
        std::error_code ec;
        const fs::path file = fs::absolute(k.exists ? p : follow_links(p), ec);
        k.path = fs::weakly_canonical(file, ec);
        if (ec) {
            k.path = file.lexically_normal();
        }
        return k;
    };
    auto same = [](const Key& a, const Key& b) {
        if (a.exists || b.exists) {
            return a.exists && b.exists && a.dev == b.dev && a.ino == b.ino;
        }
        return a.path == b.path;
    };
    std::vector<std::pair<const NamedPath*, Key>> seen;
    for (const NamedPath& out : outputs) {
        if (out.path.empty()) {
            continue;
        }
        check_output_path(out.path);
        const Key k = key_of(out.path);
        for (const NamedPath& in : inputs) {
            if (!in.path.empty() && same(k, key_of(in.path))) {
                throw InputError(out.option + " '" + out.path.string() + "' is the input " +
                                 (in.option.empty() ? "" : in.option + " ") + "'" +
                                 in.path.string() + "': give the output another name");
            }
        }
        for (const auto& [other, ok] : seen) {
            if (!k.device && same(k, ok)) {
                throw InputError(other->option + " and " + out.option + " name the same file '" +
                                 out.path.string() + "': give each output its own file");
            }
        }
        seen.emplace_back(&out, k);
    }
}

OutputBatch::~OutputBatch() {
    for (const auto& [target, fd] : reserved_) {
        ::close(fd);
    }
    for (const auto& [tmp, target] : pending_) {
        ::unlink(tmp.c_str());
        untrack_temporary(tmp);
    }
}

void OutputBatch::reserve(const fs::path& path, std::uint64_t bytes) {
    const std::string file = path.string();
    std::string target;
    if (classify(path, target) == Target::direct) {
        return;
    }
    std::string tmp;
    Fd fd(create_temporary(file, target, tmp));
    pending_.emplace_back(tmp, target);
    // Only a lack of room (or a failing disk) is the output's failure: a file system that
    // cannot reserve (EOPNOTSUPP and the like) is written as any other.
    if (bytes > 0 && ::fallocate(fd.get(), 0, 0, static_cast<off_t>(bytes)) != 0 &&
        (errno == ENOSPC || errno == EDQUOT || errno == EFBIG || errno == EIO)) {
        fail(file, "cannot take " + std::to_string(bytes) + " bytes for it", errno);
    }
    reserved_.emplace_back(target, fd.release());
}

void OutputBatch::write(const fs::path& path,
                        std::initializer_list<std::span<const std::uint8_t>> parts) {
    write(path, [&](const Sink& sink) {
        for (const auto& part : parts) {
            sink(part);
        }
    });
}

void OutputBatch::write(const fs::path& path, const std::function<void(const Sink&)>& produce) {
    const std::string file = path.string();
    std::string target;
    if (classify(path, target) == Target::direct) {
        Fd fd(::open(file.c_str(), O_WRONLY | O_CLOEXEC));
        if (fd.get() < 0) {
            fail(file, "cannot open", errno);
        }
        produce([&](std::span<const std::uint8_t> part) { write_all(fd.get(), file, part); });
        if (const int e = fd.close(); e != 0) {
            fail(file, "close failed", e);
        }
        return;
    }
    const auto found = std::find_if(reserved_.begin(), reserved_.end(),
                                    [&](const auto& r) { return r.first == target; });
    const bool reserved = found != reserved_.end();
    std::string tmp;
    Fd fd(reserved ? found->second : create_temporary(file, target, tmp));
    if (reserved) {
        reserved_.erase(found);
    } else {
        pending_.emplace_back(tmp, target);
    }
    std::uint64_t written = 0;
    produce([&](std::span<const std::uint8_t> part) {
        write_all(fd.get(), file, part);
        written += part.size();
    });
    // A reserved file is cut to what was written (its room may have been more).
    if (reserved && ::ftruncate(fd.get(), static_cast<off_t>(written)) != 0) {
        fail(file, "cannot set its length", errno);
    }
    // Not forced to disk (no fsync, as numpy.save and cp do not): the rename makes the file
    // whole or absent for readers; its data reach the disk with the page cache's writeback.
    if (const int e = fd.close(); e != 0) {
        fail(file, "close failed", e);
    }
}

void OutputBatch::write(const fs::path& path, const std::string& text) {
    write(path, {std::span<const std::uint8_t>(reinterpret_cast<const std::uint8_t*>(text.data()),
                                               text.size())});
}

void OutputBatch::commit() {
    while (!pending_.empty()) {
        const auto [tmp, target] = pending_.front();
        // Renamed only onto a regular file or a new path: something else put there since the
        // write is left alone.
        struct stat st {};
        const bool exists = ::lstat(target.c_str(), &st) == 0;
        if (exists && !S_ISREG(st.st_mode)) {
            throw InputError("cannot write '" + target +
                             "': it is no longer a regular file or a new path");
        }
        // An old file is swapped with the complete new one in one step (renameat2's
        // RENAME_EXCHANGE), then removed under the temporary's name. A plain rename over it
        // would do the same for readers, but ext4 (auto_da_alloc) starts the new file's
        // writeback inside such a rename: 0.36 s after a 512 MiB field's `generate` had written
        // it on an H100 machine (bench/README.md, "The end of the process"). A file system
        // without the exchange gets the plain rename.
        if (exists &&
            ::renameat2(AT_FDCWD, tmp.c_str(), AT_FDCWD, target.c_str(), RENAME_EXCHANGE) == 0) {
            struct stat old {};
            if (::lstat(tmp.c_str(), &old) != 0 || !S_ISREG(old.st_mode)) {
                // Not the regular file lstat saw (replaced meanwhile): swapped back, refused.
                ::renameat2(AT_FDCWD, tmp.c_str(), AT_FDCWD, target.c_str(), RENAME_EXCHANGE);
                throw InputError("cannot write '" + target +
                                 "': it is no longer a regular file or a new path");
            }
            ::unlink(tmp.c_str());  // the old file; a failure leaves a hidden temporary only
        } else if (::rename(tmp.c_str(), target.c_str()) != 0) {
            fail(target, "rename failed", errno);
        }
        untrack_temporary(tmp);
        pending_.erase(pending_.begin());
    }
}

void remove_output_temporaries() noexcept {
    const std::size_t n = std::min(g_tracked_used.load(), kTrackedSlots);
    for (std::size_t i = 0; i < n; ++i) {
        if (g_tracked[i].load()) {
            ::unlink(g_tracked_names[i]);
        }
    }
}

void write_output_file(const fs::path& path,
                       std::initializer_list<std::span<const std::uint8_t>> parts) {
    OutputBatch batch;
    batch.write(path, parts);
    batch.commit();
}

void write_output_file(const fs::path& path, const std::string& text) {
    OutputBatch batch;
    batch.write(path, text);
    batch.commit();
}

namespace detail {

void write_file_atomic(const fs::path& path,
                       std::initializer_list<std::span<const std::uint8_t>> parts) {
    write_output_file(path, parts);
}

}  // namespace detail

}  // namespace voxfield
