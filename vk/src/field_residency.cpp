// The ray marcher's field residency: device buffers, uploads, in-place updates of dirty regions
// and blocks, shared bindings (field_residency.hpp).
#include "field_residency.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <stdexcept>
#include <string>
#include <utility>

#include "march_params.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/sdf_layout.hpp"
#include "voxfield/layout.h"

namespace voxfield::vk {
namespace {

// The ray marcher's own block-minimum table (and its placeholder).
constexpr VkBufferUsageFlags kTableUsage =
    VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;

std::uint64_t round_up4(std::uint64_t v) {
    return (v + 3) / 4 * 4;
}

// The voxels in the boxes of an in-place update (`what`) of a field of `d`; a box that leaves
// the field is bad input.
std::uint64_t update_voxels(std::span<const Box> boxes, const Dims& d, const std::string& what) {
    const Box world{{0, 0, 0}, {d.x, d.y, d.z}};
    std::uint64_t voxels = 0;
    for (const Box& b : boxes) {
        if (!b.empty() && intersect(b, world) != b) {
            throw InputError(what + ": a box leaves the field of " + d.to_string());
        }
        voxels += b.empty() ? 0 : static_cast<std::uint64_t>(b.volume());
    }
    return voxels;
}

// Calls row(slab, at, length) for each x row of the boxes, in order (the order in which their
// values are staged): `at` is the row's first voxel's index in its slab of `l`.
template <class Row>
void for_each_row(std::span<const Box> boxes, const FieldLayout& l, Row&& row) {
    const Dims d = l.dims;
    const VkDeviceSize plane = VkDeviceSize{d.x} * d.y;
    for (const Box& b : boxes) {
        if (b.empty()) {
            continue;
        }
        const auto length = static_cast<VkDeviceSize>(b.max.x - b.min.x);
        for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
            const auto slab = static_cast<std::uint32_t>(z / l.slab_depth);
            const auto local = static_cast<VkDeviceSize>(z - std::int64_t{slab} * l.slab_depth);
            for (std::int64_t y = b.min.y; y < b.max.y; ++y) {
                row(slab,
                    local * plane + static_cast<VkDeviceSize>(y) * d.x +
                        static_cast<VkDeviceSize>(b.min.x),
                    length);
            }
        }
    }
}

// Appends the copy of `size` bytes from src to dst to `out`, merged into its last region where
// it continues it.
void append_copy(std::vector<VkBufferCopy>& out, VkDeviceSize src, VkDeviceSize dst,
                 VkDeviceSize size) {
    if (!out.empty() && out.back().srcOffset + out.back().size == src &&
        out.back().dstOffset + out.back().size == dst) {
        out.back().size += size;
    } else {
        out.push_back(VkBufferCopy{src, dst, size});
    }
}

}  // namespace

FieldFormat parse_field_format(const std::string& name) {
    if (name == "packed32") {
        return FieldFormat::packed32;
    }
    if (name == "compact") {
        return FieldFormat::compact;
    }
    throw InputError("unknown field format '" + name + "': use packed32 or compact");
}

std::string to_string(FieldFormat f) {
    return f == FieldFormat::packed32 ? "packed32" : "compact";
}

std::size_t element_size(FieldFormat f) {
    return f == FieldFormat::packed32 ? 4 : 2;
}

std::uint64_t FieldLayout::slab_bytes(std::uint32_t s) const {
    const std::uint64_t z0 = std::uint64_t{s} * slab_depth;
    const std::uint64_t nz = std::min<std::uint64_t>(slab_depth, dims.z - z0);
    return round_up4(std::uint64_t{dims.x} * dims.y * nz * element_size(format));
}

FieldResidency::FieldResidency(Context& ctx, VkDeviceSize max_binding)
    : ctx_(ctx), max_binding_(max_binding) {
    palette_ = ctx_.make_buffer(
        256 * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
        MemoryIntent::device_local, "palette");
    bind_block_min(no_table(), false, false);
    clear_implicit();
}

