#include "voxfield/cl/runtime.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <mutex>
#include <new>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "voxfield/core/output.hpp"

namespace voxfield::ocl {
namespace {

std::string with_context(const std::string& call, cl_int code, const std::string& context) {
    std::string msg = call + " failed with " + error_name(code);
    if (!context.empty()) {
        msg += " (" + context + ")";
    }
    return msg;
}

std::string type_name(cl_device_type t) {
    if (t & CL_DEVICE_TYPE_GPU) {
        return "gpu";
    }
    if (t & CL_DEVICE_TYPE_CPU) {
        return "cpu";
    }
    if (t & CL_DEVICE_TYPE_ACCELERATOR) {
        return "accelerator";
    }
    return "other";
}

std::string trim(std::string s) {
    while (!s.empty() && (s.back() == '\0' || s.back() == ' ')) {
        s.pop_back();
    }
    return s;
}

std::string describe(const DeviceInfo& d) {
    return "#" + std::to_string(d.index) + " " + d.name + " (" + d.platform + ", " + d.type + ")";
}

// Why `d` cannot serve any request, or "" if it can.
std::string unusable(const DeviceInfo& d) {
    if (!d.available) {
        return "device reports it is not available";
    }
    if (!d.compiler_available) {
        return "device has no OpenCL C compiler";
    }
    return "";
}

}  // namespace

ClError::ClError(const std::string& call, cl_int code, const std::string& context)
    : std::runtime_error(with_context(call, code, context)), code_(code) {}

const char* error_name(cl_int code) {
    switch (code) {
#define VF_CASE(c) \
    case c:        \
        return #c;
        VF_CASE(CL_SUCCESS)
        VF_CASE(CL_DEVICE_NOT_FOUND)
        VF_CASE(CL_DEVICE_NOT_AVAILABLE)
        VF_CASE(CL_COMPILER_NOT_AVAILABLE)
        VF_CASE(CL_MEM_OBJECT_ALLOCATION_FAILURE)
        VF_CASE(CL_OUT_OF_RESOURCES)
        VF_CASE(CL_OUT_OF_HOST_MEMORY)
        VF_CASE(CL_PROFILING_INFO_NOT_AVAILABLE)
        VF_CASE(CL_MEM_COPY_OVERLAP)
        VF_CASE(CL_BUILD_PROGRAM_FAILURE)
        VF_CASE(CL_MAP_FAILURE)
        VF_CASE(CL_EXEC_STATUS_ERROR_FOR_EVENTS_IN_WAIT_LIST)
        VF_CASE(CL_COMPILE_PROGRAM_FAILURE)
        VF_CASE(CL_LINK_PROGRAM_FAILURE)
        VF_CASE(CL_INVALID_VALUE)
        VF_CASE(CL_INVALID_DEVICE_TYPE)
        VF_CASE(CL_INVALID_PLATFORM)
        VF_CASE(CL_INVALID_DEVICE)
        VF_CASE(CL_INVALID_CONTEXT)
        VF_CASE(CL_INVALID_QUEUE_PROPERTIES)
        VF_CASE(CL_INVALID_COMMAND_QUEUE)
        VF_CASE(CL_INVALID_HOST_PTR)
        VF_CASE(CL_INVALID_MEM_OBJECT)
        VF_CASE(CL_INVALID_BUILD_OPTIONS)
        VF_CASE(CL_INVALID_PROGRAM)
        VF_CASE(CL_INVALID_PROGRAM_EXECUTABLE)
        VF_CASE(CL_INVALID_KERNEL_NAME)
        VF_CASE(CL_INVALID_KERNEL)
        VF_CASE(CL_INVALID_ARG_INDEX)
        VF_CASE(CL_INVALID_ARG_VALUE)
        VF_CASE(CL_INVALID_ARG_SIZE)
        VF_CASE(CL_INVALID_KERNEL_ARGS)
        VF_CASE(CL_INVALID_WORK_DIMENSION)
        VF_CASE(CL_INVALID_WORK_GROUP_SIZE)
        VF_CASE(CL_INVALID_WORK_ITEM_SIZE)
        VF_CASE(CL_INVALID_GLOBAL_OFFSET)
        VF_CASE(CL_INVALID_EVENT_WAIT_LIST)
        VF_CASE(CL_INVALID_EVENT)
        VF_CASE(CL_INVALID_OPERATION)
        VF_CASE(CL_INVALID_BUFFER_SIZE)
        VF_CASE(CL_INVALID_GLOBAL_WORK_SIZE)
        VF_CASE(CL_INVALID_PROPERTY)
        VF_CASE(CL_PLATFORM_NOT_FOUND_KHR)
#undef VF_CASE
        default:
            return "CL_UNKNOWN_ERROR";
    }
}

bool DeviceInfo::has_extension(const std::string& ext) const {
    return std::find(extensions.begin(), extensions.end(), ext) != extensions.end();
}

namespace {

// Every platform the ICD loader knows; empty without any.
std::vector<cl::Platform> all_platforms() {
    std::vector<cl::Platform> platforms;
    try {
        cl::Platform::get(&platforms);
    } catch (const cl::Error& e) {
        if (e.err() == CL_PLATFORM_NOT_FOUND_KHR) {
            return {};
        }
        throw ClError(e.what(), e.err(), "listing OpenCL platforms");
    }
    return platforms;
}

std::vector<cl::Device> devices_of(const cl::Platform& platform) {
    std::vector<cl::Device> devices;
    try {
        platform.getDevices(CL_DEVICE_TYPE_ALL, &devices);
    } catch (const cl::Error& e) {
        if (e.err() == CL_DEVICE_NOT_FOUND) {
            return {};
        }
        throw ClError(e.what(), e.err(), "listing devices");
    }
    return devices;
}

DeviceInfo info_of(const cl::Platform& platform, const cl::Device& dev, std::size_t index) {
    return cl_call("querying device info", [&] {
        DeviceInfo d;
        d.index = index;
        d.device = dev;
        d.name = trim(dev.getInfo<CL_DEVICE_NAME>());
        d.vendor = trim(dev.getInfo<CL_DEVICE_VENDOR>());
        d.platform = trim(platform.getInfo<CL_PLATFORM_NAME>());
        d.version = trim(dev.getInfo<CL_DEVICE_VERSION>());
        d.driver = trim(dev.getInfo<CL_DRIVER_VERSION>());
        d.type = type_name(dev.getInfo<CL_DEVICE_TYPE>());
        d.compute_units = dev.getInfo<CL_DEVICE_MAX_COMPUTE_UNITS>();
        d.global_mem = dev.getInfo<CL_DEVICE_GLOBAL_MEM_SIZE>();
        d.max_alloc = dev.getInfo<CL_DEVICE_MAX_MEM_ALLOC_SIZE>();
        d.local_mem = dev.getInfo<CL_DEVICE_LOCAL_MEM_SIZE>();
        d.max_work_group = dev.getInfo<CL_DEVICE_MAX_WORK_GROUP_SIZE>();
        d.available = dev.getInfo<CL_DEVICE_AVAILABLE>() != CL_FALSE;
        d.compiler_available = dev.getInfo<CL_DEVICE_COMPILER_AVAILABLE>() != CL_FALSE;
        d.host_unified_memory = dev.getInfo<CL_DEVICE_HOST_UNIFIED_MEMORY>() != CL_FALSE;
        std::istringstream ext(dev.getInfo<CL_DEVICE_EXTENSIONS>());
        for (std::string e; ext >> e;) {
            d.extensions.push_back(e);
        }
        return d;
    });
}

// The platforms walked in order, each asked for its devices only when the walk reaches it:
// selection stops at the platform holding the device asked for, so the platforms after it
// (another vendor's driver, which may take long to start) are never asked.
class PlatformWalk {
  public:
    explicit PlatformWalk(std::vector<cl::Platform> platforms)
        : platforms_(std::move(platforms)), devices_(platforms_.size()) {}

