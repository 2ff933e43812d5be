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
#include "voxfield/core/scene_file.hpp"
#include "voxfield/core/sdf.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/core/vdb.hpp"
#include "voxfield/core/vox.hpp"
#include "voxfield/core/world_info.hpp"

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

VoxModel load_npy(const std::filesystem::path& path, const InputOptions& options) {
    // A uint8 array is the world's own bytes: read straight into the world, without the
    // array's copy (at 512^3 two passes and 128 MiB of page faults fewer).
    const NpyReader reader(path);
    if (reader.type() == NpyType::u8) {
        World world(reader.dims());
        reader.read_data(world.voxels());
        return VoxModel{std::move(world), Palette()};
    }
    std::vector<std::uint8_t> data(reader.data_bytes());
    reader.read_data(data);
    try {
        return VoxModel{world_from_labels(reader.type(), reader.dims(), data,
                                          options.palette_values ? Labels::palette : Labels::solid),
                        Palette()};
    } catch (const InputError& e) {
        throw InputError(path.string() + ": " + e.what());
    }
}

WorldInfo describe_vox(const std::filesystem::path& path, const InputOptions&, double bound) {
    const VoxScene scene = read_vox_scene(path);
    TileCensus census(scene.dims);
    scene.place([&](std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint8_t) {
        census.add(x, y, z);
    });
    WorldInfo info;
    info.kind = "vox";
    census.finish(info, bound);
    info.scene_graph = scene.has_scene_graph;
    info.models = scene.models.size();
    info.instances = scene.instances.size();
    info.hidden_instances = scene.hidden_instances;
    return info;
}

VoxModel load_sdf(const std::filesystem::path& path, const InputOptions&) {
    return VoxModel{sdf::solid_world(sdf::load_part(path), path.string()), Palette()};
}

VoxModel load_scene_world(const std::filesystem::path& path, const InputOptions&) {
    const scene::Scene s = scene::load_scene(path);
    return VoxModel{s.world(path.string()), s.palette};
}

SparseModel sparse_vox(const std::filesystem::path& path, const InputOptions&) {
    const VoxScene scene = read_vox_scene(path);
    return SparseModel{
        SparseWorld::from_voxels(scene.dims, [&](const VoxelSink& sink) { scene.place(sink); }),
        scene.palette};
}

// Inputs read dense first: the dense world, tiled.
template <VoxModel (*Load)(const std::filesystem::path&, const InputOptions&)>
SparseModel sparse_from_dense(const std::filesystem::path& path, const InputOptions& options) {
    const VoxModel model = Load(path, options);
    return SparseModel{SparseWorld::from_dense(model.world), model.palette};
}

// The description of a loaded world of kind `kind`, counted voxel by voxel.
WorldInfo describe_world(const World& world, const char* kind, double bound) {
    TileCensus census(world.dims());
    census.add_world(world);
    WorldInfo info;
    info.kind = kind;
    census.finish(info, bound);
    return info;
}

WorldInfo describe_sdf(const std::filesystem::path& path, const InputOptions& options,
                       double bound) {
    return describe_world(load_sdf(path, options).world, "sdf", bound);
}

WorldInfo describe_scene(const std::filesystem::path& path, const InputOptions& options,
                         double bound) {
    return describe_world(load_scene_world(path, options).world, "scene", bound);
}

WorldInfo describe_npy(const std::filesystem::path& path, const InputOptions& options,
                       double bound) {
    return describe_world(load_npy(path, options).world, "npy", bound);
}

VoxModel load_vdb(const std::filesystem::path& path, const InputOptions& options) {
    return read_vdb(path, options.grid);
}

WorldInfo describe_vdb_file(const std::filesystem::path& path, const InputOptions& options,
                            double bound) {
    return describe_vdb(path, options.grid, bound);
}

SparseModel sparse_vdb(const std::filesystem::path& path, const InputOptions& options) {
    return SparseModel{read_vdb_sparse(path, options.grid), Palette()};
}

// The input formats, by lower-case extension: how to load one (dense or sparse) and how to
// describe one.
struct InputFormat {
    std::string_view extension;
    VoxModel (*load)(const std::filesystem::path&, const InputOptions&);
    SparseModel (*load_sparse)(const std::filesystem::path&, const InputOptions&);
    WorldInfo (*describe)(const std::filesystem::path&, const InputOptions&, double);
};
constexpr InputFormat kInputFormats[] = {
    {".vox", load_vox, sparse_vox, describe_vox},
    {".npy", load_npy, sparse_from_dense<load_npy>, describe_npy},
    {".vdb", load_vdb, sparse_vdb, describe_vdb_file},
};

const InputFormat& input_format(const std::filesystem::path& path) {
    // `.sdf.json` is named by two suffixes, so it is matched by name before the table.
    static constexpr InputFormat sdf_format{".sdf.json", load_sdf, sparse_from_dense<load_sdf>,
                                            describe_sdf};
    static constexpr InputFormat scene_format{".scene.json", load_scene_world,
                                              sparse_from_dense<load_scene_world>, describe_scene};
    if (sdf::is_sdf_path(path)) {
        return sdf_format;
    }
    if (scene::is_scene_path(path)) {
        return scene_format;
    }
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    std::string accepted;
    for (const InputFormat& f : kInputFormats) {
        if (ext == f.extension) {
            return f;
        }
        accepted += (accepted.empty() ? "" : ", ") + std::string(f.extension);
    }
    throw InputError("'" + path.string() + "': unsupported file type " +
                     (ext.empty() ? std::string("(no extension)") : "'" + ext + "'") +
                     " (expected one of " + accepted + ", .sdf.json, .scene.json)");
}

}  // namespace

VoxModel load_world(const std::filesystem::path& path, const InputOptions& options) {
    return input_format(path).load(path, options);
}

SparseModel load_sparse_world(const std::filesystem::path& path, const InputOptions& options) {
    return input_format(path).load_sparse(path, options);
}

WorldInfo describe_input(const std::filesystem::path& path, const InputOptions& options,
                         double max_distance) {
    return input_format(path).describe(path, options, max_distance);
}

}  // namespace voxfield
