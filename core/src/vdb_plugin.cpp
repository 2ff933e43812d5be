// OpenVDB .vdb input and output (Museth, "VDB: High-resolution sparse volumes with dynamic
// topology", ACM TOG 2013), read and written with Debian's libopenvdb: the plugin
// libvoxfield_vdb.so (vdb_plugin.hpp), loaded by vdb.cpp on first use.
#include "vdb_plugin.hpp"

#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetUtil.h>
#include <openvdb/tools/Prune.h>

#include "input_file.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <ios>
#include <mutex>
#include <new>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "voxfield/core/error.hpp"

namespace voxfield {

namespace {

void init_openvdb() {
    static std::once_flag once;
    std::call_once(once, [] { openvdb::initialize(); });
}

// OpenVDB's messages on one line.
std::string one_line(std::string s) {
    std::replace(s.begin(), s.end(), '\n', ' ');
    return s;
}

struct OpenGrid {
    openvdb::GridBase::Ptr grid;
    std::string name;
};

// Opens the file and reads the chosen grid; every OpenVDB failure is an InputError.
OpenGrid read_grid(const std::filesystem::path& path, const std::string& wanted) {
    {
        std::uint64_t size = 0;
        detail::open_input(path, size);  // the project's messages for missing/unreadable paths
    }
    init_openvdb();
    const std::string file_name = path.string();
    try {
        openvdb::io::File file(file_name);
        file.open(false);
        // In file order (the name iterator would sort them).
        std::vector<std::string> names;
        const openvdb::GridPtrVecPtr metadata = file.readAllGridMetadata();
        for (const auto& meta : *metadata) {
            names.push_back(meta->getName());
        }
        if (names.empty()) {
            throw InputError(file_name + ": the OpenVDB file holds no grid");
        }
        std::string chosen = names.front();
        if (!wanted.empty()) {
            if (std::find(names.begin(), names.end(), wanted) == names.end()) {
                std::string list;
                for (const auto& n : names) {
                    list += (list.empty() ? "'" : ", '") + n + "'";
                }
                throw InputError(file_name + ": no grid named '" + wanted + "' (grids: " + list +
                                 ")");
            }
            chosen = wanted;
        }
        OpenGrid g{file.readGrid(chosen), chosen};
        file.close();
        return g;
    } catch (const openvdb::Exception& e) {
        throw InputError(file_name + ": not a readable OpenVDB file (" + one_line(e.what()) + ")");
    } catch (const std::ios_base::failure& e) {
        throw InputError(file_name + ": not a readable OpenVDB file (" + one_line(e.what()) + ")");
    } catch (const std::length_error&) {
        throw InputError(file_name + ": not a readable OpenVDB file (corrupt sizes)");
    } catch (const std::bad_alloc&) {
        // A corrupt size field asks for more memory than there is.
        throw InputError(file_name +
                         ": not a readable OpenVDB file (corrupt, or a grid larger than memory)");
    }
}

// The grids whose values voxfield reads: numbers, booleans and vectors.
using ReadableGrids = openvdb::TypeList<openvdb::FloatGrid, openvdb::DoubleGrid, openvdb::Int32Grid,
                                        openvdb::Int64Grid, openvdb::BoolGrid, openvdb::Vec3SGrid,
                                        openvdb::Vec3DGrid, openvdb::Vec3IGrid>;

// Calls start(dims) once, then f(x, y, z, material) for every solid voxel of the grid, in world
// coordinates (origin at the active bounding box's minimum corner).
// The grid's active bounding box; InputError when it is empty or over kVoxMaxSceneAxis.
openvdb::CoordBBox solid_box(const OpenGrid& g, const std::string& file) {
    const std::string where = file + ": grid '" + g.name + "'";
    const openvdb::CoordBBox box = g.grid->evalActiveVoxelBoundingBox();
    if (box.empty()) {
        throw InputError(where + " has no active voxels");
    }
    // In 64 bits: CoordBBox::dim() wraps around in Int32 for voxels 2^31 or more apart.
    std::int64_t n[3];
    for (int a = 0; a < 3; ++a) {
        n[a] = std::int64_t{box.max()[a]} - box.min()[a] + 1;
    }
    if (std::max({n[0], n[1], n[2]}) > std::int64_t{kVoxMaxSceneAxis}) {
        throw InputError(where + " spans " + std::to_string(n[0]) + "x" + std::to_string(n[1]) +
                         "x" + std::to_string(n[2]) + " voxels, over the limit of " +
                         std::to_string(kVoxMaxSceneAxis) + " per axis");
    }
    return box;
}

Dims dims_of(const openvdb::CoordBBox& box) {
    const openvdb::Coord n = box.dim();
    return Dims{static_cast<std::uint32_t>(n[0]), static_cast<std::uint32_t>(n[1]),
                static_cast<std::uint32_t>(n[2])};
}

template <typename S, typename F>
void walk_solid(const OpenGrid& g, const std::string& file, S&& start, F&& f) {
    const openvdb::GridBase& grid = *g.grid;
    const std::string where = file + ": grid '" + g.name + "'";
    const openvdb::CoordBBox box = solid_box(g, file);
    start(dims_of(box));
    const openvdb::Coord lo = box.min();
    auto emit = [&](const openvdb::CoordBBox& b, std::uint8_t material) {
        const openvdb::CoordBBox c(openvdb::Coord::maxComponent(b.min(), box.min()),
                                   openvdb::Coord::minComponent(b.max(), box.max()));
        for (auto k = c.min().z(); k <= c.max().z(); ++k) {
            for (auto j = c.min().y(); j <= c.max().y(); ++j) {
                for (auto i = c.min().x(); i <= c.max().x(); ++i) {
                    f(static_cast<std::uint32_t>(i - lo.x()),
                      static_cast<std::uint32_t>(j - lo.y()),
                      static_cast<std::uint32_t>(k - lo.z()), material);
                }
            }
        }
    };
    if (grid.getGridClass() == openvdb::GRID_LEVEL_SET) {
        auto interior = [&](const auto& typed) {
            const auto mask = openvdb::tools::sdfInteriorMask(typed);
            for (auto it = mask->cbeginValueOn(); it; ++it) {
                if (*it) {
                    emit(it.getBoundingBox(), 1);
                }
            }
        };
        if (const auto fg = openvdb::GridBase::constGrid<openvdb::FloatGrid>(g.grid)) {
            interior(*fg);
            return;
        }
        if (const auto dg = openvdb::GridBase::constGrid<openvdb::DoubleGrid>(g.grid)) {
            interior(*dg);
            return;
        }
        throw InputError(where + " is a level set of type " + grid.valueType() +
                         " (expected float or double)");
    }
    const bool known = grid.apply<ReadableGrids>([&](const auto& typed) {
        using Value = typename std::decay_t<decltype(typed)>::ValueType;
        const Value zero = openvdb::zeroVal<Value>();
        for (auto it = typed.cbeginValueOn(); it; ++it) {
            const Value v = *it;
            if (v == zero) {
                continue;
            }
            // As label volumes: 1..255 is the palette index, any other nonzero value 1.
            std::uint8_t material = 1;
            if constexpr (std::is_integral_v<Value> && !std::is_same_v<Value, bool>) {
                if (v > 0 && v <= 255) {
                    material = static_cast<std::uint8_t>(v);
                }
            }
            emit(it.getBoundingBox(), material);
        }
    });
    if (!known) {
        throw InputError(where + " holds values of type " + grid.valueType() +
                         ", which are not voxels (expected a number, bool or vector grid)");
    }
}

VoxModel read_world(const std::filesystem::path& path, const std::string& grid) {
    const OpenGrid g = read_grid(path, grid);
    std::optional<World> world;
    walk_solid(
        g, path.string(),
        [&](Dims dims) {
            if (dims.count() > (std::size_t{1} << 31)) {
                throw InputError(path.string() + ": grid '" + g.name + "' spans " +
                                 dims.to_string() + " (" + std::to_string(dims.count()) +
                                 " voxels), more than a dense world holds (2^31 voxels)");
            }
            world.emplace(dims);
        },
        [&](std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint8_t m) {
            world->set(x, y, z, m);
        });
    return VoxModel{std::move(*world), Palette()};
}

SparseWorld read_sparse_world(const std::filesystem::path& path, const std::string& grid) {
    const OpenGrid g = read_grid(path, grid);
    return SparseWorld::from_voxels(dims_of(solid_box(g, path.string())),
                                    [&](const VoxelSink& sink) {
                                        walk_solid(
                                            g, path.string(), [](Dims) {}, sink);
                                    });
}

Dims extent(const std::filesystem::path& path, const std::string& grid) {
    return dims_of(solid_box(read_grid(path, grid), path.string()));
}

WorldInfo describe(const std::filesystem::path& path, const std::string& grid,
                   double max_distance) {
    const OpenGrid g = read_grid(path, grid);
    std::optional<TileCensus> census;
    walk_solid(
        g, path.string(), [&](Dims dims) { census.emplace(dims); },
        [&](std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint8_t) {
            census->add(x, y, z);
        });
    WorldInfo info;
    info.kind = "vdb";
    census->finish(info, max_distance);
    info.grid = g.name;
    info.grid_class = openvdb::GridBase::gridClassToString(g.grid->getGridClass());
    return info;
}

// The .vdb file's bytes, from boxes of the world and its field: OpenVDB's io::Stream keeps
// the grids in the order given.
std::string vdb_bytes(const std::function<bool(VdbBox&)>& next, Format format,
                      const VdbFieldSpec& spec) {
    init_openvdb();
    const auto d = static_cast<float>(spec.background);
    const auto transform = openvdb::math::Transform::createLinearTransform(spec.voxel_size);
    auto material = openvdb::Int32Grid::create(0);
    material->setName("material");
    material->setTransform(transform);
    auto distance = openvdb::FloatGrid::create(d);
    distance->setName("distance");
    distance->setTransform(transform->copy());
    distance->setGridClass(spec.level_set ? openvdb::GRID_LEVEL_SET : openvdb::GRID_UNKNOWN);
    auto mat = material->getAccessor();
    auto dist = distance->getAccessor();
    const std::size_t es = element_size(format);
    std::vector<std::uint8_t> row;  // decode_value reads vectors
    VdbBox b;
    while (next(b)) {
        const auto nx = static_cast<std::size_t>(b.box.max.x - b.box.min.x);
        row.resize(nx * es);
        std::size_t base = 0;
        for (std::int64_t z = b.box.min.z; z < b.box.max.z; ++z) {
            for (std::int64_t y = b.box.min.y; y < b.box.max.y; ++y, base += nx) {
                std::copy_n(b.field.begin() + static_cast<std::ptrdiff_t>(base * es), row.size(),
                            row.begin());
                for (std::size_t i = 0; i < nx; ++i) {
                    const openvdb::Coord ijk(
                        static_cast<openvdb::Int32>(b.box.min.x) + static_cast<openvdb::Int32>(i),
                        static_cast<openvdb::Int32>(y), static_cast<openvdb::Int32>(z));
                    const std::uint8_t m = b.voxels[base + i];
                    if (m != 0) {
                        mat.setValue(ijk, m);
                    }
                    const double v = decode_value(row, format, i);
                    if (std::fabs(v) < spec.background) {
                        dist.setValue(ijk, static_cast<float>(v));
                    } else if (v < 0) {
                        dist.setValueOff(ijk, -d);
                    }
                }
            }
        }
    }
    openvdb::tools::prune(distance->tree());
    openvdb::GridPtrVec grids{material, distance};
    std::ostringstream out(std::ios::binary);
    openvdb::io::Stream(out).write(grids);
    return out.str();
}

const detail::VdbPlugin plugin{
    {VOXFIELD_PLUGIN_BUILD_ID}, read_world, read_sparse_world, extent, describe, vdb_bytes};

}  // namespace
}  // namespace voxfield

const voxfield::PluginHeader* voxfield_vdb_plugin() {
    return &voxfield::plugin.header;
}
