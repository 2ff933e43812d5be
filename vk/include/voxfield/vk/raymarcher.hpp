#pragma once
// The DDA ray marcher (vk/shaders/raymarch.comp) over a packed32 or compact distance field,
// rendering into an offscreen image that is read back as RGBA8 (render), copied into memory
// another VkDevice imports (render_to), or recorded into a caller's command buffer (record:
// a Presenter on the same Context copies it into the swapchain image). Buffers, images and
// descriptor sets that frames in flight may still use when they are replaced (a new field, a
// resized image) are retired through the Context, never destroyed in use.
#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "voxfield/core/chunks.hpp"
#include "voxfield/core/metric.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/world.hpp"
#include "voxfield/vk/context.hpp"
#include "voxfield/vk/shared.hpp"
#include "voxfield/vk/trace_layout.h"

namespace voxfield::vk {

using Vec3 = std::array<double, 3>;

// Pinhole camera, DESIGN §4: up = +y, vertical field of view in degrees, in (0, 180).
struct Camera {
    Vec3 position{0, 0, 0}, target{0, 0, 1};
    double fov_deg = 60;
};

// The camera's basis for an image of width x height: pixel (i, j) (j down) looks along
// forward + sx * right + sy * up with sx = ((i+0.5)/W*2-1), sy = (1-(j+0.5)/H*2), where
// right is scaled by aspect * tan(fov/2) and up by tan(fov/2). Looking straight along +-y,
// right is +x. Throws InputError when target equals position or fov is outside (0, 180).
struct CameraBasis {
    Vec3 forward, right, up;
};
CameraBasis camera_basis(const Camera& camera, std::uint32_t width, std::uint32_t height);

// A camera outside the world looking at its centre from above and in front (a three-quarter
// view that shows the whole world at a 60 degree field of view in a 4:3 image).
Camera default_camera(Dims dims);
// `render`'s and `view`'s default camera: the same view of the box of the world's solid voxels
// (core's solid_framing and framing_position), framed for a width x height image.
Camera default_camera(const World& world, std::uint32_t width, std::uint32_t height,
                      double fov_deg = 60);

enum class Shading { flat, lit };

inline constexpr std::uint32_t kMaxImageSize = 16384;

struct RenderOptions {
    std::uint32_t width = 800, height = 600;  // 1 .. kMaxImageSize
    Camera camera;
    Shading shading = Shading::flat;
    Rgba sky{0, 0, 0, 255};
    // Lit shading only: the sky gradient and sun disc instead of the flat `sky` colour.
    bool sky_gradient = false;
    // Pixel bytes B, G, R, A instead of R, G, B, A (for a BGRA swapchain).
    bool bgra = false;
    // Also count each primary ray's field fetches and DDA steps (Image::fetches / steps; lit
    // shading's shadow rays are not counted), through a pipeline variant that writes a
    // counter per pixel: for benchmarks, render() only.
    bool count = false;
    // Also record each primary ray's hit point and normal (Image::surface), through a pipeline
    // variant that writes them per pixel: for checks, render() only.
    bool surface = false;
};

// A primary ray's hit (RenderOptions::surface): kind VF_TRACE_MISS, VF_TRACE_CUBE (a voxel's
// face; normal the face's, or -direction when the camera's own cell is solid) or
// VF_TRACE_SMOOTH (the trilinear interpolant of an implicit surface's crossed voxel: normal the
// normalised trilinear interpolation of its corner gradients); point in voxel units (world
// coordinates of the field's grid); t the distance from the camera along the unit ray.
struct SurfaceHit {
    float x, y, z, kind;
    float nx, ny, nz, t;
};
static_assert(sizeof(SurfaceHit) == 32);

struct Image {
    std::uint32_t width = 0, height = 0;
    std::vector<std::uint8_t> rgba;  // width * height * 4 bytes, rows top to bottom
    double raymarch_ms = -1;         // the dispatch, by GPU timestamps (-1: not available)
    // With RenderOptions::count: field fetches and DDA steps summed over all width * height
    // rays (a ray that misses the world box has none).
    std::uint64_t fetches = 0, steps = 0;
    // With RenderOptions::surface: width * height hits, rows top to bottom.
    std::vector<SurfaceHit> surface;
};

// An implicit part's discretisation laid over the field's voxel grid (ocl::ImplicitGrid's
// arrays, core/sdf_layout.hpp; vk/ does not include cl/): the ray marcher's hits in the voxels
// the surface crosses intersect the trilinear interpolant of their 8 corner values instead of
// the cube. The field the surface is traced over must be that of a world whose voxels are
// solid where the part is solid or crossed (the march stops only at distance 0).
struct ImplicitSurface {
    Dims dims;   // voxels: the field's dims
    Dims tiles;  // ceil(dims / tile_edge)
    std::uint32_t tile_depth = 0;
    std::span<const std::uint32_t> tile_table, nodes, voxels;
    std::span<const float> vertices;  // VF_SDF_VERTEX_FLOATS per corner vertex
};

// Throws InputError for sizes outside 1..kMaxImageSize or a bad camera.
void validate(const RenderOptions& options);

// What the ray marcher reads. packed32: the field of DESIGN §3 (4 bytes per voxel) plus the
// world's material bytes beside it (flat shading needs the exact palette index, which rgb332
// loses), 5 bytes per voxel resident. compact: 16 bits per voxel, (min(d,255) << 8) | material
// index (layout.h VF_COMPACT_*), two voxels per 32-bit word (the lower half first): world and
// field in 2 bytes per voxel, nothing beside it.
enum class FieldFormat { packed32, compact };
FieldFormat parse_field_format(const std::string& name);  // throws InputError
std::string to_string(FieldFormat f);
std::size_t element_size(FieldFormat f);  // 4, 2

// How a field is split along z into storage-buffer bindings ("slabs"). In one allocation
// (sharing paths 1/2) slab s starts at byte s * slab_stride; voxel (x, y, z) is element
// ((z - s * slab_depth) * Y + y) * X + x of its slab.
struct FieldLayout {
    FieldFormat format = FieldFormat::compact;
    Dims dims;
    std::uint32_t slab_depth = 0, slabs = 0;
    std::uint64_t slab_stride = 0;  // bytes, a multiple of VF_FIELD_SLAB_ALIGN
    std::uint64_t total_bytes = 0;  // slab_stride * slabs