    // The first device, in list_devices() order, that `accept(device)` takes; its full info.
    template <class Accept>
    std::optional<DeviceInfo> find(Accept&& accept) {
        std::size_t index = 0;
        for (std::size_t p = 0; p < platforms_.size(); ++p) {
            const std::vector<cl::Device>& devices = devices_on(p);
            for (const cl::Device& dev : devices) {
                if (accept(dev, index)) {
                    return info_of(platforms_[p], dev, index);
                }
                ++index;
            }
        }
        return std::nullopt;
    }

  private:
    const std::vector<cl::Device>& devices_on(std::size_t p) {
        if (!devices_[p]) {
            devices_[p] = devices_of(platforms_[p]);
        }
        return *devices_[p];
    }

    std::vector<cl::Platform> platforms_;
    std::vector<std::optional<std::vector<cl::Device>>> devices_;
};

// Whether `dev` is usable and of `type` ("" for any): the queries unusable() and the type
// filter of select_device need, without the rest of the device's info.
bool usable_of_type(const cl::Device& dev, const std::string& type) {
    return cl_call("querying device info", [&] {
        return (type.empty() || type_name(dev.getInfo<CL_DEVICE_TYPE>()) == type) &&
               dev.getInfo<CL_DEVICE_AVAILABLE>() != CL_FALSE &&
               dev.getInfo<CL_DEVICE_COMPILER_AVAILABLE>() != CL_FALSE;
    });
}

}  // namespace

std::vector<DeviceInfo> list_devices() {
    std::vector<DeviceInfo> out;
    for (const cl::Platform& platform : all_platforms()) {
        for (const cl::Device& dev : devices_of(platform)) {
            out.push_back(info_of(platform, dev, out.size()));
        }
    }
    return out;
}

DeviceInfo select_device(const std::string& requested) {
    std::string spec = requested;
    std::string origin = "--device";
    if (spec.empty()) {
        if (const char* env = std::getenv("VOXFIELD_DEVICE"); env != nullptr && *env != '\0') {
            spec = env;
            origin = "VOXFIELD_DEVICE";
        }
    }
    const bool is_index = !spec.empty() && std::all_of(spec.begin(), spec.end(),
                                                       [](char c) { return c >= '0' && c <= '9'; });
    if (!spec.empty() && spec != "cpu" && spec != "gpu" && !is_index) {
        throw DeviceSelectionError(origin + " '" + spec +
                                   "' is not a device: use cpu, gpu or an index from "
                                   "`voxfield devices`");
    }
    // The device asked for, found by walking the platforms only as far as the one holding it;
    // the walk picks what the rules below would pick from the whole list. Only when it finds
    // nothing is every device listed, to say why each was rejected.
    PlatformWalk walk(all_platforms());
    std::optional<DeviceInfo> quick;
    if (is_index) {
        const std::size_t first = spec.find_first_not_of('0');
        const std::string digits = first == std::string::npos ? "0" : spec.substr(first);
        if (digits.size() <= 9) {
            const std::size_t want = std::stoul(digits);
            quick = walk.find([&](const cl::Device& dev, std::size_t index) {
                return index == want && usable_of_type(dev, "");
            });
        }
    } else {
        const std::vector<std::string> types =
            spec.empty() ? std::vector<std::string>{"gpu", "cpu", ""} : std::vector{spec};
        for (const std::string& type : types) {
            quick = walk.find(
                [&](const cl::Device& dev, std::size_t) { return usable_of_type(dev, type); });
            if (quick) {
                break;
            }
        }
    }
    if (quick) {
        return *quick;
    }
    const auto devices = list_devices();
    if (devices.empty()) {
        throw DeviceSelectionError(
            "no OpenCL device found: no platform is installed (install an ICD such as "
            "pocl-opencl-icd; see /etc/OpenCL/vendors)");
    }
    std::string reasons;
    auto consider = [&](const std::string& want_type, bool by_index,
                        std::size_t index) -> const DeviceInfo* {
        for (const auto& d : devices) {
            std::string why;
            if (by_index && d.index != index) {
                why = "not index " + std::to_string(index);
            } else if (!want_type.empty() && d.type != want_type) {
                why = "is a " + d.type + ", not a " + want_type;
            } else {
                why = unusable(d);
            }
            if (why.empty()) {
                return &d;
            }
            reasons += (reasons.empty() ? "" : "; ") + describe(d) + ": " + why;
        }
        return nullptr;
    };
    const DeviceInfo* found = nullptr;
    std::string wanted;
    if (spec.empty()) {
        wanted = "the default (first GPU, else first CPU)";
        found = consider("gpu", false, 0);
        if (found == nullptr) {
            reasons.clear();
            found = consider("cpu", false, 0);
        }
        if (found == nullptr) {
            reasons.clear();
            found = consider("", false, 0);
        }
    } else if (is_index) {
        wanted = origin + " " + spec;
        // Compared as text, never converted: an index beyond the integers (18446744073709551616)
        // must not wrap around to a device.
        const std::string trimmed = spec.find_first_not_of('0') == std::string::npos
                                        ? "0"
                                        : spec.substr(spec.find_first_not_of('0'));
        std::size_t index = devices.size();
        for (const auto& d : devices) {
            if (std::to_string(d.index) == trimmed) {
                index = d.index;
            }
        }
        if (index == devices.size()) {
            for (const auto& d : devices) {
                reasons += (reasons.empty() ? "" : "; ") + describe(d) + ": not index " + trimmed;
            }
            throw DeviceSelectionError(
                "no OpenCL device matches " + wanted + ": the indices are 0.." +
                std::to_string(devices.size() - 1) + " (" + reasons + "; see `voxfield devices`)");
        }
        found = consider("", true, index);
    } else {
        wanted = origin + " " + spec;
        found = consider(spec, false, 0);
    }
    if (found == nullptr) {
        throw DeviceSelectionError("no OpenCL device matches " + wanted + " (" + reasons + ")");
    }
    return *found;
}

namespace {

// The disk cache's entry format; a change of it makes every old entry a miss.
constexpr const char* kCacheMagic = "voxfield program cache 1\n";
// An entry larger than this is not read (no program binary comes near it).
constexpr std::size_t kMaxEntryBytes = std::size_t{512} << 20;

std::uint64_t fnv1a(std::uint64_t h, const void* data, std::size_t size) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < size; ++i) {
        h = (h ^ p[i]) * 0x100000001b3ULL;
    }
    return h;
}

