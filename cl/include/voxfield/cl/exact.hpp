#pragma once
// `exact`: global exact Manhattan distance field on any OpenCL device (DESIGN §3 semantics).
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "voxfield/cl/runtime.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield::ocl {

struct FieldTiming {
    double kernel_ms = 0;    // first kernel start to last kernel end (profiling events)
    double upload_ms = 0;    // world + palette upload (profiling events)
    double download_ms = 0;  // field readback (profiling events)
};

// A world resident on the device with its output buffer, ready to be transformed any number
// of times (benchmarks repeat run() without re-uploading).
// Which kernel layout runs: `automatic` picks by device type; tests force each one on PoCL so
// that the GPU kernels are checked where CI runs.
enum class Layout { automatic, cpu, gpu };

class ExactManhattan {
  public:
    // Uploads the world and palette; throws ClError (e.g. the device cannot allocate it).
    ExactManhattan(Context& ctx, const World& world, const Palette& palette, Format format,
                   Layout layout = Layout::automatic);

    // Enqueues the transform, waits, and returns its kernel time in milliseconds.
    double run();
    // Reads the field back (element_size(format) bytes per voxel, little-endian).
    std::vector<std::uint8_t> read(double* download_ms = nullptr);

    double upload_ms() const { return upload_ms_; }
    // Per-kernel times of the last run(), in enqueue order: {kernel name, ms}.
    const std::vector<std::pair<std::string, double>>& stage_ms() const { return stage_ms_; }
    const char* layout() const;  // "cpu" or "gpu": which kernel layout runs

    // The buffer the field is written to (for later consumers such as the renderer).
    const cl::Buffer& field_buffer() const { return out_; }

  private:
    Context& ctx_;
    Dims dims_;
    Format format_;
    bool gpu_layout_;
    cl::Buffer voxels_, rgb_, work_, out_;
    // The kernels of one transform, in enqueue order.
    struct Stage {
        std::string name;
        cl::Kernel kernel;
        cl::NDRange global, local;
    };
    std::vector<Stage> stages_;
    double upload_ms_ = 0;
    std::vector<std::pair<std::string, double>> stage_ms_;
};

struct FieldResult {
    std::vector<std::uint8_t> bytes;
    FieldTiming timing;
};

// Uploads, transforms once and reads back.
FieldResult generate_exact(Context& ctx, const World& world, const Palette& palette, Format format,
                           Layout layout = Layout::automatic);

}  // namespace voxfield::ocl
