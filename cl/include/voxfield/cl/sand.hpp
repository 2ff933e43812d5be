#pragma once
// Falling sand and water on an OpenCL device (kernels: cl/kernels/sand.cl): the block
// automaton of voxfield/core/sand.hpp, bit for bit, with the voxels each step changed read
// back compactly (only those), ready for IncrementalField::apply_changes.
#include <cstdint>
#include <string>
#include <vector>

#include "voxfield/cl/generator.hpp"
#include "voxfield/core/sand.hpp"

namespace voxfield::ocl {

struct SandStepResult {
    VoxelChanges changes;    // ascending index, as sand_step returns them
    double simulate_ms = 0;  // device time of the step: kernel(s) and the changes' readback
};

class SandSimulator {
  public:
    // Uploads the world. Layout: cpu runs one work-item per row of blocks along x, gpu one
    // per block; automatic picks by device type. Throws InputError for bad rules or a world
    // of 2^32 voxels or more, ClError when the device cannot hold it.
    SandSimulator(Context& ctx, const World& world, const SandRules& rules,
                  Layout layout = Layout::automatic);

    // Runs step `step` of the automaton with `seed` on the device world.
    SandStepResult step(std::uint64_t seed, std::uint64_t step);
    // The device world (one byte per voxel, x fastest).
    std::vector<std::uint8_t> read_world();
    std::string variant() const;  // "cpu layout" or "gpu layout"

  private:
    // Enqueues resetting the change count and the step's kernel.
    void launch(std::vector<cl::Event>& events, std::uint64_t step, std::uint64_t key);
    // Enqueues writing the first `count` changes into world_[current_].
    void sync(std::vector<cl::Event>& events, std::size_t count);

    Context& ctx_;
    Dims dims_;
    SandRules rules_;
    bool gpu_layout_;
    cl::Kernel kernel_, sync_;
    cl::Buffer world_[2], count_, changes_;
    int current_ = 0;  // the step reads world_[current_]; both copies agree between steps
    std::size_t capacity_ = 0;
    std::vector<cl_uint2> staged_;  // the step's changes as read back
    std::vector<std::uint64_t> keys_, sort_scratch_;
};

}  // namespace voxfield::ocl
