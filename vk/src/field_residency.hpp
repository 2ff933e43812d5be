#pragma once
// The ray marcher's field residency (private to vk/): the device buffers the shader reads (the
// field's slabs, packed32's material bytes, the palette, the block-minimum table), how they got
// there (copied: sharing path 3; or bound over memory OpenCL writes: paths 1/2), their in-place
// updates of dirty regions and blocks, and the metric their distances are in. It records no
// ray march: the dispatch (raymarcher.cpp) binds what it holds, re-writing its descriptors when
// generation() moved, and notes each submission that reads it (note_reader). Buffers that
// frames in flight may still read when they are replaced are retired through the Context.
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "voxfield/core/chunks.hpp"
#include "voxfield/core/metric.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/world.hpp"
#include "voxfield/vk/context.hpp"
#include "voxfield/vk/raymarcher.hpp"
#include "voxfield/vk/shared.hpp"

namespace voxfield::vk {

class FieldResidency {
  public:
    // max_binding: the most bytes one storage-buffer binding holds (a multiple of 4).
    FieldResidency(Context& ctx, VkDeviceSize max_binding);

    // As the Raymarcher members of the same names (raymarcher.hpp).
    FieldLayout plan(Dims dims, FieldFormat format) const;
    void upload(const World& world, const Palette& palette,
                std::span<const std::uint32_t> packed32);
    void upload_compact(Dims dims, const Palette& palette, std::span<const std::uint16_t> compact);
    void bind_shared(const ExternalMemory& memory, const FieldLayout& layout,
                     const Palette& palette);
    void update_compact(std::span<const Box> boxes, std::span<const std::uint16_t> values);
    void update_compact(std::span<const std::uint16_t> compact);
    void update_packed32(std::span<const Box> boxes, std::span<const std::uint32_t> packed32,
                         std::span<const std::uint8_t> materials);
    std::vector<std::uint16_t> read_compact();
    void set_block_min(std::span<const std::uint32_t> block_min);
    void update_block_min(std::span<const Box> blocks, std::span<const std::uint32_t> minima);
    void bind_shared_block_min(const ExternalMemory& memory, std::uint64_t offset);
    void set_metric(Metric m) { metric_ = m; }
    // As Raymarcher::set_implicit / clear_implicit.
    void set_implicit(const ImplicitSurface& surface);
    void clear_implicit();

    // Submission `serial` (Context::next_serial() when a ray march is recorded) reads the
    // buffers: they are replaced, not overwritten, until it has finished.
    void note_reader(std::uint64_t serial) { last_reader_ = serial; }
    // Waits on the CPU until the latest reader has finished (Raymarcher::wait_for_readers).
    void wait_for_readers();

    // What the dispatch binds. field(): one buffer per slab; material(): packed32's, one per
    // slab (empty for compact). generation() changes whenever one of these buffers is replaced.
    bool empty() const { return field_.empty(); }
    const std::vector<Buffer>& field() const { return field_; }
    const std::vector<Buffer>& material() const { return material_; }
    const Buffer& palette() const { return palette_; }
    const Buffer& block_min() const { return block_min_; }
    std::uint64_t generation() const { return generation_; }
    // The table holds the current field's minima (the shader may use them); it lies in the
    // shared field's memory (path 1: acquired from the external queue family with the field).
    bool coarse() const { return coarse_; }
    bool block_min_shared() const { return block_min_shared_; }
    const FieldLayout& layout() const { return layout_; }
    SharingPath sharing() const { return sharing_; }
    Metric metric() const { return metric_; }
    std::uint64_t bytes_copied() const { return copied_; }
    std::uint64_t block_min_bytes_copied() const { return block_min_copied_; }
    // The implicit surface's buffers (tile table, nodes, voxel records, vertices; one
    // placeholder word each without a surface), whether one is held and applies to the
    // current field (same dims), its tile grid (tiles x, y, z, tile depth) and device bytes.
    const std::array<Buffer, 4>& implicit_buffers() const { return implicit_; }
    bool has_implicit() const { return implicit_dims_.count() > 0; }
    bool implicit_active() const { return has_implicit() && implicit_dims_ == layout_.dims; }
    const std::array<std::uint32_t, 4>& implicit_grid() const { return implicit_grid_; }
    std::uint64_t implicit_bytes() const { return implicit_bytes_; }

  private:
    // Whether a submission that reads the buffers may not have finished (no wait).
    bool read_in_flight();
    void upload_palette(const Palette& p);
    // The number of blocks of the current field (layout.h VF_RAYMARCH_BLOCK).
    Dims block_grid() const;
    // The placeholder bound while there is no table: one word, never read.
    Buffer no_table();
    // Takes `table` as the block-minimum binding; the old table is retired.
    void bind_block_min(Buffer table, bool coarse_now, bool shared);
    // Copies a compact field into new device-local slabs laid out as `l`; adds their size to
    // `bytes`.
    std::vector<Buffer> copy_compact(const FieldLayout& l, std::span<const std::uint16_t> compact,
                                     std::uint64_t& bytes);
    // Copies `bytes` (staged) into the buffers at the given regions, after every earlier use of
    // the buffers in queue order (frames in flight read them, earlier copies wrote them) and
    // before every later one, without a CPU wait.
    void copy_in_place(const void* bytes, VkDeviceSize size,
                       const std::vector<std::pair<VkBuffer, std::vector<VkBufferCopy>>>& regions,
                       const std::string& what);
    // Takes the new field buffers (the old ones are retired).
    void install(std::vector<Buffer> new_field, std::vector<Buffer> new_material,
                 const FieldLayout& new_layout, SharingPath path);

    Context& ctx_;
    VkDeviceSize max_binding_;
    Buffer palette_;  // 256 colours
    // A buffer of the ray marcher's own (copied), one over the shared field's memory (written
    // by OpenCL), or, while there is no table, a placeholder word that is never read.
    Buffer block_min_;
    bool coarse_ = false;
    bool block_min_shared_ = false;
    std::uint64_t block_min_copied_ = 0;
    Metric metric_ = Metric::manhattan;
    std::vector<Buffer> field_, material_;  // material: packed32 only
    FieldLayout layout_;
    SharingPath sharing_ = SharingPath::copy;
    std::uint64_t copied_ = 0;
    std::uint64_t last_reader_ = 0;  // the serial of the latest submission that reads them
    std::uint64_t generation_ = 0;
    std::array<Buffer, 4> implicit_;
    Dims implicit_dims_{0, 0, 0};
    std::array<std::uint32_t, 4> implicit_grid_{};
    std::uint64_t implicit_bytes_ = 0;
};

}  // namespace voxfield::vk
