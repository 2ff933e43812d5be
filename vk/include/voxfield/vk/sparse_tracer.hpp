#pragma once
// Ray tracing of sparse worlds (core/sparse.hpp's tile grid of 64-trees) by
// vk/shaders/sparse_trace.comp into an offscreen image read back as RGBA8: one hierarchical
// Amanatides & Woo walk per ray over blocks of 8^3 tiles, tiles, 16^3 nodes, 4^3 nodes and
// voxels, leaving every empty node in one step. The camera, options and image are the ray
// marcher's (raymarcher.hpp); flat shading writes the hit voxel's palette colour exactly, pixel
// for pixel the dense ray marcher's image of the same world. Lit shading: the ray marcher's
// face normal, sun and ambient terms, shadows by a ray traced toward the sun through the same
// walk, ambient occlusion from 20 voxel look-ups in the 64-trees (not a distance field).
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "voxfield/core/palette.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/vk/context.hpp"
#include "voxfield/vk/raymarcher.hpp"
#include "voxfield/vk/shared.hpp"

namespace voxfield::vk {

// `render`'s default camera for a sparse world: the ray marcher's framing (core's
// framing_position, from the front-left and above the -z side) of the box of the world's solid
// voxels (the union of its tiles' solid bounds; the whole world when it has none), for a width x
// height image.
Camera default_camera(const SparseWorld& world, std::uint32_t width, std::uint32_t height,
                      double fov_deg = 60);

// What an upload put on the device.
struct SparseDeviceStats {
    std::uint64_t bytes = 0;  // every buffer of the tracer's own that it reads
    // Trees read in place (upload_shared): the memory of their sets, not the tracer's.
    std::uint64_t shared_bytes = 0;
    std::uint32_t node_chunks = 0, material_chunks = 0;
    std::uint64_t blocks = 0, pages = 0;  // block table entries, pages of tile indices
    // The edit arena (update_tiles): tiles whose trees live there, its nodes and material
    // bytes in use (live and superseded) and its capacity; arena_node_chunk is VF_SPARSE_NONE
    // while there is no arena.
    std::uint32_t arena_tiles = 0, arena_node_chunk = 0xFFFFFFFFu;
    std::uint64_t arena_nodes = 0, arena_material_bytes = 0;
    std::uint64_t arena_node_capacity = 0, arena_material_capacity = 0;
};

// Buffer usage of memory the tracer reads trees from in place (ExternalMemory for upload_shared).
inline constexpr VkBufferUsageFlags kSharedTreeUsage =
    VK_BUFFER_USAGE_SHADER_DEVICE_ADDRESS_BIT | VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;

// One set of core's three tree buffers (node masks, node offsets, materials, as in
// core/sparse.hpp) in memory that another API writes (OpenCL: pipeline/shared_trees.hpp), made
// with kSharedTreeUsage. Null: a set without memory (no tile points into it). `serials`: per
// buffer a number its owner never gives other memory (handles and addresses may be reused once
// memory is freed); the tracer makes its views again when they change.
struct SharedTreeSet {
    const ExternalMemory* masks = nullptr;
    const ExternalMemory* offsets = nullptr;
    const ExternalMemory* materials = nullptr;
    std::array<std::uint64_t, 3> serials{};
};

// Where one stored tile's 64-tree lies: in set `set`, its root at node `node`, its first
// material at byte `material` (node offsets tile-relative, as core lays a tile out).
struct SharedTile {
    Int3 tile;
    std::uint32_t set = 0;
    std::uint64_t node = 0, material = 0;
};

// What one update_tiles or repoint did.
struct SparseTileUpdate {
    // Tiles whose 64-tree was written into the edit arena (repoint: whose record now points at
    // their tree's new place).
    std::uint32_t tiles_written = 0;
    std::uint32_t tiles_removed = 0;  // tiles taken out of the directory (now empty)
    std::uint32_t tiles_added = 0;    // tiles new to the directory (of tiles_written)
    // repoint: tiles whose records were written again because their set's memory was replaced.
    std::uint32_t tiles_moved = 0;
    std::uint64_t bytes = 0;     // bytes copied from the host to the device
    bool arena_rebuilt = false;  // the arena was (re)made: its live tiles written again
    bool whole = false;          // the world was uploaded whole instead
};

class SparseTracer {
  public:
    // max_binding_bytes: cut nodes and materials into chunks of at most this many bytes (0: the
    // device's maxStorageBufferRange), the directory's buffers too. Tests lower it to exercise
    // the cut. DeviceSelectionError when the context has no buffer device addresses
    // (Context::buffer_device_address: VK_KHR_buffer_device_address and its feature).
    explicit SparseTracer(Context& ctx, std::uint64_t max_binding_bytes = 0);
    ~SparseTracer();
    SparseTracer(const SparseTracer&) = delete;
    SparseTracer& operator=(const SparseTracer&) = delete;

