#pragma once
// NumPy .npy files (format 1.0/2.0/3.0 read, 1.0 write): 3-D uint8/uint16/uint32, C order,
// shape (Z, Y, X). Anything else is rejected with an InputError naming the problem.
#include <cstdint>
#include <filesystem>
#include <vector>

#include "voxfield/core/world.hpp"

namespace voxfield {

enum class NpyType { u8, u16, u32 };

struct NpyArray {
    NpyType type = NpyType::u8;
    Dims dims;                       // x = shape[2], y = shape[1], z = shape[0]
    std::vector<std::uint8_t> data;  // little-endian elements, x fastest
};

NpyArray read_npy(const std::filesystem::path& path);

// Writes atomically: a temporary file in the same folder, renamed on success, so a failure
// never leaves a partial file. Throws InputError if the folder does not exist.
void write_npy(const std::filesystem::path& path, NpyType type, Dims dims,
               const std::vector<std::uint8_t>& data);

// A world from a .npy array; values must be palette indices 0..255.
World world_from_npy(const NpyArray& array);
NpyArray npy_from_world(const World& world);

}  // namespace voxfield
