#pragma once
// `exact` for everything beyond unit-spacing Manhattan: L1, L-inf and L2 with voxel spacing,
// signed fields and the feature transform (kernels: cl/kernels/exact_separable.cl).
#include <string>

#include "voxfield/cl/generator.hpp"

namespace voxfield::ocl {

class ExactSeparable : public Generator {
  public:
    // Whether `options` (algorithm exact) need this generator rather than ExactManhattan.
    static bool needed(const GeneratorOptions& options);

    // Uploads the world and palette and builds the kernels; options as resolve_options
    // returns them. Throws ClError when the device cannot hold the buffers or lacks fp64.
    ExactSeparable(Context& ctx, const World& world, const Palette& palette,
                   const GeneratorOptions& options);

    double run() override;
    std::string variant() const override;  // "cpu layout" or "gpu layout"

  private:
    struct Stage {
        std::string name;
        cl::Kernel kernel;
        cl::NDRange global;
    };
    bool gpu_layout_;
    cl::Buffer voxels_, rgb_, g_[2], h_[2], feat_[2], scratch_;
    std::vector<Stage> stages_;
};

}  // namespace voxfield::ocl