    // Copies the world's 64-trees (its buffers as they are, cut at tile boundaries into chunks
    // of one binding each, any number of them, read through device addresses), a directory of
    // its tiles (sparse_trace_layout.h) and the palette onto the device. Throws InputError when
    // a tile exceeds one binding, or the block table, the pages or the tile records do; the
    // message says the limit.
    void upload(const SparseWorld& world, const Palette& palette);

    // After the voxels of `changed` were edited in the uploaded world (`world`: the same world,
    // its edits stored: SparseWorld::edit / put_tile, or ocl::SparseField::world()), makes the
    // device copy equal a fresh upload of it without uploading it whole: every tile the box
    // overlaps is written again from `world`, its new 64-tree appended to the edit arena (an
    // extra node chunk and material chunk, grown by doubling, its superseded trees dropped when
    // it grows), its directory entry repointed, added (a page made for a block that had none)
    // or removed (the page freed when it empties). Only when the arena's live trees would
    // exceed one binding the world is uploaded whole. The bytes are staged on the host and
    // copied in the next trace's submission, before its dispatch (no submission of their own;
    // a second update before that trace submits the first's copies first).
    // logic_error before an upload or for a world of other dims. After another exception the
    // tracer traces nothing until an upload.
    SparseTileUpdate update_tiles(const SparseWorld& world, const Box& changed);

    // Like upload, but the trees are read in place in `sets` (memory OpenCL writes, shared with
    // this device): nothing of the trees is copied; the tracer's own buffers are the directory
    // (`tiles`: every stored tile of a world of `dims`, each once), its records of device
    // addresses into the sets, and the palette. The sets' memory must stay alive and unchanged
    // by others while a trace runs, until a later upload or repoint names other memory; the
    // caller orders the other API's writes before the next trace (a finished queue). Memory
    // exported as an opaque fd is acquired from VK_QUEUE_FAMILY_EXTERNAL before each trace and
    // released back after. Shared trees always take the address path (never chunk 0's
    // bindings). update_tiles is not taken (logic_error): edits are told through repoint.
    // logic_error for a tile outside the tile grid or listed twice.
    void upload_shared(Dims dims, const Palette& palette, const std::vector<SharedTreeSet>& sets,
                       const std::vector<SharedTile>& tiles);
    // After trees moved (the device world's edits wrote tiles into other places, or its memory
    // was replaced): `sets` as they are now (a set whose memory changed: its tiles' records
    // written again, same places in the new memory), `tiles` whose tree is now elsewhere or
    // new to the directory, `removed` tiles no longer stored (those the directory lacks are
    // ignored). Only records, pages and block entries are copied, as update_tiles copies: in
    // the next trace's submission. logic_error before upload_shared. After an exception the
    // tracer traces nothing until upload_shared.
    SparseTileUpdate repoint(const std::vector<SharedTreeSet>& sets,
                             const std::vector<SharedTile>& tiles,
                             const std::vector<Int3>& removed);
    // Forgets the shared sets (their memory is about to be freed): nothing is traced until the
    // next upload_shared.
    void drop_shared();

    // Traces one image and reads it back (Image::raymarch_ms: the dispatch by GPU timestamps).
    // options.count: Image::fetches counts node visits and Image::steps node exits (every level
    // from blocks to voxels), over all primary rays. options.surface is not supported
    // (std::logic_error), nor rendering before an upload. InputError for bad options.
    Image render(const RenderOptions& options);
    void render(const RenderOptions& options, Image& out);
    // Traces one image and leaves it on the device (a headless viewer's frame); returns the
    // dispatch's GPU time (ms, -1 without timestamps).
    double trace(const RenderOptions& options);

    const SparseDeviceStats& stats() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace voxfield::vk