std::string hex(std::uint64_t v) {
    char text[17];
    std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(v));
    return text;
}

// 128 bits over every part, each preceded by its length (so that no two keys run together):
// two FNV-1a passes from different offsets, named in hex.
std::string digest_of(const std::vector<std::string>& parts) {
    std::uint64_t a = 0xcbf29ce484222325ULL, b = 0x84222325cbf29ce4ULL;
    for (const std::string& part : parts) {
        const std::uint64_t n = part.size();
        a = fnv1a(fnv1a(a, &n, sizeof n), part.data(), part.size());
        b = fnv1a(fnv1a(b, part.data(), part.size()), &n, sizeof n);
    }
    return hex(a) + hex(b);
}

// The whole content of a regular file, nullopt when it is missing, not a regular file (never
// blocks on a FIFO), too large or unreadable.
std::optional<std::string> read_entry(const std::filesystem::path& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        return std::nullopt;
    }
    std::optional<std::string> out;
    struct stat st {};
    if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) &&
        static_cast<std::size_t>(st.st_size) <= kMaxEntryBytes) {
        std::string bytes(static_cast<std::size_t>(st.st_size), '\0');
        std::size_t done = 0;
        while (done < bytes.size()) {
            const ssize_t r = ::read(fd, bytes.data() + done, bytes.size() - done);
            if (r < 0 && errno == EINTR) {
                continue;
            }
            if (r <= 0) {
                break;
            }
            done += static_cast<std::size_t>(r);
        }
        if (done == bytes.size()) {
            out = std::move(bytes);
        }
    }
    ::close(fd);
    return out;
}

