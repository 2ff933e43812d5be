#pragma once
// Implicit surfaces (DESIGN §3, `.sdf.json`): the part description parsed and validated, its
// expression compiled once to a flat postfix tape (sdf_layout.hpp), and CPU evaluators on the
// tape: float value (with material), interval enclosure over a box, and value with gradient
// (analytic, forward-mode dual numbers). Signed distance bounds after Inigo Quilez's
// "distance functions" article; interval pruning after the reference blog (farfa.dev,
// "implicit surface rendering for CAD").
//
// Materials: a node's "material" applies to its subtree except where a descendant carries its
// own (the nearest one wins; default 1). A union (smooth or not) takes the material of the child
// with the smallest value at the point, an intersection that of the child with the largest, a
// difference (smooth or not) keeps A's; transforms and shells keep their child's.
#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "voxfield/core/sdf_layout.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield::sdf {

struct Vec3 {
    float x = 0, y = 0, z = 0;
};

struct Interval {
    float lo = 0, hi = 0;
};

struct Box {
    Interval x, y, z;
};

// One tape instruction, as the device reads it (VF_SDF_INSTR_WORDS words).
struct Instr {
    std::uint32_t op = 0;
    std::uint32_t material = 0;
    std::array<float, VF_SDF_INSTR_PARAMS> p{};
};
static_assert(sizeof(Instr) == VF_SDF_INSTR_WORDS * 4);

struct Tape {
    std::vector<Instr> code;
    std::uint32_t max_values = 0;  // deepest value stack
    std::uint32_t max_points = 0;  // deepest point stack (1: no transform)
};

// A parsed part: the grid (ceil((x1 - x0) / h) voxels per axis, voxel i's centre at
// x0 + (i + 0.5) h) and the compiled expression.
struct Part {
    double voxel_size = 0;
    std::array<double, 3> lo{}, hi{};
    Dims dims;
    Tape tape;
    std::size_t nodes = 0;  // nodes of the expression tree
    std::size_t depth = 0;  // nodes on its longest root-to-leaf path

    // Where the grid's corner (i, j, k) lies, in float, as every evaluator computes it:
    // x0 + i * h (i may be a half-integer index times two: see centre()).
    float corner_x(std::uint32_t i) const;
    float corner_y(std::uint32_t j) const;
    float corner_z(std::uint32_t k) const;
    Vec3 corner(std::uint32_t i, std::uint32_t j, std::uint32_t k) const;
    // Voxel (i, j, k)'s centre: x0 + (i + 0.5) h.
    Vec3 centre(std::uint32_t i, std::uint32_t j, std::uint32_t k) const;
    // The closed box from corner (i0, j0, k0) to corner (i1, j1, k1).
    Box box(std::uint32_t i0, std::uint32_t j0, std::uint32_t k0, std::uint32_t i1,
            std::uint32_t j1, std::uint32_t k1) const;
};

// Parses `.sdf.json` text; `name` prefixes every message. One-line InputError on anything
// malformed: not JSON, wrong version, unknown node, missing field, wrong type, a non-positive
// voxel size or size parameter, empty bounds, a tree deeper than VF_SDF_MAX_DEPTH, a material
// outside 1..255.
Part parse_part(const std::string& text, const std::string& name);
// Reads and parses a file (InputError naming it when it cannot be read).
Part load_part(const std::filesystem::path& path);
// Whether `path` names an `.sdf.json` file (by its name, case-insensitive).
bool is_sdf_path(const std::filesystem::path& path);

struct ValueMaterial {
    float value = 0;
    std::uint8_t material = 0;
};

struct ValueGradient {
    float value = 0;
    Vec3 gradient;
};

// The tape's value at p (f < 0 inside).
float evaluate(const Tape& tape, Vec3 p);
// The value and the material at p.
ValueMaterial evaluate_material(const Tape& tape, Vec3 p);
// A sound enclosure of the tape's float value over every point of the closed box, and the
// material when one child surely decides every selection (0 when it is not decided).
struct IntervalMaterial {
    Interval value;
    std::uint8_t material = 0;
};
IntervalMaterial evaluate_interval(const Tape& tape, const Box& box);
// The value and its gradient (forward-mode dual numbers: exact derivatives of the float
// expression, one-sided where it has a kink).
ValueGradient evaluate_gradient(const Tape& tape, Vec3 p);

// The discretised solid as a voxel world: voxel (i, j, k) holds the material at its centre
// where f < 0 there, else 0. Blocks whose interval excludes 0 are filled or skipped without
// sampling. InputError when the grid has more voxels than a dense world may (2^31).
World solid_world(const Part& part, const std::string& name);

}  // namespace voxfield::sdf
