// Output formats of a distance field and their exact encoding (DESIGN §3: saturate, never
// wrap; packed32 is the dissertation's (min(d,255) << 8) | rgb332 layout).
#include "voxfield/core/format.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "voxfield/core/error.hpp"

namespace voxfield {

namespace {

struct FormatInfo {
    Format format;
    const char* name;
    std::size_t size;
    std::uint32_t max;  // 0 for floats
};

constexpr FormatInfo kFormats[] = {
    {Format::u8, "u8", 1, 255u},          {Format::u16, "u16", 2, 65535u},
    {Format::u32, "u32", 4, 0xFFFFFFFFu}, {Format::packed32, "packed32", 4, 255u},
    {Format::i8, "i8", 1, 127u},          {Format::i16, "i16", 2, 32767u},
    {Format::i32, "i32", 4, 0x7FFFFFFFu}, {Format::f32, "f32", 4, 0u},
    {Format::f64, "f64", 8, 0u},
};

const FormatInfo& info(Format f) {
    for (const FormatInfo& i : kFormats) {
        if (i.format == f) {
            return i;
        }
    }
    throw std::invalid_argument("invalid Format value");
}

void store_le(std::uint8_t* p, std::uint64_t v, std::size_t bytes) {
    for (std::size_t b = 0; b < bytes; ++b) {
        p[b] = static_cast<std::uint8_t>(v >> (8 * b));
    }
}

std::uint64_t load_le(const std::uint8_t* p, std::size_t bytes) {
    std::uint64_t v = 0;
    for (std::size_t b = 0; b < bytes; ++b) {
        v |= static_cast<std::uint64_t>(p[b]) << (8 * b);
    }
    return v;
}

}  // namespace

const std::vector<std::string>& format_names() {
    static const std::vector<std::string> names = [] {
        std::vector<std::string> v;
        for (const FormatInfo& i : kFormats) {
            v.emplace_back(i.name);
        }
        return v;
    }();
    return names;
}

Format parse_format(const std::string& name) {
    std::string valid;
    for (const FormatInfo& i : kFormats) {
        if (name == i.name) {
            return i.format;
        }
        valid += (valid.empty() ? "" : ", ") + std::string(i.name);
    }
    throw InputError("unknown format '" + name + "' (valid: " + valid + ")");
}

std::string to_string(Format f) {
    return info(f).name;
}

std::size_t element_size(Format f) {
    return info(f).size;
}

bool is_float(Format f) {
    return f == Format::f32 || f == Format::f64;
}

bool holds_sign(Format f) {
    return f == Format::i8 || f == Format::i16 || f == Format::i32 || is_float(f);
}

std::uint32_t max_distance(Format f) {
    if (is_float(f)) {
        throw std::invalid_argument("max_distance: " + to_string(f) + " is a float format");
    }
    return info(f).max;
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
        store_le(out.data() + i * es, v, es);
    }
    return out;
}

std::vector<std::uint8_t> encode_real_field(const std::vector<double>& distances,
                                            const World& world, const Palette& palette, Format f) {
    if (distances.size() != world.size()) {
        throw std::invalid_argument("encode_real_field: " + std::to_string(distances.size()) +
                                    " distances for a world of " + std::to_string(world.size()) +
                                    " voxels");
    }
    const std::size_t es = element_size(f);
    const auto table = palette.rgb332_table();
    const auto& voxels = world.voxels();
    std::vector<std::uint8_t> out(distances.size() * es);
    for (std::size_t i = 0; i < distances.size(); ++i) {
        const double d = distances[i];
        std::uint8_t* p = out.data() + i * es;
        if (f == Format::f32) {
            const float v = static_cast<float>(d);
            std::uint32_t bits = 0;
            std::memcpy(&bits, &v, 4);
            store_le(p, bits, 4);
        } else if (f == Format::f64) {
            std::uint64_t bits = 0;
            std::memcpy(&bits, &d, 8);
            store_le(p, bits, 8);
        } else if (holds_sign(f)) {
            const double cap = max_distance(f);
            const double t = std::clamp(std::trunc(d), -cap, cap);
            store_le(p, static_cast<std::uint64_t>(static_cast<std::int64_t>(t)), es);
        } else {
            const double cap = max_distance(f);
            auto v = static_cast<std::uint32_t>(std::clamp(std::floor(d), 0.0, cap));
            if (f == Format::packed32) {
                v = (v << 8) | table[voxels[i]];
            }
            store_le(p, v, es);
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
    auto v = static_cast<std::uint32_t>(load_le(field.data() + i * es, es));
    if (f == Format::packed32) {
        v = (v >> 8) & 0xFFu;
    }
    return v;
}

double decode_value(const std::vector<std::uint8_t>& field, Format f, std::size_t i) {
    const std::size_t es = element_size(f);
    if (i >= field.size() / es) {
        throw std::out_of_range("decode_value: element " + std::to_string(i) +
                                " is outside a field of " + std::to_string(field.size() / es) +
                                " elements");
    }
    const std::uint64_t bits = load_le(field.data() + i * es, es);
    switch (f) {
        case Format::f32: {
            float v = 0;
            const auto b32 = static_cast<std::uint32_t>(bits);
            std::memcpy(&v, &b32, 4);
            return v;
        }
        case Format::f64: {
            double v = 0;
            std::memcpy(&v, &bits, 8);
            return v;
        }
        case Format::i8:
            return static_cast<std::int8_t>(bits);
        case Format::i16:
            return static_cast<std::int16_t>(bits);
        case Format::i32:
            return static_cast<std::int32_t>(bits);
        case Format::packed32:
            return static_cast<double>((bits >> 8) & 0xFFu);
        case Format::u8:
        case Format::u16:
        case Format::u32:
            return static_cast<double>(bits);
    }
    throw std::invalid_argument("decode_value: invalid Format value");
}

}  // namespace voxfield
