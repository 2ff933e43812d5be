#pragma once
// Output formats of a distance field (DESIGN §3) and the exact host-side encoding of a
// distance array into them.
#include <cstdint>
#include <string>
#include <vector>

#include "voxfield/core/palette.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield {

enum class Format { u8, u16, u32, packed32 };

// Distance value meaning "no solid voxel anywhere" in an unsaturated distance array.
inline constexpr std::uint32_t kInfinite = 0xFFFFFFFFu;

Format parse_format(const std::string& name);  // throws InputError listing the valid names
std::string to_string(Format f);
std::size_t element_size(Format f);    // 1, 2, 4, 4
std::uint32_t max_distance(Format f);  // 255, 65535, 4294967295, 255

// Encodes unsaturated distances (kInfinite allowed) into `f`, little-endian, saturating at
// max_distance(f). packed32 = (min(d,255) << 8) | rgb332 of the voxel (0 for air).
std::vector<std::uint8_t> encode_field(const std::vector<std::uint32_t>& distances,
                                       const World& world, const Palette& palette, Format f);

// Reads element i of an encoded field as its distance (for packed32, bits 15..8).
std::uint32_t decode_distance(const std::vector<std::uint8_t>& field, Format f, std::size_t i);

}  // namespace voxfield
