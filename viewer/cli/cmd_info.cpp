// `voxfield info INPUT [--json]`: a world's size, solid voxels, 64^3 tiles, models and
// instances of a .vox scene, and the memory a dense and a sparse field of it would take.
#include <cmath>
#include <cstdint>
#include <iostream>
#include <memory>
#include <string>

#include "cli_util.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/world_info.hpp"

namespace voxfield::cli {

namespace {

struct InfoOptions {
    std::string input, grid, format = "u16";
    double max_distance = 16;
    bool json = false;
};

// "123 B", "4.5 KiB", "1.25 GiB".
std::string bytes_text(std::uint64_t b) {
    const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB", "PiB"};
    double v = static_cast<double>(b);
    int u = 0;
    while (v >= 1024 && u < 5) {
        v /= 1024;
        ++u;
    }
    return u == 0 ? std::to_string(b) + " B" : fixed(v, 2) + " " + units[u];
}

int run_info(const InfoOptions& o) {
    if (!(o.max_distance > 0) || !std::isfinite(o.max_distance)) {
        throw InputError("--max-distance " + fixed(o.max_distance, 3) +
                         " must be a positive finite number");
    }
    const Format format = parse_format(o.format);
    InputOptions in;
    in.grid = o.grid;
    const WorldInfo info = describe_input(o.input, in, o.max_distance);
    const std::uint64_t voxels = info.dims.count();
    const std::uint64_t tiles =
        std::uint64_t{info.tile_grid.x} * info.tile_grid.y * info.tile_grid.z;
    const std::uint64_t dense = dense_field_bytes(info, format);
    const std::uint64_t sparse = sparse_field_bytes(info, format);
    if (o.json) {
        nlohmann::json j;
        j["input"] = o.input;
        j["kind"] = info.kind;
        j["dims"] = {info.dims.x, info.dims.y, info.dims.z};
        j["voxels"] = voxels;
        j["solid_voxels"] = info.solid;
        j["tiles"] = {{"size", kTileSize},
                      {"grid", {info.tile_grid.x, info.tile_grid.y, info.tile_grid.z}},
                      {"total", tiles},
                      {"solid", info.solid_tiles},
                      {"stored", info.stored_tiles},
                      {"blocks16", info.blocks16},
                      {"blocks4", info.blocks4}};
        if (info.kind == "vox") {
            j["scene_graph"] = info.scene_graph;
            j["models"] = info.models;
            j["instances"] = info.instances;
            j["hidden_instances"] = info.hidden_instances;
        }
        if (!info.grid.empty()) {
            j["grid"] = info.grid;
            j["grid_class"] = info.grid_class;
        }
        j["memory"] = {{"format", to_string(format)},
                       {"max_distance", o.max_distance},
                       {"dense_bytes", dense},
                       {"sparse_bytes", sparse}};
        std::cout << j.dump(2) << '\n';
        return 0;
    }
    std::cout << "input: " << o.input << " (" << info.kind;
    if (info.kind == "vox") {
        std::cout << ", " << info.models << " model(s), "
                  << (info.scene_graph ? "scene graph: " + std::to_string(info.instances) +
                                             " visible instance(s), " +
                                             std::to_string(info.hidden_instances) + " hidden"
                                       : std::string("no scene graph: the first model"));
    }
    if (!info.grid.empty()) {
        std::cout << ", grid '" << info.grid << "' (" << info.grid_class << ")";
    }
    std::cout << ")\n";
    std::cout << "dims: " << info.dims.to_string() << " (" << voxels << " voxels)\n";
    std::cout << "solid voxels: " << info.solid << " ("
              << fixed(voxels
                           ? 100.0 * static_cast<double>(info.solid) / static_cast<double>(voxels)
                           : 0.0,
                       3)
              << "%)\n";
    std::cout << "tiles of " << kTileSize << "^3: " << info.solid_tiles << " of " << tiles
              << " hold a solid voxel; " << info.stored_tiles << " stored with --max-distance "
              << fixed(o.max_distance, 2) << "\n";
    std::cout << "memory (" << to_string(format) << " field): dense " << bytes_text(dense)
              << " (1 + " << element_size(format) << " bytes per voxel), sparse "
              << bytes_text(sparse) << " (" << info.stored_tiles << " tiles, 64-tree "
              << info.solid_tiles + info.blocks16 + info.blocks4 << " nodes)\n";
    return 0;
}

}  // namespace

Command add_info(CLI::App& root) {
    auto o = std::make_shared<InfoOptions>();
    auto* app = root.add_subcommand(
        "info",
        "Describe a world: dims, solid voxels, 64^3 tiles holding a solid voxel, models and "
        "instances of a .vox scene, and the memory a dense and a sparse field would take");
    app->add_option("INPUT", o->input, kWorldInputHelp)->required();
    app->add_flag("--json", o->json, "Print the description as JSON");
    app->add_option("--grid", o->grid, ".vdb input: the grid to read (default: the first grid)");
    app->add_option("--format", o->format,
                    "Field format the memory estimates are for (u8, u16, u32, packed32, i8, i16, "
                    "i32, f32, f64)")
        ->capture_default_str();
    app->add_option("--max-distance", o->max_distance,
                    "Bound of the sparse field: tiles within it of a solid voxel are stored")
        ->capture_default_str();
    return {app, [o] { return run_info(*o); }};
}

}  // namespace voxfield::cli