// One line of `text` from `pos` (without its newline), advancing `pos`; nullopt at the end.
std::optional<std::string> next_line(const std::string& text, std::size_t& pos) {
    const std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) {
        return std::nullopt;
    }
    std::string line = text.substr(pos, end - pos);
    pos = end + 1;
    return line;
}

bool cache_disabled() {
    const char* off = std::getenv("VOXFIELD_NO_PROGRAM_CACHE");
    return off != nullptr && *off != '\0' && std::string(off) != "0";
}

}  // namespace

std::filesystem::path program_cache_dir() {
    if (cache_disabled()) {
        return {};
    }
    // XDG: a relative $XDG_CACHE_HOME is invalid and ignored.
    if (const char* xdg = std::getenv("XDG_CACHE_HOME"); xdg != nullptr && xdg[0] == '/') {
        return std::filesystem::path(xdg) / "voxfield" / "programs";
    }
    if (const char* home = std::getenv("HOME"); home != nullptr && home[0] == '/') {
        return std::filesystem::path(home) / ".cache" / "voxfield" / "programs";
    }
    return {};
}

Context::Context(DeviceInfo device) : info_(std::move(device)), cache_dir_(program_cache_dir()) {
    cl_call("creating a context on " + info_.name, [&] {
        context_ = cl::Context(info_.device);
        queue_ = cl::CommandQueue(context_, info_.device, CL_QUEUE_PROFILING_ENABLE);
    });
}