FieldLayout FieldResidency::plan(Dims d, FieldFormat format) const {
    const VkDeviceSize slice = VkDeviceSize{d.x} * d.y * element_size(format);
    if (slice > max_binding_) {
        throw InputError("world " + d.to_string() + ": one z-slice of the " + to_string(format) +
                         " field (" + std::to_string(slice) + " bytes) exceeds the Vulkan " +
                         "device's storage-buffer binding limit of " +
                         std::to_string(max_binding_) + " bytes");
    }
    FieldLayout l;
    l.format = format;
    l.dims = d;
    // max_binding is a multiple of 4, so rounding a slab up to whole words stays within it.
    l.slab_depth = static_cast<std::uint32_t>(std::min<VkDeviceSize>(d.z, max_binding_ / slice));
    l.slabs = (d.z + l.slab_depth - 1) / l.slab_depth;
    if (l.slabs > VF_RAYMARCH_MAX_SLABS) {
        throw InputError("world " + d.to_string() + " needs " + std::to_string(l.slabs) +
                         " storage-buffer bindings of at most " + std::to_string(max_binding_) +
                         " bytes for its " + to_string(format) + " field; the ray marcher has " +
                         std::to_string(VF_RAYMARCH_MAX_SLABS));
    }
    const std::uint64_t align = VF_FIELD_SLAB_ALIGN;
    l.slab_stride = (l.slab_bytes(0) + align - 1) / align * align;
    l.total_bytes = l.slab_stride * l.slabs;
    return l;
}

bool FieldResidency::read_in_flight() {
    return !ctx_.finished(last_reader_);
}

void FieldResidency::wait_for_readers() {
    ctx_.wait_for(last_reader_);
}

void FieldResidency::upload_palette(const Palette& p) {
    std::array<std::uint32_t, 256> colours{};
    for (std::size_t i = 0; i < 256; ++i) {
        colours[i] = pack_rgba(p[static_cast<std::uint8_t>(i)]);
    }
    // Frames in flight may read the old colours: those keep a buffer of their own.
    if (read_in_flight()) {
        ctx_.retire(std::move(palette_));
        palette_ = ctx_.make_buffer(
            sizeof colours, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
            MemoryIntent::device_local, "palette");
        ++generation_;
    }
    ctx_.upload(palette_, colours.data(), sizeof colours);
    coarse_ = false;              // a new field: the old minima no longer hold
    metric_ = Metric::manhattan;  // nor the old metric; manhattan's step is safe for any field
    if (block_min_shared_) {
        // It may lie in memory the new field no longer keeps alive.
        bind_block_min(no_table(), false, false);
    }
}

Dims FieldResidency::block_grid() const {
    const std::uint32_t b = VF_RAYMARCH_BLOCK;
    const Dims d = layout_.dims;
    return Dims{(d.x + b - 1) / b, (d.y + b - 1) / b, (d.z + b - 1) / b};
}

Buffer FieldResidency::no_table() {
    return ctx_.make_buffer(4, kTableUsage, MemoryIntent::device_local, "no block minima");
}

void FieldResidency::bind_block_min(Buffer table, bool coarse_now, bool shared) {
    ctx_.retire(std::move(block_min_));
    block_min_ = std::move(table);
    coarse_ = coarse_now;
    block_min_shared_ = shared;
    ++generation_;
}

void FieldResidency::install(std::vector<Buffer> new_field, std::vector<Buffer> new_material,
                             const FieldLayout& new_layout, SharingPath path) {
    // Frames in flight may still read the old buffers.
    ctx_.retire(std::move(field_));
    ctx_.retire(std::move(material_));
    field_ = std::move(new_field);
    material_ = std::move(new_material);
    layout_ = new_layout;
    sharing_ = path;
    ++generation_;
}

