#pragma once
// Output formats of a distance field (DESIGN §3) and the exact host-side encoding of a
// distance array into them.
#include <cstdint>
#include <string>
#include <vector>

#include "voxfield/core/palette.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield {

// u8..u32 and packed32 hold unsigned distances rounded down; i8..i32 signed ones rounded
// toward zero; f32 and f64 the distance itself. All saturate at their range.
enum class Format { u8, u16, u32, packed32, i8, i16, i32, f32, f64 };

// Distance value meaning "no solid voxel anywhere" in an unsaturated distance array.
inline constexpr std::uint32_t kInfinite = 0xFFFFFFFFu;

Format parse_format(const std::string& name);  // throws InputError listing the valid names
std::string to_string(Format f);
const std::vector<std::string>& format_names();
std::size_t element_size(Format f);  // 1, 2, 4, 4, 1, 2, 4, 4, 8
bool is_float(Format f);             // f32, f64
// Formats that can hold a signed field (--signed): i8, i16, i32, f32, f64.
bool holds_sign(Format f);
// The largest distance an integer format holds: 255, 65535, 4294967295, 255, 127, 32767,
// 2147483647. Throws std::invalid_argument for float formats.
std::uint32_t max_distance(Format f);

// Encodes unsaturated distances (kInfinite allowed) into `f`, little-endian, saturating at
// max_distance(f). packed32 = (min(d,255) << 8) | rgb332 of the voxel (0 for air).
std::vector<std::uint8_t> encode_field(const std::vector<std::uint32_t>& distances,
                                       const World& world, const Palette& palette, Format f);

// Encodes real distances (signed allowed, +-inf for "none") into `f` as DESIGN §3 says:
// unsigned integer formats floor and saturate (negative values are a caller error),
// signed integer formats round toward zero and saturate, floats round to nearest.
std::vector<std::uint8_t> encode_real_field(const std::vector<double>& distances,
                                            const World& world, const Palette& palette, Format f);

// Reads element i of an encoded field as its distance (for packed32, bits 15..8).
std::uint32_t decode_distance(const std::vector<std::uint8_t>& field, Format f, std::size_t i);
// Reads element i of a field in any format as a real value (packed32: bits 15..8).
double decode_value(const std::vector<std::uint8_t>& field, Format f, std::size_t i);

}  // namespace voxfield
