// Dirty tracking: disjoint pending voxel boxes and the chunks they overlap.
#include "voxfield/core/dirty.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

namespace voxfield {

namespace {

Box world_box(const Dims& d) {
    return Box{{0, 0, 0}, {d.x, d.y, d.z}};
}

Box bounding(const Box& a, const Box& b) {
    return Box{
        {std::min(a.min.x, b.min.x), std::min(a.min.y, b.min.y), std::min(a.min.z, b.min.z)},
        {std::max(a.max.x, b.max.x), std::max(a.max.y, b.max.y), std::max(a.max.z, b.max.z)}};
}

// Overlap or share a face, an edge or a corner.
bool touches(const Box& a, const Box& b) {
    return a.min.x <= b.max.x && b.min.x <= a.max.x && a.min.y <= b.max.y && b.min.y <= a.max.y &&
           a.min.z <= b.max.z && b.min.z <= a.max.z;
}

bool overlaps(const Box& a, const Box& b) {
    return !intersect(a, b).empty();
}

// The parts of `a` outside `b`, as at most 6 disjoint boxes (all of `a` when they are
// disjoint).
void subtract(const Box& a, const Box& b, std::vector<Box>& out) {
    const Box common = intersect(a, b);
    if (common.empty()) {
        out.push_back(a);
        return;
    }
    Box rest = a;
    auto cut = [&](std::int64_t Int3::*axis) {
        if (rest.min.*axis < common.min.*axis) {
            Box piece = rest;
            piece.max.*axis = common.min.*axis;
            out.push_back(piece);
            rest.min.*axis = common.min.*axis;
        }
        if (common.max.*axis < rest.max.*axis) {
            Box piece = rest;
            piece.min.*axis = common.max.*axis;
            out.push_back(piece);
            rest.max.*axis = common.max.*axis;
        }
    };
    cut(&Int3::z);
    cut(&Int3::y);
    cut(&Int3::x);
}

bool box_less(const Box& a, const Box& b) {
    return std::tie(a.min.z, a.min.y, a.min.x, a.max.z, a.max.y, a.max.x) <
           std::tie(b.min.z, b.min.y, b.min.x, b.max.z, b.max.y, b.max.x);
}

}  // namespace

DirtyTracker::DirtyTracker(const ChunkGrid& grid, double merge_slack)
    : grid_(grid), merge_slack_(merge_slack) {
    if (!(merge_slack >= 0)) {
        throw std::invalid_argument("DirtyTracker: merge_slack must be >= 0, got " +
                                    std::to_string(merge_slack));
    }
}

bool DirtyTracker::should_merge(const Box& a, const Box& b) const {
    if (!touches(a, b)) {
        return false;
    }
    const std::int64_t united = a.volume() + b.volume() - intersect(a, b).volume();
    const std::int64_t extra = bounding(a, b).volume() - united;
    return extra == 0 || static_cast<double>(extra) <= merge_slack_ * static_cast<double>(united);
}

void DirtyTracker::add(const Box& voxels) {
    const Box box = intersect(voxels, world_box(grid_.world()));
    if (box.empty()) {
        return;
    }
    insert(box);
}

void DirtyTracker::insert(Box box) {
    // 1. Grow the box over every pending region it may absorb within the slack.
    for (bool merged = true; merged;) {
        merged = false;
        for (std::size_t i = 0; i < pending_.size(); ++i) {
            if (should_merge(pending_[i], box)) {
                box = bounding(pending_[i], box);
                pending_.erase(pending_.begin() + static_cast<std::ptrdiff_t>(i));
                merged = true;
                break;
            }
        }
    }
    // 2. Keep only what no pending region covers yet.
    std::vector<Box> pieces{box}, next;
    for (const Box& r : pending_) {
        if (!overlaps(r, box)) {
            continue;
        }
        next.clear();
        for (const Box& p : pieces) {
            subtract(p, r, next);
        }
        pieces.swap(next);
    }
    // 3. Add the pieces, joining disjoint neighbours whose union is exactly a box.
    std::vector<Box> work = std::move(pieces);
    while (!work.empty()) {
        Box p = work.back();
        work.pop_back();
        bool joined = false;
        for (std::size_t i = 0; i < pending_.size(); ++i) {
            const Box& r = pending_[i];
            if (touches(r, p) && !overlaps(r, p) &&
                bounding(r, p).volume() == r.volume() + p.volume()) {
                work.push_back(bounding(r, p));
                pending_.erase(pending_.begin() + static_cast<std::ptrdiff_t>(i));
                joined = true;
                break;
            }
        }
        if (!joined) {
            pending_.push_back(p);
        }
    }
}

std::vector<Box> DirtyTracker::regions() const {
    std::vector<Box> r = pending_;
    std::sort(r.begin(), r.end(), box_less);
    return r;
}

std::int64_t DirtyTracker::pending_voxels() const {
    std::int64_t n = 0;
    for (const Box& r : pending_) {
        n += r.volume();
    }
    return n;
}

std::vector<std::size_t> DirtyTracker::dirty_chunks() const {
    std::vector<std::size_t> out;
    for (const Box& r : pending_) {
        const Box chunks = grid_.chunks_overlapping(r);
        for (std::int64_t z = chunks.min.z; z < chunks.max.z; ++z) {
            for (std::int64_t y = chunks.min.y; y < chunks.max.y; ++y) {
                for (std::int64_t x = chunks.min.x; x < chunks.max.x; ++x) {
                    out.push_back(grid_.chunk_index({x, y, z}));
                }
            }
        }
    }
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
    return out;
}

DirtyTracker::Snapshot DirtyTracker::take() {
    Snapshot s;
    s.regions = regions();
    s.chunks = dirty_chunks();
    pending_.clear();
    return s;
}

}  // namespace voxfield