void FieldResidency::upload(const World& world, const Palette& palette,
                            std::span<const std::uint32_t> packed32) {
    const Dims d = world.dims();
    if (packed32.size() != d.count()) {
        throw InputError("field has " + std::to_string(packed32.size()) + " elements, the world " +
                         std::to_string(d.count()));
    }
    const FieldLayout l = plan(d, FieldFormat::packed32);
    // Built aside and installed at the end, so that a failure leaves the old world intact.
    std::vector<Buffer> field, material;
    const VkBufferUsageFlags usage =
        VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;
    const std::size_t slice_voxels = std::size_t{d.x} * d.y;
    std::uint64_t copied = 0;
    for (std::uint32_t s = 0; s < l.slabs; ++s) {
        const std::uint32_t z0 = s * l.slab_depth, nz = std::min(l.slab_depth, d.z - z0);
        const std::size_t voxels = slice_voxels * nz, first = slice_voxels * z0;
        field.push_back(ctx_.make_buffer(voxels * 4, usage, MemoryIntent::device_local,
                                         "field slab " + std::to_string(s)));
        ctx_.upload(field.back(), packed32.data() + first, voxels * 4);
        // Material bytes, padded to whole words (the padding is never read).
        const std::size_t words = (voxels + 3) / 4;
        material.push_back(ctx_.make_buffer(words * 4, usage, MemoryIntent::device_local,
                                            "material slab " + std::to_string(s)));
        std::vector<std::uint8_t> bytes(words * 4, 0);
        std::memcpy(bytes.data(), world.voxels().data() + first, voxels);
        ctx_.upload(material.back(), bytes.data(), bytes.size());
        copied += voxels * 4 + bytes.size();
    }
    upload_palette(palette);
    install(std::move(field), std::move(material), l, SharingPath::copy);
    copied_ += copied;
}

void FieldResidency::upload_compact(Dims d, const Palette& palette,
                                    std::span<const std::uint16_t> compact) {
    if (compact.size() != d.count()) {
        throw InputError("compact field has " + std::to_string(compact.size()) +
                         " elements, the world " + std::to_string(d.count()));
    }
    const FieldLayout l = plan(d, FieldFormat::compact);
    std::uint64_t copied = 0;
    std::vector<Buffer> field = copy_compact(l, compact, copied);
    upload_palette(palette);
    install(std::move(field), {}, l, SharingPath::copy);
    copied_ += copied;
}

std::vector<Buffer> FieldResidency::copy_compact(const FieldLayout& l,
                                                 std::span<const std::uint16_t> compact,
                                                 std::uint64_t& bytes) {
    std::vector<Buffer> out;
    const VkBufferUsageFlags usage = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT |
                                     VK_BUFFER_USAGE_TRANSFER_DST_BIT |
                                     VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
    const Dims d = l.dims;
    const std::size_t slice_voxels = std::size_t{d.x} * d.y;
    for (std::uint32_t s = 0; s < l.slabs; ++s) {
        const std::uint32_t z0 = s * l.slab_depth, nz = std::min(l.slab_depth, d.z - z0);
        const std::size_t voxels = slice_voxels * nz, first = slice_voxels * z0;
        out.push_back(ctx_.make_buffer(l.slab_bytes(s), usage, MemoryIntent::device_local,
                                       "compact field slab " + std::to_string(s)));
        if (voxels % 2 == 0) {
            ctx_.upload(out.back(), compact.data() + first, voxels * 2);
        } else {  // padded to a whole word (the padding is never read)
            std::vector<std::uint16_t> padded(voxels + 1, 0);
            std::memcpy(padded.data(), compact.data() + first, voxels * 2);
            ctx_.upload(out.back(), padded.data(), padded.size() * 2);
        }
        bytes += l.slab_bytes(s);
    }
    return out;
}

void FieldResidency::bind_shared(const ExternalMemory& memory, const FieldLayout& l,
                                 const Palette& palette) {
    if (l.format != FieldFormat::compact) {
        throw std::logic_error("Raymarcher::bind_shared: only the compact format is shared");
    }
    if (memory.memory() == VK_NULL_HANDLE || memory.size() < l.total_bytes) {
        throw std::logic_error("Raymarcher::bind_shared: the shared memory (" +
                               std::to_string(memory.size()) + " bytes) is smaller than the " +
                               "field layout (" + std::to_string(l.total_bytes) + " bytes)");
    }
    std::vector<Buffer> field;
    for (std::uint32_t s = 0; s < l.slabs; ++s) {
        const std::string what = "shared field slab " + std::to_string(s);
        field.push_back(ctx_.make_external_buffer(
            l.slab_bytes(s), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, memory.handle_type(), what));
        ctx_.bind(field.back(), memory.memory(), std::uint64_t{s} * l.slab_stride, what);
    }
    upload_palette(palette);
    install(std::move(field), {}, l, memory.path());
}

