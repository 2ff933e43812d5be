// Chunk geometry: C-voxel cubes (C a power of two), clipped at the world's far faces.
#include "voxfield/core/chunks.hpp"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "voxfield/core/error.hpp"

namespace voxfield {

std::int64_t Box::volume() const {
    if (empty()) {
        return 0;
    }
    return (max.x - min.x) * (max.y - min.y) * (max.z - min.z);
}

Box intersect(const Box& a, const Box& b) {
    Box r;
    r.min = {std::max(a.min.x, b.min.x), std::max(a.min.y, b.min.y), std::max(a.min.z, b.min.z)};
    r.max = {std::min(a.max.x, b.max.x), std::min(a.max.y, b.max.y), std::min(a.max.z, b.max.z)};
    return r;
}

Box hull(const Box& a, const Box& b) {
    if (a.empty() || b.empty()) {
        return a.empty() ? b : a;
    }
    return Box{
        {std::min(a.min.x, b.min.x), std::min(a.min.y, b.min.y), std::min(a.min.z, b.min.z)},
        {std::max(a.max.x, b.max.x), std::max(a.max.y, b.max.y), std::max(a.max.z, b.max.z)}};
}

std::vector<Box> merge_for_launches(std::vector<Box> boxes, std::int64_t launch_voxels,
                                    std::size_t max_boxes) {
    std::erase_if(boxes, [](const Box& b) { return b.empty(); });
    max_boxes = std::max<std::size_t>(max_boxes, 1);
    if (boxes.size() > 2 * max_boxes) {
        Box all = boxes.front();
        for (const Box& b : boxes) {
            all = hull(all, b);
        }
        return {all};
    }
    // extra[i][j]: the voxels the hull of boxes i and j adds to theirs (overlaps counted twice
    // in the boxes, so it may be negative).
    const auto added = [&](std::size_t i, std::size_t j) {
        return hull(boxes[i], boxes[j]).volume() - boxes[i].volume() - boxes[j].volume();
    };
    std::vector<std::vector<std::int64_t>> extra(boxes.size(),
                                                 std::vector<std::int64_t>(boxes.size()));
    for (std::size_t i = 0; i < boxes.size(); ++i) {
        for (std::size_t j = i + 1; j < boxes.size(); ++j) {
            extra[i][j] = added(i, j);
        }
    }
    while (boxes.size() > 1) {
        std::size_t bi = 0, bj = 1;
        for (std::size_t i = 0; i < boxes.size(); ++i) {
            for (std::size_t j = i + 1; j < boxes.size(); ++j) {
                if (extra[i][j] < extra[bi][bj]) {
                    bi = i;
                    bj = j;
                }
            }
        }
        if (boxes.size() <= max_boxes && extra[bi][bj] > launch_voxels) {
            break;
        }
        boxes[bi] = hull(boxes[bi], boxes[bj]);
        boxes.erase(boxes.begin() + static_cast<std::ptrdiff_t>(bj));
        extra.erase(extra.begin() + static_cast<std::ptrdiff_t>(bj));
        for (auto& row : extra) {
            row.erase(row.begin() + static_cast<std::ptrdiff_t>(bj));
        }
        for (std::size_t k = 0; k < boxes.size(); ++k) {
            if (k != bi) {
                extra[std::min(k, bi)][std::max(k, bi)] = added(std::min(k, bi), std::max(k, bi));
            }
        }
    }
    return boxes;
}

std::int64_t floor_div(std::int64_t a, std::int64_t b) {
    if (b == 0) {
        throw std::invalid_argument("floor_div: division by zero");
    }
    std::int64_t q = a / b;
    if ((a % b != 0) && ((a < 0) != (b < 0))) {
        --q;
    }
    return q;
}

namespace {

std::uint32_t ceil_div(std::uint32_t a, std::uint32_t b) {
    return static_cast<std::uint32_t>((std::uint64_t{a} + b - 1) / b);
}

}  // namespace

ChunkGrid::ChunkGrid(Dims world, std::uint32_t chunk) : world_(world), chunk_(chunk) {
    if (chunk == 0 || (chunk & (chunk - 1)) != 0) {
        throw InputError("invalid chunk size " + std::to_string(chunk) +
                         ": must be a power of two (1, 2, 4, ..., e.g. 16)");
    }
    if (world.x == 0 || world.y == 0 || world.z == 0) {
        throw InputError("invalid world dims " + world.to_string() + ": every axis must be >= 1");
    }
    chunks_ = {ceil_div(world.x, chunk), ceil_div(world.y, chunk), ceil_div(world.z, chunk)};
}

Int3 ChunkGrid::chunk_of(Int3 voxel) const {
    const std::int64_t c = chunk_;
    return {floor_div(voxel.x, c), floor_div(voxel.y, c), floor_div(voxel.z, c)};
}

Box ChunkGrid::voxels_of(Int3 chunk) const {
    const std::int64_t c = chunk_;
    const Box raw{{chunk.x * c, chunk.y * c, chunk.z * c},
                  {(chunk.x + 1) * c, (chunk.y + 1) * c, (chunk.z + 1) * c}};
    const Box world{{0, 0, 0}, {world_.x, world_.y, world_.z}};
    return intersect(raw, world);
}

std::size_t ChunkGrid::chunk_index(Int3 chunk) const {
    if (!chunks_.contains(chunk.x, chunk.y, chunk.z)) {
        throw std::out_of_range("chunk (" + std::to_string(chunk.x) + ", " +
                                std::to_string(chunk.y) + ", " + std::to_string(chunk.z) +
                                ") is outside the chunk grid " + chunks_.to_string());
    }
    return chunks_.index(static_cast<std::uint32_t>(chunk.x), static_cast<std::uint32_t>(chunk.y),
                         static_cast<std::uint32_t>(chunk.z));
}

Box ChunkGrid::chunks_overlapping(const Box& voxels) const {
    if (voxels.empty()) {
        return Box{};
    }
    const Int3 lo = chunk_of(voxels.min);
    const Int3 hi = chunk_of({voxels.max.x - 1, voxels.max.y - 1, voxels.max.z - 1});
    const Box raw{lo, {hi.x + 1, hi.y + 1, hi.z + 1}};
    const Box grid{{0, 0, 0}, {chunks_.x, chunks_.y, chunks_.z}};
    const Box r = intersect(raw, grid);
    return r.empty() ? Box{} : r;
}

void require_chunk_fits(Dims world, std::uint32_t chunk) {
    const ChunkGrid grid(world, chunk);  // checks the power of two
    const char* axes[] = {"x", "y", "z"};
    const std::uint32_t extent[] = {world.x, world.y, world.z};
    // The largest chunk that fits: a power of two no longer than the world's shortest axis.
    const std::uint32_t fits = std::bit_floor(std::min({world.x, world.y, world.z}));
    for (int a = 0; a < 3; ++a) {
        if (chunk > extent[a]) {
            throw InputError("chunk size " + std::to_string(chunk) + " is larger than the world " +
                             world.to_string() + " along " + axes[a] + ": use --chunk " +
                             std::to_string(fits) + " or less (a power of two)");
        }
    }
}

Box focus_chunks(const ChunkGrid& grid, const Focus& focus) {
    const Dims n = grid.chunks();
    const Int3 c = focus.centre;
    if (c.x < 0 || c.y < 0 || c.z < 0 || c.x >= n.x || c.y >= n.y || c.z >= n.z) {
        throw InputError("focus centre chunk (" + std::to_string(c.x) + "," + std::to_string(c.y) +
                         "," + std::to_string(c.z) + ") is outside the chunk grid " +
                         n.to_string() + " (chunk coordinates run from 0 to " +
                         std::to_string(n.x - 1) + "," + std::to_string(n.y - 1) + "," +
                         std::to_string(n.z - 1) + ")");
    }
    if (focus.size < 0) {
        throw InputError("focus size " + std::to_string(focus.size) + " is negative");
    }
    // Beyond the grid's largest extent a larger size covers nothing more (and must not
    // overflow the box arithmetic).
    const std::int64_t s = std::min<std::int64_t>(focus.size, std::max({n.x, n.y, n.z}));
    const Box raw{{c.x - s, c.y - s, c.z - s}, {c.x + s + 1, c.y + s + 1, c.z + s + 1}};
    return intersect(raw, Box{{0, 0, 0}, {n.x, n.y, n.z}});
}

}  // namespace voxfield