Context::Unprofiled::Unprofiled(Context& ctx) {
    if (ctx.unprofiled_) {
        return;
    }
    cl_call("switching to a queue without profiling", [&] {
        ctx.queue_.finish();
        if (ctx.other_queue_() == nullptr) {
            ctx.other_queue_ = cl::CommandQueue(ctx.context_, ctx.info_.device, 0);
        }
    });
    std::swap(ctx.queue_, ctx.other_queue_);
    ctx.unprofiled_ = true;
    ctx_ = &ctx;
}

Context::Unprofiled::~Unprofiled() {
    if (ctx_ == nullptr) {
        return;
    }
    // A failing finish has no one to report to here; the next command on either queue fails.
    try {
        ctx_->queue_.finish();
    } catch (const cl::Error&) {
    }
    std::swap(ctx_->queue_, ctx_->other_queue_);
    ctx_->unprofiled_ = false;
}

cl::Program Context::program(const std::string& name, const std::vector<std::string>& sources,
                             const std::string& options) {
    auto key = std::make_tuple(name, options, sources);
    if (auto it = programs_.find(key); it != programs_.end()) {
        return it->second;
    }
    std::string digest;
    std::filesystem::path entry;
    if (!cache_dir_.empty()) {
        std::vector<std::string> parts = {kCacheMagic,  options,        info_.name,  info_.version,
                                          info_.driver, info_.platform, info_.vendor};
        parts.insert(parts.end(), sources.begin(), sources.end());
        digest = digest_of(parts);
        entry = cache_dir_ / (digest + ".bin");
        if (std::optional<cl::Program> cached = load_program(entry, digest, options)) {
            ++cache_stats_.loaded;
            programs_.emplace(std::move(key), *cached);
            return *cached;
        }
    }
    cl::Program program = cl_call("creating program " + name, [&] {
        return cl::Program(context_, cl::Program::Sources(sources.begin(), sources.end()));
    });
    try {
        program.build({info_.device}, options.c_str());
    } catch (const cl::Error& e) {
        std::string log;
        try {
            log = program.getBuildInfo<CL_PROGRAM_BUILD_LOG>(info_.device);
        } catch (const cl::Error&) {
            log = "(no build log available)";
        }
        throw BuildError("building kernel program " + name + " with options '" + options +
                         "' failed on " + info_.name + " (" + info_.platform +
                         "): " + error_name(e.err()) + "\nbuild log:\n" + log);
    }
    ++cache_stats_.built;
    if (!entry.empty()) {
        store_program(entry, digest, name, options, program);
    }
    programs_.emplace(std::move(key), program);
    return program;
}

