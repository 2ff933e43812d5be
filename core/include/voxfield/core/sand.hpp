#pragma once
// Falling sand and water (DESIGN §4, `simulate`): a block cellular automaton on the voxel
// world, the CPU reference of cl/kernels/sand.cl.
// Source: Toffoli & Margolus, "Cellular Automata Machines" (1987), ch. 12 (Margolus blocks).
//
// Each step cuts the world into 2x2x2 blocks (the Margolus neighbourhood extended to 3-D), whose
// origin moves with the step: block corners at 2*i - o per axis, o = sand_block_offset(step), so
// that o.y alternates every step (a grain falls one cell per step) and o.x, o.z cycle through all
// four combinations in eight steps (every diagonal and sideways direction is offered in turn).
// Moves happen only inside a block, so blocks are independent and a step has no conflicts
// whatever order the blocks run in. Cells outside the world are walls: nothing leaves it.
//
// Inside a block, with h = sand_hash(sand_step_key(seed, step) ^ block) (block: the block's
// linear index, x fastest, in the step's block grid), the four columns (dx, dz) are visited
// in the order c = (n + (h & 3)) & 3 for n = 0..3, column c = dx + 2 * dz:
//   1. falling, top layer: a sand or water cell moves down into air; sand also swaps with
//      water below that has not moved this step; otherwise it moves diagonally down (to the
//      bottom cell of column c ^ 1 or c ^ 2) into air, bit 8 + c of h choosing when both are
//      air (0: c ^ 1).
//   2. sideways, top layer then bottom layer: water that has not moved moves into the air
//      cell of column c ^ 1 or c ^ 2 in its layer, bit 16 + c + 4 * layer choosing when both
//      are, except a bottom-layer water cell whose cell below (outside the block) was air
//      before the step: it falls in the next step instead.
// A cell moves at most once per step; every other solid material is static. Each material's
// count is conserved, and the result depends only on the world, the seed and the step.
#include <cstdint>

#include "voxfield/core/chunks.hpp"
#include "voxfield/core/undo.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield {

struct SandRules {
    std::uint8_t sand = 2;   // --sand-material
    std::uint8_t water = 3;  // --water-material
};

// Throws InputError unless both materials are 1..255 and differ.
void check_sand_rules(const SandRules& rules);

// The automaton's hash: splitmix64's output function (Steele, Lea & Flood 2014) of x.
std::uint64_t sand_hash(std::uint64_t x);
// The key every block hash of a step derives from: sand_hash(sand_hash(seed) ^ step).
std::uint64_t sand_step_key(std::uint64_t seed, std::uint64_t step);
// The block partition's offset o of a step: ((step >> 1) & 1, step & 1, (step >> 2) & 1).
Int3 sand_block_offset(std::uint64_t step);

// Runs one step on `world` and returns the voxels it changed (ascending index, before !=
// after). Throws InputError for bad rules (check_sand_rules).
VoxelChanges sand_step(World& world, const SandRules& rules, std::uint64_t seed,
                       std::uint64_t step);

// The `bench --suite sand` world, deterministic for a seed, with SandRules{}'s materials: a
// floor (material 1) at y = 0, a steep sand cone that slumps, a water basin with walls
// (material 4) and sand grains falling from the upper half of the world (one voxel in 64
// there). Any dims; small worlds keep what fits.
World scene_sand(Dims dims, std::uint64_t seed);

}  // namespace voxfield
