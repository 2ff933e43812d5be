// Procedural scenes. Floor + spheres follows the dissertation's test scene; the Menger
// sponge is the classic fractal (Menger, 1926); the city's hills are value noise (Perlin's
// lattice noise with hashed values, "An image synthesizer", SIGGRAPH 1985). Randomness:
// std::mt19937_64 with our own mappings, so every standard library gives the same worlds for a
// seed.
#include "voxfield/core/scenes.hpp"

#include "voxfield/core/sand.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
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

// ---- Terrain and city ---------------------------------------------------------------------

namespace {

constexpr std::uint8_t kBlack = 1, kRed = 4, kPink = 5, kPurple = 6, kBlue = 7, kCyan = 8,
                       kTurquoise = 9, kYellow = 11;
constexpr std::uint32_t kBlock = 64;  // city block pitch (a tile), roads along its low edges
constexpr std::uint32_t kRoad = 8;
constexpr std::uint32_t kLot = (kBlock - kRoad) / 2;  // 2 x 2 lots per block
constexpr std::uint32_t kMaxCityAxis = 1u << 20;

std::uint64_t splitmix(std::uint64_t v) {
    v += 0x9E3779B97F4A7C15ull;
    v = (v ^ (v >> 30)) * 0xBF58476D1CE4E5B9ull;
    v = (v ^ (v >> 27)) * 0x94D049BB133111EBull;
    return v ^ (v >> 31);
}

double unit_of(std::uint64_t h) {
    return static_cast<double>(h >> 11) * 0x1.0p-53;
}

double smooth(double t) {
    return t * t * (3 - 2 * t);
}

}  // namespace

// What one (x, z) column holds, bottom to top: rock, the top material, water up to the lake
// level, and a building's span.
struct CityScene::Column {
    std::uint32_t ground = 0;          // solid terrain below this y
    std::uint32_t water = 0;           // water in [ground, water)
    std::uint8_t top = 0;              // material of the terrain's top voxel
    std::uint32_t base = 0, roof = 0;  // building in [base, roof), none when equal
    std::uint8_t wall = 0;
    bool facade = false;      // on the footprint's edge: windows
    std::uint32_t along = 0;  // position along the facade, for the window pattern
    std::uint32_t level = 0;  // where the floors count from
};

std::uint64_t CityScene::hash(std::uint64_t a, std::uint64_t b, std::uint64_t c) const {
    return splitmix(seed_ ^ splitmix(a ^ splitmix(b ^ splitmix(c))));
}

// One noise cell's corner values (a noise field's last cell, reused by the next column).
struct CityScene::Corners {
    double ix = std::numeric_limits<double>::quiet_NaN(), iz = 0;
    double a = 0, b = 0, c = 0, d = 0;
};

// What one fill call reuses between columns: the terrain octaves' last cells (columns along x
// share them) and the last city block's values (its city noise and ground height).
struct CityScene::Cache {
    Corners octaves[4];
    std::int64_t bx = -1, bz = -1;
    double city = 0, block_ground = 0;
};

// Value noise in [0, 1): hashed values at the corners of `cell`-sized squares, smoothly
// interpolated; `salt` picks an independent field. `corners`: the cell last used for this
// salt and cell size (reused when the point lies in it, else replaced), or null.
double CityScene::noise(double x, double z, std::uint64_t salt, double cell,
                        Corners* corners) const {
    const double fx = x / cell, fz = z / cell;
    const double ix = std::floor(fx), iz = std::floor(fz);
    const double tx = smooth(fx - ix), tz = smooth(fz - iz);
    auto at = [&](double i, double k) {
        return unit_of(hash(salt, static_cast<std::uint64_t>(static_cast<std::int64_t>(i)),
                            static_cast<std::uint64_t>(static_cast<std::int64_t>(k))));
    };
    Corners local;
    Corners& c = corners != nullptr ? *corners : local;
    if (!(c.ix == ix && c.iz == iz)) {
        c = {ix, iz, at(ix, iz), at(ix + 1, iz), at(ix, iz + 1), at(ix + 1, iz + 1)};
    }
    const double a = c.a, b = c.b, cc = c.c, d = c.d;
    return (a + (b - a) * tx) + ((cc + (d - cc) * tx) - (a + (b - a) * tx)) * tz;
}