void FieldResidency::update_compact(std::span<const std::uint16_t> compact) {
    const Dims d = layout_.dims;
    if (compact.size() != d.count()) {
        throw InputError("compact field has " + std::to_string(compact.size()) +
                         " elements, the world " + std::to_string(d.count()));
    }
    const Box whole{{0, 0, 0}, {d.x, d.y, d.z}};
    update_compact(std::span<const Box>(&whole, 1), compact);
}

void FieldResidency::update_compact(std::span<const Box> boxes,
                                    std::span<const std::uint16_t> values) {
    if (field_.empty() || layout_.format != FieldFormat::compact || sharing_ != SharingPath::copy) {
        throw std::logic_error("Raymarcher::update_compact: the field is not a copied compact one");
    }
    const FieldLayout& l = layout_;
    const std::uint64_t voxels = update_voxels(boxes, l.dims, "compact field update");
    if (values.size() != voxels) {
        throw InputError("compact field update: " + std::to_string(values.size()) + " values for " +
                         std::to_string(voxels) + " voxels in the boxes");
    }
    if (voxels == 0) {
        return;
    }
    // One copy region per row of a box inside a slab, rows that continue each other merged
    // (a box of whole rows or slices is one region per slab).
    std::vector<std::pair<VkBuffer, std::vector<VkBufferCopy>>> regions(l.slabs);
    for (std::uint32_t s = 0; s < l.slabs; ++s) {
        regions[s].first = field_[s].get();
    }
    VkDeviceSize src = 0;
    for_each_row(boxes, l, [&](std::uint32_t slab, VkDeviceSize at, VkDeviceSize length) {
        append_copy(regions[slab].second, src, 2 * at, 2 * length);
        src += 2 * length;
    });
    copy_in_place(values.data(), 2 * voxels, regions, "compact field update");
    copied_ += 2 * voxels;
}

void FieldResidency::update_packed32(std::span<const Box> boxes,
                                     std::span<const std::uint32_t> packed32,
                                     std::span<const std::uint8_t> materials) {
    if (field_.empty() || layout_.format != FieldFormat::packed32) {
        throw std::logic_error("Raymarcher::update_packed32: the field is not a packed32 one");
    }
    const FieldLayout& l = layout_;
    const std::uint64_t voxels = update_voxels(boxes, l.dims, "packed32 field update");
    if (packed32.size() != voxels || materials.size() != voxels) {
        throw InputError("packed32 field update: " + std::to_string(packed32.size()) +
                         " values and " + std::to_string(materials.size()) + " materials for " +
                         std::to_string(voxels) + " voxels in the boxes");
    }
    if (voxels == 0) {
        return;
    }
    // Staged as the field's words, then the material bytes; one region per row of a box inside
    // a slab, in each of the slab's two buffers.
    std::vector<std::uint8_t> staged(5 * voxels);
    std::memcpy(staged.data(), packed32.data(), 4 * voxels);
    std::memcpy(staged.data() + 4 * voxels, materials.data(), voxels);
    std::vector<std::pair<VkBuffer, std::vector<VkBufferCopy>>> regions;
    for (std::uint32_t s = 0; s < l.slabs; ++s) {
        regions.push_back({field_[s].get(), {}});
    }
    for (std::uint32_t s = 0; s < l.slabs; ++s) {
        regions.push_back({material_[s].get(), {}});
    }
    VkDeviceSize n = 0;  // voxels staged so far
    for_each_row(boxes, l, [&](std::uint32_t slab, VkDeviceSize at, VkDeviceSize length) {
        append_copy(regions[slab].second, 4 * n, 4 * at, 4 * length);
        append_copy(regions[l.slabs + slab].second, 4 * voxels + n, at, length);
        n += length;
    });
    copy_in_place(staged.data(), staged.size(), regions, "packed32 field update");
    copied_ += staged.size();
}

