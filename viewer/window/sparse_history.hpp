#pragma once
// Undo and redo for the sparse viewer, kept on the OpenCL device: an undo step is the tiles a
// stroke touched, each as it was before the stroke's first brush reached it, gathered on the
// device (ocl::SparseDeviceWorld::gather_tiles) into device memory. Ctrl+Z writes them back
// (ocl::SparseField::write_tiles: the world re-encoded, the field recomputed within D), having
// gathered those tiles as they are for Ctrl+Y. Nothing goes through the host.
#include <cstdint>
#include <deque>
#include <optional>
#include <vector>

#include "voxfield/cl/runtime.hpp"
#include "voxfield/cl/sparse_field.hpp"
#include "voxfield/core/chunks.hpp"

namespace voxfield::cli {

class SparseHistory {
  public:
    // At most `max_bytes` of tiles are kept (64^3 bytes each; the oldest steps go first).
    SparseHistory(ocl::Context& ctx, std::uint64_t max_bytes);

    // Closes the current undo step: the next edit starts a new one (the edits of one step, a
    // stroke, are undone together).
    void begin_step() { open_ = false; }
    // Before an edit of `bounds` (voxels): the tiles it overlaps that the current step has not
    // seen yet are gathered as they are now. The first edit of a step clears what could be
    // redone.
    void before_edit(ocl::SparseField& field, const Box& bounds);

    // Undoes the last step (nullopt when there is none): the tiles it wrote back.
    std::optional<std::vector<Int3>> undo(ocl::SparseField& field);
    // Redoes the last undone step (nullopt when there is none).
    std::optional<std::vector<Int3>> redo(ocl::SparseField& field);

    std::size_t undo_steps() const { return undo_.size(); }
    std::size_t redo_steps() const { return redo_.size(); }
    std::uint64_t bytes() const { return bytes_; }

  private:
    // Tiles and their voxels, as gather_tiles lays them out, in one or more parts.
    struct Part {
        std::vector<Int3> tiles;
        cl::Buffer voxels;
    };
    struct Step {
        std::vector<Part> parts;
        std::uint64_t bytes = 0;
    };
    Part gather(ocl::SparseField& field, const std::vector<Int3>& tiles);
    // Writes `from` back after gathering its tiles as they are into the returned step.
    Step swap(ocl::SparseField& field, const Step& from);
    // Undo (from undo_ to redo_) or redo (the other way): the last step of `from` written back,
    // the tiles as they were onto `to`. Its tiles, or nullopt when `from` is empty.
    std::optional<std::vector<Int3>> replay(ocl::SparseField& field, std::deque<Step>& from,
                                            std::deque<Step>& to);
    void drop_oldest_over_budget();
    void clear_redo();

    ocl::Context& ctx_;
    std::uint64_t max_bytes_;
    std::deque<Step> undo_, redo_;
    std::uint64_t bytes_ = 0;
    bool open_ = false;  // the last undo step takes further edits
};

}  // namespace voxfield::cli
