// Viewer editing logic: brushes from picks, scroll sizes, undo/redo of strokes, and the
// dissertation's benchmark edits (seed-code-notes.md, "Benchmark mode") made reproducible.
#include "voxfield/core/undo.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include "voxfield/core/error.hpp"

namespace voxfield {

std::string to_string(Tool tool) {
    switch (tool) {
        case Tool::place:
            return "place";
        case Tool::erase:
            return "erase";
        case Tool::paint:
            return "paint";
    }
    return "?";
}

std::optional<Brush> brush_for_pick(Tool tool, const BrushSettings& settings, const PickHit& hit) {
    Brush b;
    b.shape = settings.shape;
    b.radius = std::max<std::int64_t>(settings.size, 1) / 2;
    b.material = settings.material == 0 ? std::uint8_t{1} : settings.material;
    b.centre = hit.voxel;
    switch (tool) {
        case Tool::place:
            if (hit.normal == Int3{0, 0, 0}) {
                return std::nullopt;
            }
            b.op = BrushOp::place;
            b.centre = {hit.voxel.x + hit.normal.x, hit.voxel.y + hit.normal.y,
                        hit.voxel.z + hit.normal.z};
            break;
        case Tool::erase:
            b.op = BrushOp::erase;
            break;
        case Tool::paint:
            b.op = BrushOp::paint;
            break;
    }
    return b;
}

std::int64_t scroll_brush_size(std::int64_t size, double scroll, std::int64_t max_size) {
    if (!std::isfinite(scroll)) {
        scroll = 0;
    }
    const double next = double(size) + std::round(scroll);
    return static_cast<std::int64_t>(
        std::clamp(next, 1.0, double(std::max<std::int64_t>(1, max_size))));
}

EditResult apply_changes(World& world, const VoxelChanges& changes) {
    for (const VoxelChange& c : changes) {
        if (c.index >= world.size()) {
            throw InputError("undo: voxel index " + std::to_string(c.index) +
                             " is outside the world " + world.dims().to_string());
        }
        if (world.voxels()[c.index] != c.before) {
            throw InputError("undo: voxel " + std::to_string(c.index) + " holds " +
                             std::to_string(world.voxels()[c.index]) + ", expected " +
                             std::to_string(c.before) + " (the world changed outside the stack)");
        }
    }
    const Dims d = world.dims();
    const auto grow = [](Box& box, const Int3& p) {
        if (box.empty()) {
            box = Box{p, {p.x + 1, p.y + 1, p.z + 1}};
            return;
        }
        box.min = {std::min(box.min.x, p.x), std::min(box.min.y, p.y), std::min(box.min.z, p.z)};
        box.max = {std::max(box.max.x, p.x + 1), std::max(box.max.y, p.y + 1),
                   std::max(box.max.z, p.z + 1)};
    };
    EditResult result;
    for (const VoxelChange& c : changes) {
        if (c.before == c.after) {
            continue;
        }
        world.voxels()[c.index] = c.after;
        result.changes.push_back(c);
        const Int3 p{static_cast<std::int64_t>(c.index % d.x),
                     static_cast<std::int64_t>(c.index / d.x % d.y),
                     static_cast<std::int64_t>(c.index / d.x / d.y)};
        grow(result.bounds, p);
        if (c.before == 0) {
            ++result.became_solid;
            grow(result.occupancy_bounds, p);
        } else if (c.after == 0) {
            ++result.became_empty;
            grow(result.occupancy_bounds, p);
        } else {
            ++result.recoloured;
        }
    }
    const auto by_index = [](const VoxelChange& a, const VoxelChange& b) {
        return a.index < b.index;
    };
    // Often ascending already (a falling-sand step's list): then checking is all it costs.
    if (!std::is_sorted(result.changes.begin(), result.changes.end(), by_index)) {
        std::sort(result.changes.begin(), result.changes.end(), by_index);
    }
    return result;
}

UndoStack::UndoStack(std::size_t max_strokes, std::size_t max_voxels)
    : max_strokes_(std::max<std::size_t>(1, max_strokes)), max_voxels_(max_voxels) {}

void UndoStack::begin_stroke() {
    if (open_) {
        end_stroke();
    }
    open_ = true;
    current_.clear();
}

void UndoStack::record(const EditResult& result) {
    if (!open_) {
        begin_stroke();
    }
    for (const VoxelChange& c : result.changes) {
        auto [it, inserted] = current_.try_emplace(c.index, c);
        if (!inserted) {
            it->second.after = c.after;
        }
    }
}

bool UndoStack::end_stroke() {
    if (!open_) {
        return false;
    }
    open_ = false;
    VoxelChanges stroke;
    stroke.reserve(current_.size());
    for (const auto& [index, c] : current_) {
        if (c.before != c.after) {
            stroke.push_back(c);
        }
    }
    current_.clear();
    if (stroke.empty()) {
        return false;
    }
    for (const auto& r : redo_) {
        voxels_ -= r.size();
    }
    redo_.clear();
    voxels_ += stroke.size();
    undo_.push_back(std::move(stroke));
    trim();
    return true;
}

void UndoStack::trim() {
    while (undo_.size() > 1 && (undo_.size() > max_strokes_ || voxels_ > max_voxels_)) {
        voxels_ -= undo_.front().size();
        undo_.pop_front();
    }
}

VoxelChanges UndoStack::undo() {
    end_stroke();
    if (undo_.empty()) {
        return {};
    }
    VoxelChanges stroke = std::move(undo_.back());
    undo_.pop_back();
    VoxelChanges inverse = stroke;
    for (VoxelChange& c : inverse) {
        std::swap(c.before, c.after);
    }
    redo_.push_back(std::move(stroke));
    return inverse;
}

VoxelChanges UndoStack::redo() {
    end_stroke();
    if (redo_.empty()) {
        return {};
    }
    VoxelChanges stroke = std::move(redo_.back());
    redo_.pop_back();
    VoxelChanges forward = stroke;
    undo_.push_back(std::move(stroke));
    return forward;
}

void UndoStack::clear() {
    open_ = false;
    current_.clear();
    undo_.clear();
    redo_.clear();
    voxels_ = 0;
}

RandomEdits::RandomEdits(Dims dims, std::uint32_t chunk, std::uint64_t seed)
    : dims_(dims), chunk_(chunk), state_(seed) {
    if (chunk < 2) {
        throw InputError("benchmark edits need a chunk size >= 2 (sizes are 1..chunk-1), got " +
                         std::to_string(chunk));
    }
}

std::uint64_t RandomEdits::below(std::uint64_t n) {
    // splitmix64 (Steele, Lea & Flood 2014), then Lemire's multiply-shift range reduction.
    state_ += 0x9E3779B97F4A7C15ull;
    std::uint64_t z = state_;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return static_cast<std::uint64_t>((static_cast<unsigned __int128>(z) * n) >> 64);
}

Brush RandomEdits::next() {
    Brush b;
    b.shape = BrushShape::sphere;
    b.centre = {static_cast<std::int64_t>(below(dims_.x)),
                static_cast<std::int64_t>(below(dims_.y)),
                static_cast<std::int64_t>(below(dims_.z))};
    const std::int64_t size = 1 + static_cast<std::int64_t>(below(chunk_ - 1));
    last_size_ = size;
    b.radius = size / 2;
    const auto material = static_cast<std::uint8_t>(below(12));
    if (material == 0) {
        b.op = BrushOp::erase;
        b.material = 1;
    } else {
        b.op = BrushOp::place;
        b.material = material;
    }
    return b;
}

}  // namespace voxfield