CityScene::CityScene(Dims dims, std::uint64_t seed) : dims_(dims), seed_(seed) {
    if (dims.x == 0 || dims.y == 0 || dims.z == 0 || dims.x > kMaxCityAxis ||
        dims.y > kMaxCityAxis || dims.z > kMaxCityAxis) {
        throw InputError("city scene: dims " + dims.to_string() + " must be 1.." +
                         std::to_string(kMaxCityAxis) + " per axis");
    }
    cell_ = std::clamp(static_cast<double>(std::max(dims.x, dims.z)) / 2, 32.0, 1024.0);
}

// The terrain's height at (x, z): four octaves of noise.
double CityScene::terrain(double x, double z, Cache* cache) const {
    const double ny = dims_.y;
    double h = 0, amp = 0.5, cell = cell_;
    for (std::uint64_t octave = 0; octave < 4; ++octave) {
        h += amp * noise(x, z, octave, cell, cache != nullptr ? &cache->octaves[octave] : nullptr);
        amp *= 0.5;
        cell *= 0.5;
    }
    return std::clamp(std::floor(ny * (0.06 + 0.3 * h)), 1.0, ny);  // h in [0, 0.94)
}

CityScene::Column CityScene::column(std::uint32_t x, std::uint32_t z, Cache& cache) const {
    const double ny = dims_.y;
    Column c;
    c.ground = static_cast<std::uint32_t>(terrain(x, z, &cache));
    const auto lake = static_cast<std::uint32_t>(std::floor(ny * 0.17));
    c.water = std::max(c.ground, std::min(lake, dims_.y));
    c.top = c.ground > ny * 0.3 ? kWhite : kGreen;
    // City: where the slow "city" noise is high, on dry land.
    const std::uint32_t bx = x / kBlock, bz = z / kBlock;
    const std::uint32_t lx = x % kBlock, lz = z % kBlock;
    const double cx = bx * double{kBlock} + kBlock / 2.0, cz = bz * double{kBlock} + kBlock / 2.0;
    if (cache.bx != bx || cache.bz != bz) {
        cache.city = noise(cx, cz, 100, 4 * cell_, nullptr);
        cache.block_ground = terrain(cx, cz, nullptr);
        cache.bx = bx;
        cache.bz = bz;
    }
    const double city = cache.city;
    const double block_ground = cache.block_ground;
    if (city < 0.45 || block_ground <= lake) {
        return c;
    }
    if (lx < kRoad || lz < kRoad) {
        c.top = kBlack;
        return c;
    }
    const std::uint32_t u = (lx - kRoad) % kLot, v = (lz - kRoad) % kLot;
    const std::uint64_t lot = hash(200 + (lx - kRoad) / kLot * 2 + (lz - kRoad) / kLot, bx, bz);
    if (unit_of(lot) < 0.2) {
        return c;  // an empty lot
    }
    auto param = [&](std::uint64_t k, std::uint32_t lo, std::uint32_t hi) {
        return lo + static_cast<std::uint32_t>(unit_of(splitmix(lot + k)) * (hi - lo + 1));
    };
    const std::uint32_t m[4] = {param(1, 2, 7), param(2, 2, 7), param(3, 2, 7), param(4, 2, 7)};
    if (u < m[0] || u >= kLot - m[1] || v < m[2] || v >= kLot - m[3]) {
        return c;
    }
    const auto base = static_cast<std::uint32_t>(std::max(1.0, block_ground - 2));
    const double tall = (city - 0.45) / 0.55 * 0.5 * ny;  // taller towards the city's core
    const auto height = static_cast<std::uint32_t>(10 + unit_of(splitmix(lot + 5)) * tall);
    c.level = base;
    c.base = std::min(c.ground, base);
    c.roof = std::min(dims_.y, base + height);
    const std::uint8_t walls[4] = {kRed, kPink, kPurple, kYellow};
    c.wall = walls[param(6, 0, 3) % 4];
    const bool edge_u = u == m[0] || u + 1 == kLot - m[1];
    const bool edge_v = v == m[2] || v + 1 == kLot - m[3];
    c.facade = edge_u || edge_v;
    c.along = edge_u ? v : u;
    // A setback tower on some: above 60% of the height only the inner footprint.
    if (unit_of(splitmix(lot + 7)) < 0.4) {
        const bool inner =
            u >= m[0] + 4 && u + 4 < kLot - m[1] && v >= m[2] + 4 && v + 4 < kLot - m[3];
        const std::uint32_t step = std::min(c.roof, base + height * 3 / 5);
        if (!inner) {
            c.roof = std::max(c.base, step);
        } else {
            const bool tower_u = u == m[0] + 4 || u + 5 == kLot - m[1];
            const bool tower_v = v == m[2] + 4 || v + 5 == kLot - m[3];
            c.facade = tower_u || tower_v;
            c.along = tower_u ? v : u;
        }
    }
    return c;
}