std::optional<cl::Program> Context::load_program(const std::filesystem::path& entry,
                                                 const std::string& digest,
                                                 const std::string& options) {
    const std::optional<std::string> text = read_entry(entry);
    if (!text) {
        return std::nullopt;  // a miss, not a rejection
    }
    // magic, "what: ..." (for people), digest, binary size, binary checksum, the binary.
    std::size_t pos = std::string(kCacheMagic).size();
    std::optional<std::string> what, stored_digest, size_text, sum_text;
    if (text->compare(0, pos, kCacheMagic) == 0) {
        what = next_line(*text, pos);
        stored_digest = next_line(*text, pos);
        size_text = next_line(*text, pos);
        sum_text = next_line(*text, pos);
    }
    const bool header_ok = sum_text && *stored_digest == digest && !size_text->empty() &&
                           size_text->size() <= 12 &&
                           size_text->find_first_not_of("0123456789") == std::string::npos;
    if (!header_ok || std::stoull(*size_text) != text->size() - pos ||
        hex(fnv1a(0xcbf29ce484222325ULL, text->data() + pos, text->size() - pos)) != *sum_text) {
        ++cache_stats_.rejected;
        return std::nullopt;
    }
    try {
        const cl::Program::Binaries binaries = {std::vector<unsigned char>(
            text->begin() + static_cast<std::ptrdiff_t>(pos), text->end())};
        std::vector<cl_int> status;
        cl::Program program(context_, {info_.device}, binaries, &status);
        if (status.size() != 1 || status[0] != CL_SUCCESS) {
            ++cache_stats_.rejected;
            return std::nullopt;
        }
        program.build({info_.device}, options.c_str());
        return program;
    } catch (const cl::Error&) {
        ++cache_stats_.rejected;
        return std::nullopt;
    }
}

void Context::store_program(const std::filesystem::path& entry, const std::string& digest,
                            const std::string& name, const std::string& options,
                            const cl::Program& program) {
    // Best effort: a cache that cannot be written (read-only home, full disk, a driver
    // without binaries) costs the next run a build, nothing more.
    try {
        const auto binaries = program.getInfo<CL_PROGRAM_BINARIES>();
        if (binaries.size() != 1 || binaries[0].empty()) {
            return;
        }
        const std::vector<unsigned char>& binary = binaries[0];
        std::string what = "what: " + name + " [" + options + "] on " + info_.name + " (" +
                           info_.platform + ", driver " + info_.driver + ")";
        std::replace(what.begin(), what.end(), '\n', ' ');
        const std::string header =
            kCacheMagic + what + "\n" + digest + "\n" + std::to_string(binary.size()) + "\n" +
            hex(fnv1a(0xcbf29ce484222325ULL, binary.data(), binary.size())) + "\n";
        std::filesystem::create_directories(entry.parent_path());
        write_output_file(
            entry, {std::span(reinterpret_cast<const std::uint8_t*>(header.data()), header.size()),
                    std::span<const std::uint8_t>(binary.data(), binary.size())});
        ++cache_stats_.stored;
    } catch (const std::exception&) {
    }
}

namespace {

// The event's profiling time `what`, or nullopt when its queue does not profile
// (Context::Unprofiled); other errors throw.
std::optional<cl_ulong> profiling_time(const cl::Event& e, cl_profiling_info what) {
    cl_ulong t = 0;
    const cl_int err = clGetEventProfilingInfo(e(), what, sizeof t, &t, nullptr);
    if (err == CL_PROFILING_INFO_NOT_AVAILABLE) {
        return std::nullopt;
    }
    if (err != CL_SUCCESS) {
        throw ClError("clGetEventProfilingInfo", err, "reading profiling info");
    }
    return t;
}

}  // namespace

