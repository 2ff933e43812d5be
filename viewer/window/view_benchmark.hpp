#pragma once
// `view --benchmark`: the dissertation's editing protocol in the viewer (core's RandomEdits,
// one edit every --interval-ms, recorded by the EditLog that `bench --suite edits` uses too),
// every frame's times, and the report: the summary printed, --json and --csv.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "edit_log.hpp"
#include "view_options.hpp"
#include "voxfield/cl/runtime.hpp"
#include "voxfield/core/undo.hpp"
#include "voxfield/pipeline/frame_pipeline.hpp"
#include "voxfield/vk/present.hpp"

namespace voxfield::cli {

struct FrameRecord {
    // update_ms: the field's incremental update plus writing it into the render field
    // (convert_ms), device time.
    double time_s = 0, frame_ms = 0, update_ms = 0, convert_ms = 0, raymarch_ms = 0;
    bool edit = false;
    // --simulate: the step's automaton (device time, -1 without a step) and the voxels it
    // changed; its field update is part of update_ms.
    double simulate_ms = -1;
    std::size_t sim_changed = 0;
};

class BenchmarkEdits {
  public:
    // chunk: the field's (0, a global field: the default chunk size sizes the edits).
    BenchmarkEdits(Dims dims, std::uint32_t chunk, std::uint64_t seed, double interval_ms);
    // The protocol's next edit once its time (seconds since the start) has come.
    std::optional<Brush> due(double time_s);
    // The update the edit's batch cost (the edit is the batch's last brush).
    void record(const Brush& brush, const pipeline::UpdateTimings& u, const EditResult& result);
    const EditLog& log() const { return log_; }

  private:
    RandomEdits edits_;
    EditLog log_;
    double interval_ms_;
    double next_s_;
};

// What the benchmark ran on, for its report.
struct BenchmarkSetup {
    std::string world_name;
    ocl::DeviceInfo opencl;
    std::string vulkan;
    std::optional<vk::PresentMode> present;  // none: headless
};

// Prints the summary and writes --json and --csv.
void report_benchmark(const ViewCliOptions& o, const BenchmarkSetup& setup,
                      const pipeline::FramePipeline& session, const vk::RenderOptions& r,
                      const std::vector<FrameRecord>& records, const EditLog& log);

// One edit of the sparse viewer (view_sparse), the benchmark's or any other.
struct SparseEditRecord {
    Brush brush;
    double time_s = 0;
    bool bench = false;  // the protocol's
    // Wall time in all (device edit and field update, read-back, tracer update), the field's
    // kernels (edit_kernel_ms of them the edit's), the edited tiles' read-back into the host
    // world, the tracer's tile update.
    double wall_ms = 0, field_kernel_ms = 0, edit_kernel_ms = 0, readback_ms = 0, tracer_ms = 0;
    std::uint32_t field_tiles = 0;                       // field tiles written
    std::uint32_t tiles_written = 0, tiles_removed = 0;  // the tracer's
    std::uint64_t tracer_bytes = 0;                      // copied to the tracer's device
    bool tracer_whole = false;                           // the tracer uploaded the world whole
};

// The sparse viewer's benchmark: prints the summary and writes --json (`world`: the sparse
// world's keys, put under "sparse") and --csv.
void report_sparse_benchmark(const ViewCliOptions& o, const BenchmarkSetup& setup,
                             const nlohmann::json& world, const vk::RenderOptions& r,
                             const std::vector<FrameRecord>& records,
                             const std::vector<SparseEditRecord>& edits);

}  // namespace voxfield::cli
