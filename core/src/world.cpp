// The voxel world and its dimensions (DESIGN §3: x fastest, then y, then z).
#include "voxfield/core/world.hpp"

#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "voxfield/core/error.hpp"

namespace voxfield {

std::string Dims::to_string() const {
    return std::to_string(x) + "x" + std::to_string(y) + "x" + std::to_string(z);
}

namespace {

// Parses a decimal integer in 1..2^32-1 made only of digits; false on anything else.
bool parse_axis(const std::string& text, std::uint32_t& out) {
    if (text.empty() || text.size() > 10) {
        return false;
    }
    std::uint64_t value = 0;
    for (char c : text) {
        if (c < '0' || c > '9') {
            return false;
        }
        value = value * 10 + static_cast<std::uint64_t>(c - '0');
    }
    if (value < 1 || value > std::numeric_limits<std::uint32_t>::max()) {
        return false;
    }
    out = static_cast<std::uint32_t>(value);
    return true;
}

}  // namespace

Dims parse_dims(const std::string& text) {
    std::vector<std::string> parts;
    std::size_t start = 0;
    while (true) {
        const std::size_t comma = text.find(',', start);
        parts.push_back(
            text.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
        if (comma == std::string::npos) {
            break;
        }
        start = comma + 1;
    }
    Dims dims;
    bool ok = false;
    if (parts.size() == 1) {
        ok = parse_axis(parts[0], dims.x);
        dims.y = dims.z = dims.x;
    } else if (parts.size() == 3) {
        ok = parse_axis(parts[0], dims.x) && parse_axis(parts[1], dims.y) &&
             parse_axis(parts[2], dims.z);
    }
    if (!ok) {
        throw InputError("invalid dims '" + text +
                         "': expected N or X,Y,Z with whole numbers >= 1 (e.g. 128 or 64,32,16)");
    }
    return dims;
}

namespace {

void check_dims(const Dims& dims) {
    if (dims.x == 0 || dims.y == 0 || dims.z == 0) {
        throw InputError("invalid world dims " + dims.to_string() + ": every axis must be >= 1");
    }
    // The voxel count must fit in a vector of bytes (and leave room for 4-byte fields).
    const std::size_t limit =
        static_cast<std::size_t>(std::numeric_limits<std::ptrdiff_t>::max()) / 4;
    const std::size_t xy = std::size_t{dims.x} * dims.y;  // cannot overflow 64 bits
    if (xy > limit / dims.z) {
        throw InputError("invalid world dims " + dims.to_string() + ": too many voxels");
    }
}

}  // namespace

World::World(Dims dims) : dims_(dims) {
    check_dims(dims_);
    voxels_.assign(dims_.count(), 0);
}

World::World(Dims dims, std::vector<std::uint8_t> voxels) : dims_(dims) {
    check_dims(dims_);
    if (voxels.size() != dims_.count()) {
        throw InputError("world " + dims_.to_string() + " needs " + std::to_string(dims_.count()) +
                         " voxels, got " + std::to_string(voxels.size()));
    }
    voxels_ = std::move(voxels);
}

std::size_t World::solid_count() const {
    std::size_t n = 0;
    for (std::uint8_t v : voxels_) {
        n += v != 0 ? 1u : 0u;
    }
    return n;
}

}  // namespace voxfield