double elapsed_ms(const cl::Event& first, const cl::Event& last) {
    const auto start = profiling_time(first, CL_PROFILING_COMMAND_START);
    const auto end = profiling_time(last, CL_PROFILING_COMMAND_END);
    return start && end ? static_cast<double>(*end - *start) * 1e-6 : 0.0;
}

CommandSpan command_span(const std::vector<cl::Event>& commands) {
    std::vector<std::pair<cl_ulong, cl_ulong>> runs;
    for (const cl::Event& e : commands) {
        if (e() != nullptr) {
            const auto start = profiling_time(e, CL_PROFILING_COMMAND_START);
            const auto end = profiling_time(e, CL_PROFILING_COMMAND_END);
            if (!start || !end) {
                return CommandSpan{};
            }
            runs.emplace_back(*start, *end);
        }
    }
    return command_span(std::move(runs));
}

CommandSpan command_span(std::vector<std::pair<cl_ulong, cl_ulong>> runs) {
    CommandSpan s;
    if (runs.empty()) {
        return s;
    }
    std::sort(runs.begin(), runs.end());
    // covered: the latest end so far (every run before it is counted in busy).
    cl_ulong busy = 0, covered = runs.front().first;
    for (const auto& [start, end] : runs) {
        covered = std::max(covered, start);
        if (end > covered) {
            busy += end - covered;
            covered = end;
        }
    }
    s.span_ms = static_cast<double>(covered - runs.front().first) * 1e-6;
    s.idle_ms = s.span_ms - static_cast<double>(busy) * 1e-6;
    return s;
}

namespace {

constexpr std::size_t kHugePage = std::size_t{2} << 20;

// HostMemory's freed blocks of 2 MiB multiples, the least recently freed first.
class HostCache {
  public:
    static constexpr std::size_t kLimit = std::size_t{1} << 30;

    // A cached block of exactly `capacity` bytes (null without one); without one the cache
    // is emptied.
    void* take(std::size_t capacity) {
        std::vector<std::pair<void*, std::size_t>> dropped;
        {
            const std::lock_guard<std::mutex> lock(mutex_);
            for (auto it = blocks_.rbegin(); it != blocks_.rend(); ++it) {
                if (it->second == capacity) {
                    void* p = it->first;
                    total_ -= capacity;
                    blocks_.erase(std::next(it).base());
                    return p;
                }
            }
            dropped.swap(blocks_);
            total_ = 0;
        }
        for (const auto& block : dropped) {
            std::free(block.first);
        }
        return nullptr;
    }

    // Keeps the block (freeing the oldest beyond kLimit).
    void give(void* p, std::size_t capacity) {
        std::vector<void*> dropped;
        {
            const std::lock_guard<std::mutex> lock(mutex_);
            blocks_.emplace_back(p, capacity);
            total_ += capacity;
            while (total_ > kLimit) {
                dropped.push_back(blocks_.front().first);
                total_ -= blocks_.front().second;
                blocks_.erase(blocks_.begin());
            }
        }
        for (void* q : dropped) {
            std::free(q);
        }
    }

  private:
    std::mutex mutex_;
    std::vector<std::pair<void*, std::size_t>> blocks_;
    std::size_t total_ = 0;
};

// Never destroyed: host memory may be freed during static destruction (numpy arrays of the
// Python module at interpreter exit).
HostCache& host_cache() {
    static HostCache* cache = new HostCache();
    return *cache;
}

}  // namespace