    std::uint64_t slab_bytes(std::uint32_t s) const;  // bytes bound for slab s (whole words)
};

class Raymarcher {
  public:
    // max_binding_bytes: split the field into storage-buffer bindings of at most this many
    // bytes (0: the device's maxStorageBufferRange). Tests lower it to exercise the split.
    explicit Raymarcher(Context& ctx, std::uint64_t max_binding_bytes = 0);
    ~Raymarcher();
    Raymarcher(const Raymarcher&) = delete;
    Raymarcher& operator=(const Raymarcher&) = delete;

    // Uploads the packed32 field (dims.count() elements, DESIGN §3: distance in bits 15..8),
    // the world's voxels (flat shading writes the palette colour of the hit voxel's
    // material exactly, not the field's rgb332 approximation) and the palette. This is
    // DESIGN §2 sharing path 3 (a copy). Throws InputError when the world needs more than
    // VF_RAYMARCH_MAX_SLABS bindings or one z-slice exceeds a binding.
    void upload(const World& world, const Palette& palette,
                std::span<const std::uint32_t> packed32);

    // How a field of `dims` in `format` is split across bindings on this device. Throws
    // InputError when it needs more than VF_RAYMARCH_MAX_SLABS bindings or one z-slice
    // exceeds a binding.
    FieldLayout plan(Dims dims, FieldFormat format) const;

    // Uploads a compact field (dims.count() elements, voxel order x fastest) and the palette
    // (sharing path 3: a copy). Throws InputError like plan().
    void upload_compact(Dims dims, const Palette& palette, std::span<const std::uint16_t> compact);

