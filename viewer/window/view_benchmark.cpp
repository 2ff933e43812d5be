// `view --benchmark`: its edits, frame records and report (see view_benchmark.hpp).
#include "view_benchmark.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <iostream>
#include <sstream>

#include "cli_util.hpp"
#include "voxfield/core/stats.hpp"

namespace voxfield::cli {
namespace {

nlohmann::json summary_json(const Summary& s) {
    nlohmann::json j = nlohmann::json::object();
    put_summary(j, s);
    return j;
}

void print_summary(const std::string& what, const Summary& s) {
    std::cout << "  " << what << ": n " << s.n << ", mean " << fixed(s.mean, 3) << " ms, median "
              << fixed(s.median, 3) << ", std " << fixed(s.std, 3) << ", min " << fixed(s.min, 3)
              << ", max " << fixed(s.max, 3) << ", 95% CI [" << fixed(s.ci95_lo, 3) << ", "
              << fixed(s.ci95_hi, 3) << "]\n";
}

// Prints the mean frame rate of frames summarised by `frames`, when there were any.
void print_mean_fps(const Summary& frames) {
    if (frames.mean > 0) {
        std::cout << "  mean FPS " << fixed(1000.0 / frames.mean, 1) << '\n';
    }
}

// The report's keys that describe the run: machine, build, source, protocol and image.
nlohmann::json run_json(const ViewCliOptions& o, const BenchmarkSetup& setup,
                        const vk::RenderOptions& ropts) {
    nlohmann::json j;
    j["device"] = device_json(setup.opencl);
    j["vulkan"] = setup.vulkan;
    j["commit"] = commit();
    j["date"] = utc_now();
    j["source"] = setup.world_name;
    j["seed"] = o.seed;
    j["interval_ms"] = o.interval_ms;
    j["duration_s"] = o.duration_s;
    j["image"] = {ropts.width, ropts.height};
    j["present"] = setup.present ? vk::to_string(*setup.present) : "headless";
    return j;
}

}  // namespace

BenchmarkEdits::BenchmarkEdits(Dims dims, std::uint32_t chunk, std::uint64_t seed,
                               double interval_ms)
    : edits_(dims, chunk != 0 ? chunk : ocl::kDefaultChunk, seed),
      interval_ms_(interval_ms),
      next_s_(interval_ms / 1000.0) {}

std::optional<Brush> BenchmarkEdits::due(double time_s) {
    if (time_s < next_s_) {
        return std::nullopt;
    }
    next_s_ += interval_ms_ / 1000.0;
    return edits_.next();
}

void BenchmarkEdits::record(const Brush& brush, const pipeline::UpdateTimings& u,
                            const EditResult& result) {
    log_.add({brush, edits_.last_size(), u.total_ms(), u.voxels_recomputed, result.changes.size(),
              u.full_regeneration});
}

void report_benchmark(const ViewCliOptions& o, const BenchmarkSetup& setup,
                      const pipeline::FramePipeline& session, const vk::RenderOptions& ropts,
                      const std::vector<FrameRecord>& records, const EditLog& log) {
    const Dims dims = session.world().dims();
    std::vector<double> frame_ms, march_ms, sim_ms, sim_update_ms;
    for (const FrameRecord& r : records) {
        frame_ms.push_back(r.frame_ms);
        if (r.simulate_ms >= 0) {
            // Every frame steps the sand: its update is the step's (plus any edit's).
            sim_ms.push_back(r.simulate_ms);
            sim_update_ms.push_back(r.update_ms);
        }
        if (r.raymarch_ms >= 0) {
            march_ms.push_back(r.raymarch_ms);
        }
    }
    const Summary sf = summarize(frame_ms), su = log.update_summary(), sm = summarize(march_ms);
    const auto edit_count = static_cast<std::size_t>(
        std::count_if(records.begin(), records.end(), [](const FrameRecord& r) { return r.edit; }));
    std::cout << "benchmark: seed " << o.seed << ", an edit every " << o.interval_ms << " ms for "
              << o.duration_s << " s, " << records.size() << " frames, " << edit_count << " edits, "
              << (o.simulate ? std::to_string(sim_ms.size()) + " sand steps, " : "") << ropts.width
              << "x" << ropts.height
              << (setup.present ? ", present " + vk::to_string(*setup.present)
                                : std::string(", headless"))
              << '\n';
    print_summary("frame (incl. field update)", sf);
    const Summary ssim = summarize(sim_ms), ssu = summarize(sim_update_ms);
    if (o.simulate) {
        print_summary("sand simulation (device)", ssim);
        print_summary("field update (every frame)", ssu);
    } else {
        print_summary("field update (edit frames)", su);
    }
    print_summary("ray march", sm);
    print_mean_fps(sf);
    if (!o.json.empty()) {
        nlohmann::json j = run_json(o, setup, ropts);
        j["format"] = to_string(session.options().format);
        j["world"] = {dims.x, dims.y, dims.z};
        j["algorithm"] = ocl::to_string(session.options().algorithm);
        j["chunk"] = session.options().chunk;
        j["sharing"] = session.marcher().sharing_path();
        j["sync"] = pipeline::to_string(session.sync());
        j["simulate"] = o.simulate;
        j["summary"] = {{"frame", summary_json(sf)},
                        {"field_update", summary_json(o.simulate ? ssu : su)},
                        {"raymarch", summary_json(sm)}};
        if (o.simulate) {
            j["summary"]["simulate"] = summary_json(ssim);
        }
        nlohmann::json frames = nlohmann::json::array();
        for (const FrameRecord& r : records) {
            frames.push_back({{"time_s", r.time_s},
                              {"frame_ms", r.frame_ms},
                              {"update_ms", r.update_ms},
                              {"convert_ms", r.convert_ms},
                              {"raymarch_ms", r.raymarch_ms},
                              {"edit", r.edit},
                              {"simulate_ms", r.simulate_ms < 0 ? nlohmann::json()
                                                                : nlohmann::json(r.simulate_ms)},
                              {"sand_voxels_changed", r.sim_changed}});
        }
        j["frames"] = frames;
        j["edits"] = log.edits_json();
        write_json_file(o.json, j);
    }
    if (!o.csv.empty()) {
        std::ostringstream csv;
        csv << "frame,time_s,edit,frame_ms,update_ms,convert_ms,raymarch_ms\n";
        for (std::size_t i = 0; i < records.size(); ++i) {
            const FrameRecord& r = records[i];
            csv << i << ',' << r.time_s << ',' << (r.edit ? 1 : 0) << ',' << r.frame_ms << ','
                << r.update_ms << ',' << r.convert_ms << ',' << r.raymarch_ms << '\n';
        }
        write_text_file(o.csv, csv.str());
    }
}

void report_sparse_benchmark(const ViewCliOptions& o, const BenchmarkSetup& setup,
                             const nlohmann::json& world, const vk::RenderOptions& ropts,
                             const std::vector<FrameRecord>& records,
                             const std::vector<SparseEditRecord>& edits) {
    std::vector<double> frame_ms, edit_frame_ms, march_ms, wall, kernel, readback, tracer;
    for (const FrameRecord& r : records) {
        frame_ms.push_back(r.frame_ms);
        if (r.edit) {
            edit_frame_ms.push_back(r.frame_ms);
        }
        if (r.raymarch_ms >= 0) {
            march_ms.push_back(r.raymarch_ms);
        }
    }
    std::uint64_t written = 0, removed = 0, whole = 0;
    for (const SparseEditRecord& e : edits) {
        if (!e.bench) {
            continue;
        }
        wall.push_back(e.wall_ms);
        kernel.push_back(e.field_kernel_ms);
        readback.push_back(e.readback_ms);
        tracer.push_back(e.tracer_ms);
        written += e.tiles_written;
        removed += e.tiles_removed;
        whole += e.tracer_whole ? 1 : 0;
    }
    const Summary sf = summarize(frame_ms), sef = summarize(edit_frame_ms),
                  sm = summarize(march_ms), sw = summarize(wall), sk = summarize(kernel),
                  sr = summarize(readback), st = summarize(tracer);
    std::cout << "benchmark: sparse, seed " << o.seed << ", an edit every " << o.interval_ms
              << " ms for " << o.duration_s << " s, " << records.size() << " frames, "
              << wall.size() << " edits (" << written << " tiles written, " << removed
              << " removed in the tracer"
              << (whole ? ", " + std::to_string(whole) + " whole uploads" : "") << "), "
              << ropts.width << "x" << ropts.height
              << (setup.present ? ", present " + vk::to_string(*setup.present)
                                : std::string(", headless"))
              << '\n';
    print_summary("frame (incl. edits)", sf);
    print_summary("frame with an edit", sef);
    print_summary("edit (wall: device edit, field, read-back, tracer)", sw);
    print_summary("edit field kernels (device)", sk);
    print_summary("edited tiles read back", sr);
    print_summary("tracer tile update", st);
    print_summary("trace", sm);
    print_mean_fps(sf);
    if (!o.json.empty()) {
        nlohmann::json j = run_json(o, setup, ropts);
        j["world"] = world.at("dims");
        j["algorithm"] = "exact (sparse tiles)";
        j["shading"] = ropts.shading == vk::Shading::lit ? "lit" : "flat";
        j["sparse"] = world;
        j["summary"] = {{"frame", summary_json(sf)},
                        {"edit_frame", summary_json(sef)},
                        {"edit", summary_json(sw)},
                        {"field_update", summary_json(sw)},
                        {"edit_field_kernels", summary_json(sk)},
                        {"readback", summary_json(sr)},
                        {"tracer_update", summary_json(st)},
                        {"raymarch", summary_json(sm)}};
        j["fps_mean"] = sf.mean > 0 ? 1000.0 / sf.mean : 0.0;
        j["tiles_written"] = written;
        j["tiles_removed"] = removed;
        j["tracer_whole_uploads"] = whole;
        nlohmann::json frames = nlohmann::json::array();
        for (const FrameRecord& r : records) {
            frames.push_back({{"time_s", r.time_s},
                              {"frame_ms", r.frame_ms},
                              {"update_ms", r.update_ms},
                              {"raymarch_ms", r.raymarch_ms},
                              {"edit", r.edit}});
        }
        j["frames"] = frames;
        nlohmann::json list = nlohmann::json::array();
        for (const SparseEditRecord& e : edits) {
            const Brush& b = e.brush;
            list.push_back({{"time_s", e.time_s},
                            {"benchmark", e.bench},
                            {"op", to_string(b.op)},
                            {"shape", to_string(b.shape)},
                            {"centre", {b.centre.x, b.centre.y, b.centre.z}},
                            {"radius", b.radius},
                            {"material", b.material},
                            {"wall_ms", e.wall_ms},
                            {"field_kernel_ms", e.field_kernel_ms},
                            {"edit_kernel_ms", e.edit_kernel_ms},
                            {"readback_ms", e.readback_ms},
                            {"tracer_ms", e.tracer_ms},
                            {"field_tiles", e.field_tiles},
                            {"tiles_written", e.tiles_written},
                            {"tiles_removed", e.tiles_removed},
                            {"tracer_bytes", e.tracer_bytes},
                            {"tracer_whole", e.tracer_whole}});
        }
        j["edits"] = list;
        write_json_file(o.json, j);
    }
    if (!o.csv.empty()) {
        std::ostringstream csv;
        csv << "frame,time_s,edit,frame_ms,update_ms,raymarch_ms\n";
        for (std::size_t i = 0; i < records.size(); ++i) {
            const FrameRecord& r = records[i];
            csv << i << ',' << r.time_s << ',' << (r.edit ? 1 : 0) << ',' << r.frame_ms << ','
                << r.update_ms << ',' << r.raymarch_ms << '\n';
        }
        write_text_file(o.csv, csv.str());
    }
}

}  // namespace voxfield::cli
