// Output formats of a distance field and their exact encoding (DESIGN §3: saturate, never
// wrap; packed32 is the dissertation's (min(d,255) << 8) | rgb332 layout).
#include "voxfield/core/format.hpp"

#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "voxfield/core/error.hpp"

namespace voxfield {

Format parse_format(const std::string& name) {
    if (name == "u8") {
        return Format::u8;
    }
    if (name == "u16") {
        return Format::u16;
    }
    if (name == "u32") {
        return Format::u32;
    }
    if (name == "packed32") {
        return Format::packed32;
    }
    throw InputError("unknown format '" + name + "' (valid: u8, u16, u32, packed32)");
}

std::string to_string(Format f) {
    switch (f) {
        case Format::u8:
            return "u8";
        case Format::u16:
            return "u16";
        case Format::u32:
            return "u32";
        case Format::packed32:
            return "packed32";
    }
    throw std::invalid_argument("to_string: invalid Format value");
}

std::size_t element_size(Format f) {
    switch (f) {
        case Format::u8:
            return 1;
        case Format::u16:
            return 2;
        case Format::u32:
        case Format::packed32:
            return 4;
    }
    throw std::invalid_argument("element_size: invalid Format value");
}

std::uint32_t max_distance(Format f) {
    switch (f) {
        case Format::u8:
        case Format::packed32:
            return 255u;
        case Format::u16:
            return 65535u;
        case Format::u32:
            return 0xFFFFFFFFu;
    }
    throw std::invalid_argument("max_distance: invalid Format value");
}

std::vector<std::uint8_t> encode_field(const std::vector<std::uint32_t>& distances,
                                       const World& world, const Palette& palette, Format f) {
    if (distances.size() != world.size()) {
        throw std::invalid_argument("encode_field: " + std::to_string(distances.size()) +
                                    " distances for a world of " + std::to_string(world.size()) +
                                    " voxels");
    }
    const std::size_t es = element_size(f);
    const std::uint32_t cap = max_distance(f);
    const auto table = palette.rgb332_table();
    const auto& voxels = world.voxels();
    std::vector<std::uint8_t> out(distances.size() * es);
    for (std::size_t i = 0; i < distances.size(); ++i) {
        std::uint32_t v = std::min(distances[i], cap);
        if (f == Format::packed32) {
            v = (v << 8) | table[voxels[i]];
        }
        std::uint8_t* p = out.data() + i * es;
        for (std::size_t b = 0; b < es; ++b) {
            p[b] = static_cast<std::uint8_t>(v >> (8 * b));
        }
    }
    return out;
}

std::uint32_t decode_distance(const std::vector<std::uint8_t>& field, Format f, std::size_t i) {
    const std::size_t es = element_size(f);
    if (i >= field.size() / es) {
        throw std::out_of_range("decode_distance: element " + std::to_string(i) +
                                " is outside a field of " + std::to_string(field.size() / es) +
                                " elements");
    }
    std::uint32_t v = 0;
    for (std::size_t b = 0; b < es; ++b) {
        v |= static_cast<std::uint32_t>(field[i * es + b]) << (8 * b);
    }
    if (f == Format::packed32) {
        v = (v >> 8) & 0xFFu;
    }
    return v;
}

}  // namespace voxfield