    // Reads the field in place from `memory` (sharing path 1 or 2), laid out as `layout`
    // (from plan()); whatever OpenCL writes there shows in the next render() with no copy.
    // Path 1: every recorded ray march acquires the field from VK_QUEUE_FAMILY_EXTERNAL
    // before reading it and releases it back after. `memory` must outlive this ray marcher or
    // the next upload / bind_shared and the frames in flight then (Context::
    // wait_frames_in_flight); OpenCL's writes into it must wait for those frames
    // (wait_for_readers).
    void bind_shared(const ExternalMemory& memory, const FieldLayout& layout,
                     const Palette& palette);

    // Path 3 after an edit of the compact field it holds: copies the values of `boxes` (voxel
    // boxes inside the field, e.g. the regions an edit changed) into the field in place, box
    // after box and x fastest in each (`values` holds their voxels in that order). Only those
    // bytes move (bytes_copied() grows by 2 per voxel), through one staged copy that the queue
    // orders after the frames in flight that read the field and before the next render: no
    // CPU wait, no new buffers. The palette, the metric and the block-minimum table stay, so
    // that update_block_min rewrites only the blocks the edit changed. The second form copies
    // the whole field (`compact`: dims.count() elements). Throws InputError when a box leaves
    // the field or the values do not match, std::logic_error when the field is not a copied
    // compact one.
    void update_compact(std::span<const Box> boxes, std::span<const std::uint16_t> values);
    void update_compact(std::span<const std::uint16_t> compact);
    // As update_compact, for the packed32 field of upload(): the field's words and the world's
    // material bytes of `boxes`, box after box and x fastest in each, copied in place (5 bytes
    // per voxel). Throws InputError when a box leaves the field or the sizes do not match,
    // std::logic_error when the field is not a packed32 one.
    void update_packed32(std::span<const Box> boxes, std::span<const std::uint32_t> packed32,
                         std::span<const std::uint8_t> materials);
    // The copied compact field as the shader reads it (dims.count() elements, x fastest), read
    // back after all work submitted so far (for checks). Throws std::logic_error when the field
    // is not a copied compact one.
    std::vector<std::uint16_t> read_compact();
    // Waits (on the CPU) until the latest submitted frame or render that reads the field has
    // finished: on its fence, not a device idle (frames that do not read it, e.g. an upload,
    // are not waited for beyond it). Before OpenCL overwrites a shared field in place (paths
    // 1/2, where no Vulkan-side copy can order the write).
    void wait_for_readers();