HostMemory::HostMemory(std::size_t bytes) : size_(bytes) {
    const bool huge = bytes >= kHugePage;
    const std::size_t capacity = huge ? (bytes + kHugePage - 1) / kHugePage * kHugePage : bytes;
    void* p = huge ? host_cache().take(capacity) : nullptr;
    if (p == nullptr) {
        if (posix_memalign(&p, huge ? kHugePage : 4096, std::max<std::size_t>(capacity, 1)) != 0) {
            throw std::bad_alloc();
        }
        if (huge) {
            // Advice only: where transparent huge pages are off the memory works in small
            // pages.
            ::madvise(p, capacity, MADV_HUGEPAGE);
        }
    }
    data_ = std::unique_ptr<std::uint8_t, Free>(static_cast<std::uint8_t*>(p), Free{capacity});
}

void HostMemory::Free::operator()(std::uint8_t* p) const {
    if (capacity >= kHugePage) {
        host_cache().give(p, capacity);
    } else {
        std::free(p);
    }
}

MappedBuffer::MappedBuffer(Context& ctx, const cl::Buffer& buffer, std::size_t bytes)
    : queue_(ctx.queue()), buffer_(buffer), size_(bytes) {
    cl_call("mapping " + std::to_string(bytes) + " bytes for reading on the host", [&] {
        cl::Event ev;
        data_ = static_cast<const std::uint8_t*>(
            queue_.enqueueMapBuffer(buffer_, CL_TRUE, CL_MAP_READ, 0, bytes, nullptr, &ev));
        map_ms_ = elapsed_ms(ev, ev);
    });
}

MappedBuffer::~MappedBuffer() {
    // A failing unmap has no one left to report to; the buffer is released either way.
    try {
        queue_.enqueueUnmapMemObject(buffer_, const_cast<std::uint8_t*>(data_));
        queue_.finish();
    } catch (const cl::Error&) {
    }
}

double read_streamed(Context& ctx, const cl::Buffer& buffer, std::size_t bytes,
                     const std::function<void(std::span<const std::uint8_t>)>& sink,
                     std::size_t piece, bool staged) {
    if (bytes == 0) {
        return 0;
    }
    if (piece == 0) {
        throw std::invalid_argument("read_streamed: pieces of 0 bytes");
    }
    if (ctx.computes_in_host_memory() && !staged) {
        const MappedBuffer mapped(ctx, buffer, bytes);
        sink(mapped.bytes());
        return mapped.map_ms();
    }
    piece = std::min(piece, bytes);
    cl::CommandQueue queue = ctx.queue();
    std::array<cl::Buffer, 2> staging;
    std::array<std::uint8_t*, 2> host{};
    cl_call("pinned staging of 2 x " + std::to_string(piece) + " bytes", [&] {
        for (std::size_t i = 0; i < 2; ++i) {
            staging[i] = cl::Buffer(ctx.context(), CL_MEM_ALLOC_HOST_PTR, piece);
            host[i] = static_cast<std::uint8_t*>(
                queue.enqueueMapBuffer(staging[i], CL_TRUE, CL_MAP_READ | CL_MAP_WRITE, 0, piece));
        }
    });
    const std::size_t pieces = (bytes + piece - 1) / piece;
    std::array<cl::Event, 2> done;
    double ms = 0;
    auto enqueue = [&](std::size_t k) {
        const std::size_t offset = k * piece, n = std::min(piece, bytes - offset);
        cl_call("downloading bytes " + std::to_string(offset) + ".." + std::to_string(offset + n),
                [&] {
                    queue.enqueueReadBuffer(buffer, CL_FALSE, offset, n, host[k % 2], nullptr,
                                            &done[k % 2]);
                });
    };
    enqueue(0);
    for (std::size_t k = 0; k < pieces; ++k) {
        cl_call("waiting for a download", [&] { done[k % 2].wait(); });
        ms += elapsed_ms(done[k % 2], done[k % 2]);
        if (k + 1 < pieces) {
            enqueue(k + 1);
        }
        sink({host[k % 2], std::min(piece, bytes - k * piece)});
    }
    cl_call("unmapping the staging", [&] {
        for (std::size_t i = 0; i < 2; ++i) {
            queue.enqueueUnmapMemObject(staging[i], host[i]);
        }
        queue.finish();
    });
    return ms;
}

}  // namespace voxfield::ocl