void FieldResidency::copy_in_place(
    const void* bytes, VkDeviceSize size,
    const std::vector<std::pair<VkBuffer, std::vector<VkBufferCopy>>>& regions,
    const std::string& what) {
    Buffer staging =
        ctx_.make_buffer(size, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, MemoryIntent::upload, what);
    std::memcpy(staging.data(), bytes, size);
    ctx_.submit_unwaited(
        [&](VkCommandBuffer cmd) {
            // After the frames that read the buffers (write after read: an execution
            // dependency) and earlier copies into them (write after write).
            VkMemoryBarrier before{};
            before.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
            before.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
            before.dstAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
            vkCmdPipelineBarrier(
                cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &before, 0, nullptr, 0, nullptr);
            for (const auto& [buffer, copies] : regions) {
                if (!copies.empty()) {
                    vkCmdCopyBuffer(cmd, staging.get(), buffer,
                                    static_cast<std::uint32_t>(copies.size()), copies.data());
                }
            }
            // Before every later ray march and copy.
            VkMemoryBarrier after{};
            after.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
            after.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
            after.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_TRANSFER_READ_BIT |
                                  VK_ACCESS_TRANSFER_WRITE_BIT;
            vkCmdPipelineBarrier(
                cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &after,
                0, nullptr, 0, nullptr);
        },
        what);
    ctx_.retire(std::move(staging));  // read by the copy until it has finished
}

std::vector<std::uint16_t> FieldResidency::read_compact() {
    if (field_.empty() || layout_.format != FieldFormat::compact || sharing_ != SharingPath::copy) {
        throw std::logic_error("Raymarcher::read_compact: the field is not a copied compact one");
    }
    const FieldLayout& l = layout_;
    const Dims d = l.dims;
    const VkDeviceSize plane = VkDeviceSize{d.x} * d.y;
    Buffer readback = ctx_.make_buffer(2 * d.count() + 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                       MemoryIntent::readback, "compact field readback");
    ctx_.submit_and_wait(
        [&](VkCommandBuffer cmd) {
            VkMemoryBarrier before{};
            before.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
            before.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
            before.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
            vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                                 VK_PIPELINE_STAGE_TRANSFER_BIT, 0, 1, &before, 0, nullptr, 0,
                                 nullptr);
            for (std::uint32_t s = 0; s < l.slabs; ++s) {
                const std::uint64_t z0 = std::uint64_t{s} * l.slab_depth;
                const std::uint64_t nz = std::min<std::uint64_t>(l.slab_depth, d.z - z0);
                const VkBufferCopy c{0, 2 * z0 * plane, 2 * nz * plane};
                vkCmdCopyBuffer(cmd, field_[s].get(), readback.get(), 1, &c);
            }
            VkMemoryBarrier to_host{};
            to_host.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
            to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
            to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
            vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0,
                                 1, &to_host, 0, nullptr, 0, nullptr);
        },
        "compact field readback");
    std::vector<std::uint16_t> out(d.count());
    std::memcpy(out.data(), readback.data(), 2 * d.count());
    return out;
}

void FieldResidency::set_block_min(std::span<const std::uint32_t> block_min) {
    const Dims d = layout_.dims;
    const std::uint64_t blocks = block_grid().count();
    if (layout_.slabs == 0 || block_min.size() != blocks) {
        throw InputError("block minima: " + std::to_string(block_min.size()) +
                         " entries for a field of " + d.to_string() + " (" +
                         std::to_string(blocks) + " blocks of " +
                         std::to_string(VF_RAYMARCH_BLOCK) + "^3)");
    }
    const VkDeviceSize bytes = 4 * blocks;
    // Frames in flight may read the old table: those keep it (retired), this one gets a new one.
    if (block_min_shared_ || block_min_.size() != bytes || read_in_flight()) {
        bind_block_min(
            ctx_.make_buffer(bytes, kTableUsage, MemoryIntent::device_local, "block minima"), false,
            false);
    }
    ctx_.upload(block_min_, block_min.data(), bytes);
    coarse_ = true;
    block_min_copied_ += bytes;
}

