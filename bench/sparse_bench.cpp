// Sparse worlds at scale (issue 24): builds a seeded terrain-and-blocks world tile by tile from
// a box-filling callback (no dense array), computes its whole exact bounded field per tile
// (cl/sparse_field.hpp) and times radius-8 sphere edits applied on the device
// (SparseField::apply_brush), recording peak memory; with --peer,
// OpenVDB's fast sweeping on the same world in the same run (openvdb_peer.hpp). Writes JSON
// with device, date and commit.
//   sparse_bench [--size X,Y,Z] [--max-distance D] [--metric M] [--format F] [--device D]
//                [--edits N] [--seed S] [--peer] [--commit C] [--json FILE]
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <fstream>
#include <iostream>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "openvdb_peer.hpp"
#include "process_memory.hpp"
#include "voxfield/cl/sparse_field.hpp"
#include "voxfield/core/clock.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/metric.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/core/stats.hpp"

namespace {

using namespace voxfield;
using bench::peak_rss_bytes;

// Rolling terrain (a sum of seeded sine waves, 12..~100 voxels high: grass on dirt on stone)
// with blocks of buildings (solid boxes up to ~160 voxels) on a 96-voxel street grid.
struct Terrain {
    std::uint32_t height_max;
    double phase[6], freq[6];
    std::uint64_t seed;

    explicit Terrain(std::uint64_t s, std::uint32_t ymax) : height_max(ymax), seed(s) {
        std::mt19937_64 rng(s);
        std::uniform_real_distribution<double> p(0, 6.283185307), f(0.002, 0.02);
        for (int i = 0; i < 6; ++i) {
            phase[i] = p(rng);
            freq[i] = f(rng);
        }
    }
    std::uint32_t ground(std::int64_t x, std::int64_t z) const {
        double h = 40;
        for (int i = 0; i < 3; ++i) {
            h += (14.0 / (i + 1)) * std::sin(freq[2 * i] * static_cast<double>(x) + phase[2 * i]) *
                 std::cos(freq[2 * i + 1] * static_cast<double>(z) + phase[2 * i + 1]);
        }
        return static_cast<std::uint32_t>(std::clamp(h, 12.0, static_cast<double>(height_max)));
    }
    // Height of the building whose lot holds (x, z), 0 for streets and empty lots.
    std::uint32_t building(std::int64_t x, std::int64_t z) const {
        const std::int64_t lx = x % 96, lz = z % 96;
        if (lx < 16 || lz < 16 || lx >= 88 || lz >= 88) {
            return 0;
        }
        std::uint64_t h = static_cast<std::uint64_t>(x / 96) * 0x9E3779B97F4A7C15ULL ^
                          static_cast<std::uint64_t>(z / 96) * 0xC2B2AE3D27D4EB4FULL ^ seed;
        h ^= h >> 29;
        h *= 0xBF58476D1CE4E5B9ULL;
        h ^= h >> 32;
        if (h % 3 == 0) {
            return 0;
        }
        return static_cast<std::uint32_t>(std::min<std::uint64_t>(20 + h % 140, height_max));
    }
};

}  // namespace

