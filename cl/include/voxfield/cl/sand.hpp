#pragma once
// Falling sand and water on an OpenCL device (kernels: cl/kernels/sand.cl): the block
// automaton of voxfield/core/sand.hpp, bit for bit, stepped in place on a world the caller
// keeps on the device (an IncrementalField's voxels). Each step lists its changed voxels on the
// device (DeviceChanges) for the field update that follows it; only the list's size and the
// boxes of the changes come back to the host.
#include <cstdint>
#include <string>
#include <vector>

#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/incremental.hpp"
#include "voxfield/core/sand.hpp"

namespace voxfield::ocl {

struct SandStepResult {
    DeviceChanges changes;   // in the simulator's list, valid until the next step
    double simulate_ms = 0;  // device time of the step: its kernels and the summary's readback
};

class SandSimulator {
  public:
    // Steps the world in `voxels` (dims.count() bytes on ctx's device, x fastest), which the
    // caller keeps alive and current. Layout: cpu runs one work-item per column of block rows,
    // gpu one per column of blocks; automatic picks by device type. `capacity`: the change
    // list's room (0: an eighth of the voxels, at least 4096); a step that changes more
    // overflows it (DeviceChanges::overflow). Throws InputError for bad rules or a world of
    // 2^32 voxels or more, ClError when the device cannot hold the list.
    SandSimulator(Context& ctx, const cl::Buffer& voxels, Dims dims, const SandRules& rules,
                  Layout layout = Layout::automatic, std::size_t capacity = 0);

    // Runs step `step` of the automaton with `seed` on the device world, in place.
    SandStepResult step(std::uint64_t seed, std::uint64_t step);
    // The last step's changes, ascending index, read back from the device list (for tests and
    // diagnostics). Throws std::logic_error after a step whose list overflowed.
    VoxelChanges read_changes();
    std::string variant() const;  // "cpu layout" or "gpu layout"

  private:
    // Enqueues clearing the summary and the step's kernel on the world `voxels` of `dims`.
    void launch(std::vector<cl::Event>& events, const cl::Buffer& voxels, Dims dims,
                std::uint64_t step, std::uint64_t key);

    Context& ctx_;
    cl::Buffer voxels_;
    Dims dims_;
    SandRules rules_;
    bool gpu_layout_;
    cl::Kernel kernel_;
    cl::Buffer summary_, changes_;
    std::size_t capacity_ = 0;
    DeviceChanges last_;
    // The step's summary as read back: a member, as a read in flight may still write it.
    std::vector<cl_uint> summary_read_;
};

}  // namespace voxfield::ocl