    // Coarse skipping (layout.h VF_RAYMARCH_BLOCK), in its own storage-buffer binding: per
    // block of the current field, the minimum of the unsaturated distance in the field's
    // metric (x fastest over ceil(dims / VF_RAYMARCH_BLOCK)). Where a cell's 8-bit distance
    // is saturated the ray then walks as from a distance of max(255, block minimum).
    // Uploading or binding a new field clears the table (its old minima no longer hold).
    //
    // set_block_min copies a whole table (e.g. ocl::CompactWriter::block_min(), path 3) into
    // a buffer of the ray marcher's own. Throws InputError when its size does not match the
    // field's blocks.
    void set_block_min(std::span<const std::uint32_t> block_min);
    // After an edit, path 3: copies the minima of `blocks` (boxes in block coordinates, e.g.
    // ocl::CompactWriter::changed_blocks()), box after box and x fastest in each (as
    // CompactWriter::block_min(blocks) reads them), over those words of the table that
    // set_block_min copied; every other word stays as it was. One staged copy, ordered by the
    // queue after the frames in flight that read the table and before the next render (no CPU
    // wait). Throws InputError when a box leaves the block grid or the minima do not match the
    // boxes, std::logic_error without a copied table.
    void update_block_min(std::span<const Box> blocks, std::span<const std::uint32_t> minima);
    // Paths 1/2: the table lies in `memory` (the shared field's, bound with bind_shared) at
    // byte `offset`, where OpenCL writes it in place (ocl::SlabLayout::block_min_offset):
    // nothing is copied, ever. The field's writer orders OpenCL's writes before the next
    // render (a clFinish before it returns, or on path 1 the "written" semaphore that Vulkan
    // waits for), so the next render reads them; the caller must not run the two at once.
    // `memory` must outlive this ray marcher or the next upload / bind_shared.
    // Throws std::logic_error when no field is shared or the table does not fit in `memory`.
    void bind_shared_block_min(const ExternalMemory& memory, std::uint64_t offset);
    // Bytes of block minima copied into the ray marcher's table so far (set_block_min and
    // update_block_min; stays 0 while the table is shared).
    std::uint64_t block_min_bytes_copied() const;
    // The metric of the current field's distances and block minima (DESIGN §3; unit spacing,
    // integer distances rounded down). It decides how far a ray may walk from a fetch without
    // passing a solid (raymarch.comp derives each metric's step). Uploading or binding a new
    // field resets it to manhattan, whose step is safe for every metric's field (only
    // slower), while a larger metric's step over another field could skip solids.
    void set_metric(Metric metric);
    Metric metric() const;
    // Traces `surface` in the voxels it crosses (copied into buffers of the ray marcher's own,
    // about the grid's bytes) in every later ray march of a field of the same dims; fields of
    // other dims are marched as voxels. Throws InputError when the arrays do not match
    // (sizes, tile grid) or one exceeds a storage-buffer binding.
    void set_implicit(const ImplicitSurface& surface);
    // Back to voxels only (e.g. after an edit that the surface no longer describes).
    void clear_implicit();
    // Whether an implicit surface is held, and its device bytes.
    bool has_implicit() const;
    std::uint64_t implicit_bytes() const;
    // Ray-marches one image and reads it back. The offscreen image and readback buffer are
    // kept while the size stays; the second form also reuses out.rgba's storage.
    Image render(const RenderOptions& options);
    void render(const RenderOptions& options, Image& out);
    // Records the ray march of `options` into `cmd` (a primary command buffer of this
    // context's queue family, recording): the image it writes is returned in
    // VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, its writes available to transfer reads; a copy
    // out of it must be recorded in the same command buffer. Submit `cmd` with
    // Context::submit before any other submission and before this ray marcher changes (a
    // new field, another image size): earlier frames may still be in flight meanwhile, the
    // next record() orders itself after them. Throws std::logic_error for options.count or
    // options.surface or before a field was given, InputError for bad options.
    VkImage record(VkCommandBuffer cmd, const RenderOptions& options);
    // The GPU time in ms of the ray march of the latest recorded frame whose submission is
    // known to have finished (by Context::wait, no wait here): in a frame loop that is the
    // frame one or two frames before. -1: none yet, or no timestamps on this device.
    double finished_raymarch_ms();
    // Ray-marches one image into `frame` (memory from ExternalMemory::exportable, at least
    // width * height * 4 bytes: rows top to bottom, no padding) without reading it back, for a
    // Presenter on another VkDevice of this GPU that imported it (Presenter::import_frame).
    // The buffer is released to VK_QUEUE_FAMILY_EXTERNAL and the work has finished when this
    // returns. Returns the dispatch's GPU time in ms (-1: not available). Throws
    // std::logic_error for options.count or options.surface.
    double render_to(const RenderOptions& options, const ExternalMemory& frame);

    // The field format and layout in use, and the bytes copied into field / material buffers
    // so far (stays 0 while the field is shared).
    const FieldLayout& layout() const;
    std::uint64_t bytes_copied() const;

    // How many storage-buffer bindings the field was split across, and z-slices per binding.
    std::uint32_t field_bindings() const;
    std::uint32_t slab_depth() const;
    // The active OpenCL -> Vulkan sharing path, for reports.
    SharingPath sharing() const;
    std::string sharing_path() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace voxfield::vk
