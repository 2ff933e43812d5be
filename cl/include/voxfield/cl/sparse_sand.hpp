#pragma once
// Falling sand and water on a sparse world (issue 24): the block automaton of
// voxfield/core/sand.hpp, stepped on the device on the 64-tree tiles of a SparseField's world,
// voxel for voxel as the dense automaton (sand.hpp, cl/sand.hpp) steps the same world, with the
// field's bounded distances updated only within D of the step's changes.
//
// A step runs only the tiles whose voxels may change. Whether a 2x2x2 block changes depends on
// its eight cells and the four below it alone (never on the hash, which only picks where
// something moves), and the block partition repeats every 8 steps; so a block that changes at
// step s has a cell, or a cell below it, that changed in steps s - 8 .. s - 1, or it held sand
// or water when the simulation started (or was edited) fewer than 8 steps ago. The tiles run are
// those within 2 voxels of such changes, and after a start or an edit (touched) those within one
// tile of a tile holding sand or water, or of the edit.
//
// Each tile run is gathered from the 64-trees into a window of its own (the tile with one voxel
// more on every side and two below, sand.cl's sand_step_windows), stepped there with the world's
// block partition, hash and walls, and when it changed encoded again on the device
// (SparseField::apply_dense_tiles), which then recomputes the field within D of each changed
// tile's box of changes. Only a 32-byte summary per tile run comes back to the host.
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "voxfield/cl/sparse_field.hpp"
#include "voxfield/core/sand.hpp"

namespace voxfield::ocl {

class SparseSand {
  public:
    // Steps the world of `field`, which must have been built on an editable world (its
    // apply_brush works) and outlive this; the gather takes the field's layout. InputError for
    // bad rules.
    SparseSand(Context& ctx, SparseField& field, const SandRules& rules);

    struct Step {
        std::uint64_t changed = 0;    // voxels the step changed
        std::uint32_t tiles_run = 0;  // tiles gathered and stepped
        std::uint32_t tiles_changed = 0;
        Box bounds;                  // of the changed voxels (Box{} when none)
        std::vector<Int3> tiles;     // the tiles encoded again (tiles_changed of them)
        double simulate_ms = 0;      // device time: gather and step kernels, summary read
        double update_ms = 0;        // device time: encoding and the field's update
        SparseField::Update update;  // the field's update (empty when nothing changed)
    };
    // Runs step `step` of the automaton with `seed` (sand_step's numbering): when `step` is not
    // the one after the last, every tile near sand or water runs for 8 steps.
    Step step(std::uint64_t seed, std::uint64_t step);
    // After the world was edited inside `box` other than by step() (a brush): its tiles and
    // their neighbours run for the next 8 steps.
    void touched(const Box& box);

  private:
    // Tile keys to run at step s, ascending.
    std::vector<std::uint64_t> tiles_to_run(std::uint64_t s);
    // Every tile holding sand or water becomes active for steps s .. s + 7.
    void activate_sandy(std::uint64_t s);
    void ensure_capacity(std::size_t windows);

    Context& ctx_;
    SparseField& field_;
    Dims dims_;  // the world's (read once: world() brings the host world up to date)
    SandRules rules_;
    bool gpu_layout_;
    cl::Kernel kernel_;
    cl::Buffer windows_, jobs_, refs_, tiles_, summary_;
    std::size_t capacity_ = 0;
    // Boxes of recent changes (world voxels) and the last step whose tiles they keep running.
    std::vector<std::pair<Box, std::uint64_t>> active_;
    std::optional<std::uint64_t> next_;  // the step after the last one run
    // A step's tables and summary, members as writes and reads in flight use them.
    std::vector<std::int64_t> host_jobs_;
    std::vector<std::uint64_t> host_refs_;
    std::vector<cl_int> host_tiles_;
    std::vector<cl_uint> host_summary_;
};

}  // namespace voxfield::ocl
