// The solid voxels of an implicit part as a dense voxel world, found by interval pruning (the
// reference blog's recursive interval test) in blocks of 16^3 and 4^3 voxels on every core.
#include <algorithm>
#include <atomic>
#include <thread>
#include <vector>

#include "voxfield/core/error.hpp"
#include "voxfield/core/sdf.hpp"

namespace voxfield::sdf {
namespace {

constexpr std::uint32_t kBlock = 16;  // outer block edge (voxels)
constexpr std::uint32_t kSub = 4;     // inner block edge

struct Filler {
    const Part& part;
    std::vector<std::uint8_t>& voxels;

    // Voxels [x0, x1) x [y0, y1) x [z0, z1), clipped to the grid: skipped when surely empty,
    // filled when surely full with a decided material, else split (edge > kSub) or sampled.
    void cells(std::uint32_t x0, std::uint32_t y0, std::uint32_t z0, std::uint32_t edge) {
        const Dims d = part.dims;
        const std::uint32_t x1 = std::min(x0 + edge, d.x), y1 = std::min(y0 + edge, d.y),
                            z1 = std::min(z0 + edge, d.z);
        const IntervalMaterial r = evaluate_interval(part.tape, part.box(x0, y0, z0, x1, y1, z1));
        if (r.value.lo > 0) {
            return;
        }
        if (r.value.hi < 0 && r.material != 0) {
            for (std::uint32_t z = z0; z < z1; ++z) {
                for (std::uint32_t y = y0; y < y1; ++y) {
                    const std::size_t row = d.index(0, y, z);
                    std::fill(voxels.begin() + static_cast<std::ptrdiff_t>(row + x0),
                              voxels.begin() + static_cast<std::ptrdiff_t>(row + x1), r.material);
                }
            }
            return;
        }
        if (edge > kSub) {
            const std::uint32_t e = edge / 4;
            for (std::uint32_t z = z0; z < z1; z += e) {
                for (std::uint32_t y = y0; y < y1; y += e) {
                    for (std::uint32_t x = x0; x < x1; x += e) {
                        cells(x, y, z, e);
                    }
                }
            }
            return;
        }
        for (std::uint32_t z = z0; z < z1; ++z) {
            for (std::uint32_t y = y0; y < y1; ++y) {
                for (std::uint32_t x = x0; x < x1; ++x) {
                    const ValueMaterial v = evaluate_material(part.tape, part.centre(x, y, z));
                    if (v.value < 0) {
                        voxels[d.index(x, y, z)] = v.material;
                    }
                }
            }
        }
    }
};

}  // namespace

World solid_world(const Part& part, const std::string& name) {
    const Dims d = part.dims;
    if (d.count() > (std::size_t{1} << 31)) {
        throw InputError(name + ": the grid of " + d.to_string() + " = " +
                         std::to_string(d.count()) +
                         " voxels is larger than a dense world may be (2^31 voxels); use a "
                         "larger voxel_size or smaller bounds");
    }
    World world(d);
    Filler filler{part, world.voxels()};
    const std::uint32_t bx = (d.x + kBlock - 1) / kBlock, by = (d.y + kBlock - 1) / kBlock,
                        bz = (d.z + kBlock - 1) / kBlock;
    const std::size_t blocks = std::size_t{bx} * by * bz;
    std::atomic<std::size_t> next{0};
    auto work = [&] {
        for (std::size_t b = next++; b < blocks; b = next++) {
            const auto x = static_cast<std::uint32_t>(b % bx);
            const auto y = static_cast<std::uint32_t>(b / bx % by);
            const auto z = static_cast<std::uint32_t>(b / bx / by);
            filler.cells(x * kBlock, y * kBlock, z * kBlock, kBlock);
        }
    };
    const unsigned n = std::max(1u, std::min(std::thread::hardware_concurrency(), 64u));
    std::vector<std::thread> threads;
    for (unsigned i = 1; i < n; ++i) {
        threads.emplace_back(work);
    }
    work();
    for (auto& t : threads) {
        t.join();
    }
    return world;
}

}  // namespace voxfield::sdf
