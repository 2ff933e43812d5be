// The sparse viewer's undo and redo on the device (sparse_history.hpp).
#include "sparse_history.hpp"

#include <algorithm>
#include <utility>

#include "voxfield/core/sparse.hpp"

namespace voxfield::cli {

SparseHistory::SparseHistory(ocl::Context& ctx, std::uint64_t max_bytes)
    : ctx_(ctx), max_bytes_(max_bytes) {}

void SparseHistory::clear_redo() {
    for (const Step& s : redo_) {
        bytes_ -= s.bytes;
    }
    redo_.clear();
}

SparseHistory::Part SparseHistory::gather(ocl::SparseField& field, const std::vector<Int3>& tiles) {
    Part p;
    p.tiles = tiles;
    p.voxels = ocl::cl_call("the undo history's tiles", [&] {
        return cl::Buffer(ctx_.context(), CL_MEM_READ_WRITE,
                          tiles.size() * std::size_t{kTileVoxels});
    });
    field.device_world().gather_tiles(tiles, p.voxels);
    return p;
}

void SparseHistory::before_edit(ocl::SparseField& field, const Box& bounds) {
    if (bounds.empty()) {
        return;
    }
    if (!open_) {
        clear_redo();
        undo_.emplace_back();
        open_ = true;
    }
    Step& step = undo_.back();
    std::vector<Int3> fresh;
    for (const Int3& t : tiles_overlapping(bounds)) {
        const bool seen = std::any_of(step.parts.begin(), step.parts.end(), [&](const Part& p) {
            return std::find(p.tiles.begin(), p.tiles.end(), t) != p.tiles.end();
        });
        if (!seen) {
            fresh.push_back(t);
        }
    }
    if (fresh.empty()) {
        return;
    }
    const std::uint64_t added = fresh.size() * std::uint64_t{kTileVoxels};
    step.parts.push_back(gather(field, fresh));
    step.bytes += added;
    bytes_ += added;
    drop_oldest_over_budget();
}

void SparseHistory::drop_oldest_over_budget() {
    // The step being recorded stays, whatever its size.
    while (bytes_ > max_bytes_ && undo_.size() > 1) {
        bytes_ -= undo_.front().bytes;
        undo_.pop_front();
    }
}

SparseHistory::Step SparseHistory::swap(ocl::SparseField& field, const Step& from) {
    Step now;
    for (const Part& p : from.parts) {
        now.parts.push_back(gather(field, p.tiles));
        now.bytes += p.tiles.size() * std::uint64_t{kTileVoxels};
    }
    // Every part's "now" is gathered before any is written back (a tile is in one part only).
    for (const Part& p : from.parts) {
        field.write_tiles(p.voxels, p.tiles);
    }
    return now;
}

std::optional<std::vector<Int3>> SparseHistory::replay(ocl::SparseField& field,
                                                       std::deque<Step>& from,
                                                       std::deque<Step>& to) {
    if (from.empty()) {
        return std::nullopt;
    }
    open_ = false;
    Step step = std::move(from.back());
    from.pop_back();
    Step again = swap(field, step);
    bytes_ += again.bytes;
    bytes_ -= step.bytes;
    std::vector<Int3> tiles;
    for (const Part& p : step.parts) {
        tiles.insert(tiles.end(), p.tiles.begin(), p.tiles.end());
    }
    to.push_back(std::move(again));
    return tiles;
}

std::optional<std::vector<Int3>> SparseHistory::undo(ocl::SparseField& field) {
    return replay(field, undo_, redo_);
}

std::optional<std::vector<Int3>> SparseHistory::redo(ocl::SparseField& field) {
    return replay(field, redo_, undo_);
}

}  // namespace voxfield::cli