int main(int argc, char** argv) {
    try {
        Dims dims{4096, 512, 4096};
        double bound = 8;
        std::string format_name = "u8", metric_name = "manhattan", device, json_path,
                    commit = "unknown";
        bool peer = false;
        int edits = 30;
        std::uint64_t seed = 1;
        for (int i = 1; i < argc; ++i) {
            const std::string a = argv[i];
            auto next = [&]() -> std::string {
                if (i + 1 >= argc) {
                    throw InputError(a + " needs a value");
                }
                return argv[++i];
            };
            if (a == "--size") {
                dims = parse_dims(next());
            } else if (a == "--max-distance") {
                bound = std::stod(next());
            } else if (a == "--metric") {
                metric_name = next();
            } else if (a == "--peer") {
                peer = true;
            } else if (a == "--format") {
                format_name = next();
            } else if (a == "--device") {
                device = next();
            } else if (a == "--edits") {
                edits = std::stoi(next());
            } else if (a == "--seed") {
                seed = std::stoull(next());
            } else if (a == "--commit") {
                commit = next();
            } else if (a == "--json") {
                json_path = next();
            } else {
                throw InputError("unknown option " + a);
            }
        }
        if (peer && (metric_name != "euclidean" || format_name != "f32")) {
            throw InputError(
                "--peer compares with the exact Euclidean field: give --metric "
                "euclidean --format f32");
        }
        const Terrain terrain(seed, dims.y);
        const auto t_build = Clock::now();
        SparseWorld world =
            SparseWorld::from_fill(dims, [&](const Box& b, std::span<std::uint8_t> out) {
                const auto nx = static_cast<std::size_t>(b.max.x - b.min.x);
                // Per call (from_fill calls this from several threads at once).
                std::vector<std::uint32_t> heights(nx *
                                                   static_cast<std::size_t>(b.max.z - b.min.z) * 2);
                std::uint32_t top = 0;
                for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
                    for (std::int64_t x = b.min.x; x < b.max.x; ++x) {
                        const std::size_t c = static_cast<std::size_t>(z - b.min.z) * nx +
                                              static_cast<std::size_t>(x - b.min.x);
                        heights[2 * c] = terrain.ground(x, z);
                        heights[2 * c + 1] = heights[2 * c] + terrain.building(x, z);
                        top = std::max(top, heights[2 * c + 1]);
                    }
                }
                if (b.min.y >= top) {
                    std::fill(out.begin(), out.end(), std::uint8_t{0});
                    return;
                }
                std::size_t i = 0;
                for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
                    for (std::int64_t y = b.min.y; y < b.max.y; ++y) {
                        for (std::size_t x = 0; x < nx; ++x, ++i) {
                            const std::size_t c = static_cast<std::size_t>(z - b.min.z) * nx + x;
                            const auto g = static_cast<std::int64_t>(heights[2 * c]);
                            const auto h = static_cast<std::int64_t>(heights[2 * c + 1]);
                            out[i] = y < g - 4 ? 3 : y < g - 1 ? 2 : y < g ? 1 : y < h ? 4 : 0;
                        }
                    }
                }
            });
        const double build_ms = ms_since(t_build);
        const double rss_after_build = peak_rss_bytes();
        std::cerr << "built " << dims.to_string() << ": " << world.tile_count() << " tiles, "
                  << world.solid_count() << " solid voxels, " << world.bytes() << " bytes in "
                  << build_ms << " ms\n";

        ocl::Context ctx(ocl::select_device(device));
        ocl::GeneratorOptions o;
        o.format = parse_format(format_name);
        o.metric = parse_metric(metric_name);
        o.max_distance = bound;
        o = ocl::resolve_sparse_options(o, true);
        const Palette palette = Palette::magicavoxel_default();
        const auto t_upload = Clock::now();
        ocl::SparseField field(ctx, world, palette, o);  // uploads the world's 64-trees
        const double upload_ms = ms_since(t_upload);
        const auto t_field = Clock::now();
        const double field_kernel_ms = field.run();
        const double field_wall_ms = ms_since(t_field);
        std::cerr << "field: " << field.dense_tiles() << " field tiles, kernels " << field_kernel_ms
                  << " ms, wall " << field_wall_ms << " ms\n";

        nlohmann::json peer_json;
        if (peer) {
            std::vector<bench::ExactTile> exact;
            for (const std::uint32_t t : bench::peer_sample_tiles(world, 64)) {
                const std::vector<std::uint8_t> bytes = field.read_box(world.tile_box(t));
                bench::ExactTile& e = exact.emplace_back();
                e.tile = t;
                e.values.resize(bytes.size() / sizeof(float));
                std::memcpy(e.values.data(), bytes.data(), e.values.size() * sizeof(float));
            }
            const bench::OpenVdbPeer p = bench::run_openvdb_peer(world, bound, exact);
            std::cerr << "OpenVDB fogToSdf: band " << p.band_voxels << " voxels, topology "
                      << p.topology_ms << " ms, sweep " << p.sweep_ms << " ms; error vs exact "
                      << "(" << p.compared << " voxels) mean " << p.mean_abs_error << ", max "
                      << p.max_abs_error << "\n";
            peer_json = {{"name", "OpenVDB tools::fogToSdf (fast sweeping, 1 iteration)"},
                         {"openvdb_version", p.version},
                         {"leaf_nodes", p.leaf_nodes},
                         {"peak_rss_bytes", p.peak_rss_bytes},
                         {"band_voxels", p.band_voxels},
                         {"topology_ms", p.topology_ms},
                         {"sweep_ms", p.sweep_ms},
                         {"compared_voxels", p.compared},
                         {"mean_abs_error_voxels", p.mean_abs_error},
                         {"max_abs_error_voxels", p.max_abs_error}};
        }

        // Radius-8 sphere edits (place and erase alternately) at random surface points.
        std::mt19937_64 rng(seed + 1);
        std::uniform_int_distribution<std::int64_t> px(8, dims.x - 9), pz(8, dims.z - 9);
        std::vector<double> edit_wall, edit_kernel;
        for (int e = 0; e < edits; ++e) {
            Brush b;
            b.op = e % 2 == 0 ? BrushOp::place : BrushOp::erase;
            b.shape = BrushShape::sphere;
            b.radius = 8;
            b.material = 5;
            const std::int64_t x = px(rng), z = pz(rng);
            b.centre = {x, static_cast<std::int64_t>(terrain.ground(x, z)), z};
            // Applied on the device (decoded, brushed and encoded there); the host world lags.
            const auto t0 = Clock::now();
            const auto u = field.apply_brush(b);
            edit_wall.push_back(ms_since(t0));
            edit_kernel.push_back(u.kernel_ms);
        }
        const auto t_sync = Clock::now();
        field.world();
        const double host_sync_ms = ms_since(t_sync);
        const Summary wall = summarize(edit_wall), kern = summarize(edit_kernel);
        const double stored_voxels = static_cast<double>(world.tile_count()) * kTileVoxels;
        const double peak = peak_rss_bytes();
        std::cerr << "edits: radius 8 on the device, median wall " << wall.median << " ms (kernels "
                  << kern.median << " ms); host world brought up to date in " << host_sync_ms
                  << " ms; peak RSS " << peak / 1048576 << " MiB\n";

        char date[32];
        const std::time_t now = std::time(nullptr);
        std::strftime(date, sizeof date, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&now));
        const auto& info = ctx.info();
        nlohmann::json j = {
            {"device", {{"name", info.name}, {"platform", info.platform}, {"type", info.type}}},
            {"date", date},
            {"commit", commit},
            {"command", "sparse_bench"},
            {"size", {dims.x, dims.y, dims.z}},
            {"voxels", static_cast<double>(dims.count())},
            {"seed", seed},
            {"max_distance", bound},
            {"format", format_name},
            {"metric", metric_name},
            {"tiles_stored", world.tile_count()},
            {"solid_voxels", world.solid_count()},
            {"stored_voxels", stored_voxels},
            {"world_bytes", world.bytes()},
            {"field_tiles", field.dense_tiles()},
            {"field_bytes", field.field_bytes()},
            {"build_ms", build_ms},
            {"field_kernel_ms", field_kernel_ms},
            {"field_wall_ms", field_wall_ms},
            {"world_upload_ms", upload_ms},
            {"edit_radius", 8},
            {"edits", edits},
            {"edit_wall_ms_median", wall.median},
            {"edit_wall_ms_samples", edit_wall},
            {"edit_path", "device"},
            {"host_sync_ms", host_sync_ms},
            {"edit_kernel_ms_median", kern.median},
            {"peak_rss_bytes", peak},
            {"rss_after_build_bytes", rss_after_build},
            {"peak_bytes_per_stored_voxel", peak / stored_voxels}};
        if (peer) {
            j["peer"] = peer_json;
        }
        if (!json_path.empty()) {
            std::ofstream(json_path) << j.dump(2) << '\n';
        }
        std::cout << j.dump(2) << '\n';
        return 0;
    } catch (const voxfield::InputError& e) {
        std::cerr << "sparse_bench: " << e.what() << '\n';
        return 2;
    } catch (const std::exception& e) {
        std::cerr << "sparse_bench: " << e.what() << '\n';
        return 1;
    }
}