void FieldResidency::update_block_min(std::span<const Box> blocks,
                                      std::span<const std::uint32_t> minima) {
    if (!coarse_ || block_min_shared_) {
        throw std::logic_error("Raymarcher::update_block_min without a table from set_block_min");
    }
    const Dims g = block_grid();
    const Box grid{{0, 0, 0}, {g.x, g.y, g.z}};
    std::uint64_t words = 0;
    for (const Box& b : blocks) {
        if (!b.empty() && intersect(b, grid) != b) {
            throw InputError("block minima: block box [" + std::to_string(b.min.x) + "," +
                             std::to_string(b.min.y) + "," + std::to_string(b.min.z) + ")..(" +
                             std::to_string(b.max.x) + "," + std::to_string(b.max.y) + "," +
                             std::to_string(b.max.z) + ") leaves the grid of " + g.to_string() +
                             " blocks");
        }
        words += b.empty() ? 0 : static_cast<std::uint64_t>(b.volume());
    }
    if (minima.size() != words) {
        throw InputError("block minima: " + std::to_string(minima.size()) + " entries for " +
                         std::to_string(words) + " blocks in the boxes");
    }
    if (words == 0) {
        return;
    }
    // One staged copy, one region per row of blocks (rows that continue each other merged),
    // ordered after the frames in flight that read the table by the queue: no CPU wait.
    const VkDeviceSize bytes = 4 * words;
    std::vector<VkBufferCopy> rows;
    VkDeviceSize src = 0;
    for (const Box& b : blocks) {
        if (b.empty()) {
            continue;
        }
        const VkDeviceSize row = 4 * static_cast<VkDeviceSize>(b.max.x - b.min.x);
        for (std::int64_t z = b.min.z; z < b.max.z; ++z) {
            for (std::int64_t y = b.min.y; y < b.max.y; ++y) {
                const auto first = static_cast<VkDeviceSize>((z * g.y + y) * g.x + b.min.x);
                append_copy(rows, src, 4 * first, row);
                src += row;
            }
        }
    }
    copy_in_place(minima.data(), bytes, {{block_min_.get(), rows}}, "block minima update");
    block_min_copied_ += bytes;
}

void FieldResidency::bind_shared_block_min(const ExternalMemory& memory, std::uint64_t offset) {
    if (field_.empty() || sharing_ == SharingPath::copy) {
        throw std::logic_error("Raymarcher::bind_shared_block_min: the field is not shared");
    }
    const VkDeviceSize bytes = 4 * block_grid().count();
    if (memory.memory() == VK_NULL_HANDLE || offset + bytes > memory.size()) {
        throw std::logic_error("Raymarcher::bind_shared_block_min: the table (" +
                               std::to_string(bytes) + " bytes at " + std::to_string(offset) +
                               ") does not fit in the shared memory (" +
                               std::to_string(memory.size()) + " bytes)");
    }
    Buffer table = ctx_.make_external_buffer(bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                             memory.handle_type(), "shared block minima");
    ctx_.bind(table, memory.memory(), offset, "shared block minima");
    bind_block_min(std::move(table), true, true);
}

}  // namespace voxfield::vk