void CityScene::fill(const Box& box, std::span<std::uint8_t> out) const {
    const Box world{{0, 0, 0}, {dims_.x, dims_.y, dims_.z}};
    if (box.empty() || intersect(box, world) != box ||
        out.size() != static_cast<std::size_t>(box.volume())) {
        throw InputError("city scene: box [" + std::to_string(box.min.x) + ", " +
                         std::to_string(box.max.x) + ") x [" + std::to_string(box.min.y) + ", " +
                         std::to_string(box.max.y) + ") x [" + std::to_string(box.min.z) + ", " +
                         std::to_string(box.max.z) + ") with " + std::to_string(out.size()) +
                         " bytes does not fit the world " + dims_.to_string());
    }
    const auto sx = static_cast<std::size_t>(box.max.x - box.min.x);
    // Per z, the row of columns first, then the voxels row by row (sequential writes); rows
    // above every column's top are empty.
    std::vector<Column> columns(sx);
    Cache cache;
    std::uint8_t* o = out.data();
    for (std::int64_t z = box.min.z; z < box.max.z; ++z) {
        std::int64_t top = 0;  // above every column's content
        for (std::size_t i = 0; i < sx; ++i) {
            const Column& c = columns[i] =
                column(static_cast<std::uint32_t>(box.min.x) + static_cast<std::uint32_t>(i),
                       static_cast<std::uint32_t>(z), cache);
            top = std::max<std::int64_t>({top, c.ground, c.water, c.roof});
        }
        for (std::int64_t y = box.min.y; y < box.max.y; ++y, o += sx) {
            if (y >= top) {
                std::fill_n(o, sx, std::uint8_t{0});
                continue;
            }
            const auto wy = static_cast<std::uint32_t>(y);
            for (std::size_t i = 0; i < sx; ++i) {
                const Column& c = columns[i];
                std::uint8_t v = 0;
                if (wy < c.roof && wy >= c.base) {
                    const std::uint32_t floor = wy >= c.level ? (wy - c.level) % 5 : 0;
                    const bool window = c.facade && (floor == 2 || floor == 3) &&
                                        (c.along % 4 == 1 || c.along % 4 == 2) && wy >= c.level;
                    v = wy + 1 == c.roof ? kTurquoise : window ? kCyan : c.wall;
                } else if (wy + 1 == c.ground) {
                    v = c.top;
                } else if (wy < c.ground) {
                    v = kGrey;
                } else if (wy < c.water) {
                    v = kBlue;
                }
                o[i] = v;
            }
        }
    }
}

World scene_city(Dims dims, std::uint64_t seed) {
    const CityScene city(dims, seed);
    World w(dims);
    city.fill(Box{{0, 0, 0}, {dims.x, dims.y, dims.z}}, w.voxels());
    return w;
}

std::vector<std::string> scene_names() {
    return {"empty", "spheres", "terrain", "menger", "random", "sand", "city"};
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
    if (name == "city") {
        return scene_city(dims, seed);
    }
    std::string valid;
    for (const auto& n : scene_names()) {
        valid += (valid.empty() ? "" : ", ") + n;
    }
    throw InputError("unknown scene '" + name + "' (valid: " + valid + ")");
}

}  // namespace voxfield
