// Procedural scenes. Floor + spheres follows the dissertation's test scene; the Menger
// sponge is the classic fractal (Menger, 1926). Randomness: std::mt19937_64 with our own
// mappings, so every standard library gives the same worlds for a seed.
#include "voxfield/core/scenes.hpp"

#include "voxfield/core/sand.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "voxfield/core/error.hpp"

namespace voxfield {

namespace {

class Rng {
  public:
    explicit Rng(std::uint64_t seed) : gen_(seed) {}
    // Uniform integer in [lo, hi] (inclusive), by the multiply-shift mapping.
    std::int64_t range(std::int64_t lo, std::int64_t hi) {
        const auto span = static_cast<std::uint64_t>(hi - lo) + 1;
        const auto wide = static_cast<unsigned __int128>(gen_()) * span;
        return lo + static_cast<std::int64_t>(static_cast<std::uint64_t>(wide >> 64));
    }
    // Uniform double in [0, 1) from the top 53 bits.
    double unit() { return static_cast<double>(gen_() >> 11) * 0x1.0p-53; }

  private:
    std::mt19937_64 gen_;
};

// Dissertation colour ids (seed-code-notes): 1 Black .. 11 Yellow.
constexpr std::uint8_t kGrey = 3, kGreen = 10, kWhite = 2;

}  // namespace

World scene_empty(Dims dims) {
    return World(dims);
}

World scene_floor_spheres(Dims dims, std::uint64_t seed, std::uint32_t spheres) {
    World w(dims);
    for (std::uint32_t z = 0; z < dims.z; ++z) {
        for (std::uint32_t x = 0; x < dims.x; ++x) {
            w.set(x, 0, z, kGrey);
        }
    }
    Rng rng(seed);
    const std::int64_t min_dim = std::min({dims.x, dims.y, dims.z});
    const std::int64_t max_r = std::max<std::int64_t>(1, min_dim / 8);
    for (std::uint32_t s = 0; s < spheres; ++s) {
        const std::int64_t cx = rng.range(0, dims.x - 1);
        const std::int64_t cy = rng.range(0, dims.y - 1);
        const std::int64_t cz = rng.range(0, dims.z - 1);
        const std::int64_t r = rng.range(1, max_r);
        const auto colour = static_cast<std::uint8_t>(rng.range(1, 11));
        const std::int64_t x0 = std::max<std::int64_t>(0, cx - r);
        const std::int64_t x1 = std::min<std::int64_t>(dims.x - 1, cx + r);
        const std::int64_t y0 = std::max<std::int64_t>(0, cy - r);
        const std::int64_t y1 = std::min<std::int64_t>(dims.y - 1, cy + r);
        const std::int64_t z0 = std::max<std::int64_t>(0, cz - r);
        const std::int64_t z1 = std::min<std::int64_t>(dims.z - 1, cz + r);
        for (std::int64_t z = z0; z <= z1; ++z) {
            for (std::int64_t y = y0; y <= y1; ++y) {
                for (std::int64_t x = x0; x <= x1; ++x) {
                    const std::int64_t dx = x - cx, dy = y - cy, dz = z - cz;
                    if (dx * dx + dy * dy + dz * dz <= r * r) {
                        w.set(static_cast<std::uint32_t>(x), static_cast<std::uint32_t>(y),
                              static_cast<std::uint32_t>(z), colour);
                    }
                }
            }
        }
    }
    return w;
}

World scene_terrain(Dims dims, std::uint64_t seed) {
    World w(dims);
    Rng rng(seed);
    constexpr double kTwoPi = 6.283185307179586;
    struct Wave {
        double fx, fz, phase, amp;
    };
    std::vector<Wave> waves;
    double amp = 0.25;
    for (int k = 0; k < 4; ++k) {
        // Between 0.5 and 2.5 periods across the world per octave, doubling each octave.
        const double scale = static_cast<double>(1 << k);
        const double px = (0.5 + 2.0 * rng.unit()) * scale;
        const double pz = (0.5 + 2.0 * rng.unit()) * scale;
        waves.push_back({kTwoPi * px / dims.x, kTwoPi * pz / dims.z, kTwoPi * rng.unit(), amp});
        amp *= 0.5;
    }
    const double ny = dims.y;
    for (std::uint32_t z = 0; z < dims.z; ++z) {
        for (std::uint32_t x = 0; x < dims.x; ++x) {
            double h = 0.4;
            for (const Wave& wv : waves) {
                h += wv.amp * std::sin(wv.fx * x + wv.fz * z + wv.phase);
            }
            const double top = std::clamp(std::floor(h * ny), 1.0, ny);
            const auto height = static_cast<std::uint32_t>(top);
            for (std::uint32_t y = 0; y < height; ++y) {
                const bool surface = y + 1 == height;
                w.set(x, y, z, surface ? (height > ny * 0.7 ? kWhite : kGreen) : kGrey);
            }
        }
    }
    return w;
}

World scene_menger(Dims dims) {
    World w(dims);
    const std::uint32_t min_dim = std::min({dims.x, dims.y, dims.z});
    std::uint32_t level = 0;
    std::uint64_t side = 1;  // 3^level
    while (side * 3 <= min_dim) {
        side *= 3;
        ++level;
    }
    // Voxel (x, y, z) samples sponge cell (x * side / X, ...), so the sponge fills the world.
    auto cell = [side](std::uint32_t p, std::uint32_t n) {
        return static_cast<std::uint64_t>(p) * side / n;
    };
    for (std::uint32_t z = 0; z < dims.z; ++z) {
        for (std::uint32_t y = 0; y < dims.y; ++y) {
            for (std::uint32_t x = 0; x < dims.x; ++x) {
                std::uint64_t cx = cell(x, dims.x), cy = cell(y, dims.y), cz = cell(z, dims.z);
                bool hole = false;
                for (std::uint32_t l = 0; l < level && !hole; ++l) {
                    const int ones = (cx % 3 == 1) + (cy % 3 == 1) + (cz % 3 == 1);
                    hole = ones >= 2;
                    cx /= 3;
                    cy /= 3;
                    cz /= 3;
                }
                if (!hole) {
                    w.set(x, y, z, kGrey);
                }
            }
        }
    }
    return w;
}

World scene_random(Dims dims, double density, std::uint64_t seed) {
    if (!(density >= 0.0 && density <= 1.0)) {
        std::ostringstream text;
        text << density;
        throw InputError("random scene: density " + text.str() + " is outside [0, 1]");
    }
    World w(dims);
    Rng rng(seed);
    for (auto& v : w.voxels()) {
        const bool solid = rng.unit() < density;
        const auto colour = static_cast<std::uint8_t>(rng.range(1, 255));
        v = solid ? colour : 0;
    }
    return w;
}

std::vector<std::string> scene_names() {
    return {"empty", "spheres", "terrain", "menger", "random", "sand"};
}

World make_scene(const std::string& name, Dims dims, std::uint64_t seed) {
    if (name == "empty") {
        return scene_empty(dims);
    }
    if (name == "spheres") {
        return scene_floor_spheres(dims, seed);
    }
    if (name == "terrain") {
        return scene_terrain(dims, seed);
    }
    if (name == "menger") {
        return scene_menger(dims);
    }
    if (name == "random") {
        return scene_random(dims, 0.1, seed);
    }
    if (name == "sand") {
        return scene_sand(dims, seed);
    }
    std::string valid;
    for (const auto& n : scene_names()) {
        valid += (valid.empty() ? "" : ", ") + n;
    }
    throw InputError("unknown scene '" + name + "' (valid: " + valid + ")");
}

}  // namespace voxfield