namespace voxfield::vk {
namespace {

std::uint32_t popcount64(std::uint32_t lo, std::uint32_t hi) {
    return static_cast<std::uint32_t>(std::popcount(lo) + std::popcount(hi));
}

// Checks that every index in the grid stays inside its array (the shader follows them without
// bounds checks): tile roots, children, leaves' voxel records and their corners' vertices.
void check_implicit(const ImplicitSurface& s) {
    const auto bad = [](const std::string& why) { throw InputError("implicit surface: " + why); };
    if (s.tile_depth > 8) {
        bad("tile depth " + std::to_string(s.tile_depth) + " is out of range (0..8)");
    }
    const std::uint32_t edge = 1u << (2 * (s.tile_depth + 1));
    const Dims want{(s.dims.x + edge - 1) / edge, (s.dims.y + edge - 1) / edge,
                    (s.dims.z + edge - 1) / edge};
    if (s.dims.count() == 0 || !(s.tiles == want) || s.tile_table.size() != want.count()) {
        bad("the tile grid " + s.tiles.to_string() + " (" + std::to_string(s.tile_table.size()) +
            " tiles) does not cover " + s.dims.to_string() + " in tiles of " +
            std::to_string(edge) + "^3");
    }
    if (s.nodes.size() % VF_SDF_NODE_WORDS != 0 || s.voxels.size() % VF_SDF_VOXEL_WORDS != 0 ||
        s.vertices.size() % VF_SDF_VERTEX_FLOATS != 0) {
        bad("an array is not a whole number of records");
    }
    const std::size_t nodes = s.nodes.size() / VF_SDF_NODE_WORDS;
    const std::size_t voxels = s.voxels.size() / VF_SDF_VOXEL_WORDS;
    const std::size_t vertices = s.vertices.size() / VF_SDF_VERTEX_FLOATS;
    for (const std::uint32_t t : s.tile_table) {
        if (t != VF_SDF_TILE_EMPTY && t != VF_SDF_TILE_FULL && t >= nodes) {
            bad("a tile's root node " + std::to_string(t) + " is past the " +
                std::to_string(nodes) + " nodes");
        }
    }
    for (std::size_t n = 0; n < nodes; ++n) {
        const std::uint32_t* rec = &s.nodes[n * VF_SDF_NODE_WORDS];
        const std::uint64_t end = std::uint64_t{rec[0]} + popcount64(rec[2], rec[3]);
        if (rec[1] == VF_SDF_NOT_LEAF) {
            if (end > nodes) {
                bad("node " + std::to_string(n) + "'s children run past the nodes");
            }
            continue;
        }
        if (end > voxels) {
            bad("leaf " + std::to_string(n) + "'s voxel records run past the records");
        }
        for (std::uint64_t v = rec[0]; v < end; ++v) {
            const std::uint32_t* vox = &s.voxels[v * VF_SDF_VOXEL_WORDS];
            for (std::uint32_t c = 0; c < 8; ++c) {
                const std::uint32_t local = vox[c / 4] >> (8 * (c % 4)) & 0xFFu;
                if (std::uint64_t{rec[1]} + local >= vertices) {
                    bad("voxel record " + std::to_string(v) + "'s corner " + std::to_string(c) +
                        " is past the vertices");
                }
            }
        }
    }
}

}  // namespace

void FieldResidency::set_implicit(const ImplicitSurface& s) {
    check_implicit(s);
    const std::array<std::pair<const void*, std::size_t>, 4> arrays = {
        std::pair<const void*, std::size_t>{s.tile_table.data(), s.tile_table.size_bytes()},
        {s.nodes.data(), s.nodes.size_bytes()},
        {s.voxels.data(), s.voxels.size_bytes()},
        {s.vertices.data(), s.vertices.size_bytes()}};
    static constexpr const char* kNames[4] = {"implicit tile table", "implicit nodes",
                                              "implicit voxel records", "implicit vertices"};
    // Built aside: a failure keeps the current surface.
    std::array<Buffer, 4> buffers;
    std::uint64_t bytes = 0;
    for (std::size_t i = 0; i < 4; ++i) {
        const auto [data, size] = arrays[i];
        if (size > max_binding_) {
            throw InputError(std::string(kNames[i]) + " (" + std::to_string(size) +
                             " bytes) exceed the Vulkan device's storage-buffer binding limit of " +
                             std::to_string(max_binding_) + " bytes");
        }
        buffers[i] = ctx_.make_buffer(std::max<VkDeviceSize>(size, 16), kTableUsage,
                                      MemoryIntent::device_local, kNames[i]);
        if (size > 0) {
            ctx_.upload(buffers[i], data, size);
        }
        bytes += size;
    }
    for (std::size_t i = 0; i < 4; ++i) {
        ctx_.retire(std::move(implicit_[i]));  // frames in flight may still read it
        implicit_[i] = std::move(buffers[i]);
    }
    implicit_dims_ = s.dims;
    implicit_grid_ = {s.tiles.x, s.tiles.y, s.tiles.z, s.tile_depth};
    implicit_bytes_ = bytes;
    ++generation_;
}

void FieldResidency::clear_implicit() {
    for (Buffer& b : implicit_) {
        ctx_.retire(std::move(b));
        // A placeholder per binding (a vec4 for the vertices'), never read.
        b = ctx_.make_buffer(16, kTableUsage, MemoryIntent::device_local, "no implicit surface");
    }
    implicit_dims_ = Dims{0, 0, 0};
    implicit_grid_ = {};
    implicit_bytes_ = 0;
    ++generation_;
}

}  // namespace voxfield::vk
