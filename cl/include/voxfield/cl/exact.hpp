#pragma once
// `exact`: global exact Manhattan distance field on any OpenCL device (DESIGN §3 semantics).
#include <string>
#include <vector>

#include "voxfield/cl/generator.hpp"

namespace voxfield::ocl {

class ExactManhattan : public Generator {
  public:
    // Uploads the world and palette; throws ClError (e.g. the device cannot allocate it).
    ExactManhattan(Context& ctx, const World& world, const Palette& palette, Format format,
                   Layout layout = Layout::automatic);

    double run() override;
    std::string variant() const override;  // "cpu layout" or "gpu layout"
    // The world on the device (uint8 per voxel); writes to it show in the next run().
    const cl::Buffer& voxels_buffer() const { return voxels_; }

  private:
    bool gpu_layout_;
    cl::Buffer voxels_, rgb_, work_;
    // The kernels of one transform, in enqueue order.
    struct Stage {
        std::string name;
        cl::Kernel kernel;
        cl::NDRange global, local;
    };
    std::vector<Stage> stages_;
};

}  // namespace voxfield::ocl
