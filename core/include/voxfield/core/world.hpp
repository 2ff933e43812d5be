#pragma once
// The voxel world: dims X,Y,Z (any size >= 1), one palette index per voxel, 0 = air.
// Linear index: x fastest, then y, then z (DESIGN §3).
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace voxfield {

struct Dims {
    std::uint32_t x = 0, y = 0, z = 0;

    std::size_t count() const { return std::size_t{x} * y * z; }
    std::size_t index(std::uint32_t px, std::uint32_t py, std::uint32_t pz) const {
        return (std::size_t{pz} * y + py) * x + px;
    }
    bool contains(std::int64_t px, std::int64_t py, std::int64_t pz) const {
        return px >= 0 && py >= 0 && pz >= 0 && px < x && py < y && pz < z;
    }
    std::string to_string() const;  // "XxYxZ"
    friend bool operator==(const Dims&, const Dims&) = default;
};

// Parses "N" (a cube) or "X,Y,Z"; throws InputError naming the text on anything else.
Dims parse_dims(const std::string& text);

class World {
  public:
    // Throws InputError if any axis is 0 or the voxel count does not fit in memory indices.
    explicit World(Dims dims);
    World(Dims dims, std::vector<std::uint8_t> voxels);  // voxels.size() must equal count

    const Dims& dims() const { return dims_; }
    std::size_t size() const { return voxels_.size(); }

    std::uint8_t at(std::uint32_t x, std::uint32_t y, std::uint32_t z) const {
        return voxels_[dims_.index(x, y, z)];
    }
    void set(std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint8_t v) {
        voxels_[dims_.index(x, y, z)] = v;
    }

    const std::vector<std::uint8_t>& voxels() const { return voxels_; }
    std::vector<std::uint8_t>& voxels() { return voxels_; }

    std::size_t solid_count() const;

  private:
    Dims dims_;
    std::vector<std::uint8_t> voxels_;
};

}  // namespace voxfield
