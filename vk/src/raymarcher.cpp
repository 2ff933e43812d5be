#include "voxfield/vk/raymarcher.hpp"

#include "voxfield/core/camera.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <stdexcept>
#include <utility>

#include "raymarch_spv.h"
#include "voxfield/core/error.hpp"
#include "voxfield/layout.h"

namespace voxfield::vk {
namespace {

// Mirrors the push-constant block `Params` of raymarch.comp (std430: vec4 / uvec4 members).
struct PushConstants {
    float origin[4];
    float forward[4];
    float right[4];
    float up[4];
    std::uint32_t dims[4];   // X, Y, Z, z-slices per slab
    std::uint32_t image[4];  // width, height, flags, flat sky RGBA8
};
static_assert(sizeof(PushConstants) == 96);
static_assert(offsetof(PushConstants, dims) == 64);
static_assert(offsetof(PushConstants, image) == 80);

constexpr std::uint32_t kBindings = VF_RAYMARCH_BINDING_MATERIAL + VF_RAYMARCH_MAX_SLABS;
static_assert(VF_RAYMARCH_BINDING_FIELD + VF_RAYMARCH_MAX_SLABS <= VF_RAYMARCH_BINDING_MATERIAL);
// The shader reads the distance of both formats with the packed32 constants.
static_assert(VF_COMPACT_DISTANCE_SHIFT == VF_PACKED_DISTANCE_SHIFT);
static_assert(VF_COMPACT_DISTANCE_MAX == VF_PACKED_DISTANCE_MAX);
// The per-pixel counters of RenderOptions::count (raymarch.comp's buffer C): the binding after
// the material slabs.
constexpr std::uint32_t kCounterBinding = kBindings;
static_assert(VF_RAYMARCH_BINDING_BLOCK_MIN == kCounterBinding + 1);
// The ray marcher's own block-minimum table (and its placeholder, reused when the sizes match).
constexpr VkBufferUsageFlags kTableUsage =
    VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT;

// raymarch.comp's specialization constants: constant_id 0 the metric (kManhattan,
// kChebyshev, kEuclidean = 0, 1, 2), constant_id 1 whether rays count, constant_id 2 whether
// lit shading marches shadow rays, constant_id 3 whether the field lies in one binding,
// constant_id 4 whether it is compact (VkBool32s).
struct Specialization {
    std::uint32_t metric;
    VkBool32 count;
    VkBool32 shadows;
    VkBool32 one_slab;
    VkBool32 compact;
};
constexpr std::size_t kMetrics = 3;
// Timestamp pairs used in turn by recorded ray marches (more than the frames that can be in
// flight, so that a finished frame's pair is read before it is reused).
constexpr std::uint32_t kQueryPairs = 4;

std::uint32_t metric_code(Metric m) {
    switch (m) {
        case Metric::manhattan:
            return 0;
        case Metric::chebyshev:
            return 1;
        case Metric::euclidean:
            return 2;
    }
    throw std::logic_error("ray marcher: unknown metric");
}

Vec3 sub(const Vec3& a, const Vec3& b) {
    return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}
double length(const Vec3& a) {
    return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
}
bool finite(const Vec3& a) {
    return std::isfinite(a[0]) && std::isfinite(a[1]) && std::isfinite(a[2]);
}

std::uint32_t pack(Rgba c) {
    return std::uint32_t{c.r} | (std::uint32_t{c.g} << 8) | (std::uint32_t{c.b} << 16) |
           (std::uint32_t{c.a} << 24);
}

std::uint64_t round_up4(std::uint64_t v) {
    return (v + 3) / 4 * 4;
}

void to4(float out[4], const Vec3& v) {
    for (int i = 0; i < 3; ++i) {
        out[i] = static_cast<float>(v[static_cast<std::size_t>(i)]);
    }
    out[3] = 0;
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

CameraBasis camera_basis(const Camera& camera, std::uint32_t width, std::uint32_t height) {
    if (!finite(camera.position) || !finite(camera.target)) {
        throw InputError("camera position and target must be finite numbers");
    }
    if (!(camera.fov_deg > 0 && camera.fov_deg < 180)) {
        throw InputError("field of view " + std::to_string(camera.fov_deg) +
                         " is outside (0, 180) degrees");
    }
    const Vec3 view = sub(camera.target, camera.position);
    if (!(length(view) > 1e-9)) {
        throw InputError("camera target equals the camera position: no view direction");
    }
    // The one camera model (core/camera.hpp image_basis, DESIGN §4).
    const ImageBasis b =
        image_basis(view, camera.fov_deg, static_cast<double>(width), static_cast<double>(height));
    return CameraBasis{b.forward, b.right, b.up};
}

namespace {

Camera framed(const Framing& f, double fov_deg, double aspect) {
    Camera c;
    c.position = framing_position(f, fov_deg, aspect);
    c.target = f.centre;
    c.fov_deg = fov_deg;
    return c;
}

}  // namespace

Camera default_camera(Dims dims) {
    return framed(world_framing(dims), 60, 4.0 / 3.0);
}

Camera default_camera(const World& world, std::uint32_t width, std::uint32_t height,
                      double fov_deg) {
    return framed(solid_framing(world), fov_deg, double(width) / double(std::max(height, 1u)));
}

void validate(const RenderOptions& o) {
    for (const auto& [name, v] : {std::pair{"width", o.width}, std::pair{"height", o.height}}) {
        if (v < 1 || v > kMaxImageSize) {
            throw InputError(std::string("image ") + name + " " + std::to_string(v) +
                             " is outside 1.." + std::to_string(kMaxImageSize));
        }
    }
    camera_basis(o.camera, o.width, o.height);
}

struct Raymarcher::Impl {
    Context& ctx;
    VkDeviceSize max_binding = 0;
    Owned<VkDescriptorSetLayout> set_layout;
    Owned<VkPipelineLayout> pipeline_layout;
    Owned<VkShaderModule> shader;
    // One pipeline per metric and combination of the specialization flags (bits 0..3 of its
    // index among the metric's 16: counting, shadow rays, one binding, compact), built on first
    // use.
    std::array<Owned<VkPipeline>, kMetrics * 16> pipelines;
    // The descriptor set, in a pool of its own: when the bindings change while work that uses
    // the set may be in flight, the pool is retired and a fresh set written.
    Owned<VkDescriptorPool> pool;
    VkDescriptorSet set = VK_NULL_HANDLE;
    bool set_recorded = false;   // bound in a command buffer since it was made
    Owned<VkQueryPool> queries;  // kQueryPairs pairs (dispatch start, end)
    std::array<std::uint64_t, kQueryPairs> pair_serial{};  // the submission that wrote each
    std::uint32_t next_pair = 0;
    std::uint64_t reported_serial = 0;  // finished_raymarch_ms(): the latest pair read
    double reported_ms = -1;
    Buffer palette;  // 256 colours
    // The block-minimum table's binding: a buffer of the ray marcher's own (copied), one over
    // the shared field's memory (written by OpenCL), or, while there is no table, a placeholder
    // word that is never read.
    Buffer block_min;
    bool coarse = false;            // the table holds the current field's minima
    bool block_min_shared = false;  // block_min lies in shared memory
    std::uint64_t block_min_copied = 0;
    Metric metric = Metric::manhattan;
    // RenderOptions::count: one uvec2 (fetches, steps) per pixel; a single one otherwise.
    Buffer counters;
    std::vector<Buffer> field, material;  // material: packed32 only
    FieldLayout layout;
    SharingPath sharing = SharingPath::copy;
    std::uint64_t copied = 0;
    // The serial of the latest submission that reads the field (a recorded frame or a render).
    std::uint64_t last_reader = 0;
    // The offscreen image and its readback buffer, kept while the image size stays (a frame
    // loop would otherwise allocate both, megabytes of pinned memory, every frame).
    struct Target {
        std::uint32_t width = 0, height = 0;
        Owned<VkDeviceMemory> memory;  // declared first: freed after the image is destroyed
        Owned<VkImage> image;
        Owned<VkImageView> view;
        Buffer readback;
    } target;

    explicit Impl(Context& c) : ctx(c) {}
    // render_to's buffer over the caller's exportable memory (rebound when that changes).
    Buffer frame;
    VkDeviceMemory frame_memory = VK_NULL_HANDLE;

    // Records the ray march of `o` into `cmd` (Raymarcher::record); returns the timestamp pair
    // it writes.
    std::uint32_t record(VkCommandBuffer cmd, const RenderOptions& o);
    // Renders `o` and copies the image into `dst` (width * height * 4 bytes), then waits.
    // external: dst lies in memory another VkDevice imports; it is released to
    // VK_QUEUE_FAMILY_EXTERNAL instead of being made visible to the host. Returns the pair.
    std::uint32_t march(const RenderOptions& o, VkBuffer dst, bool external);
    // A set that no work in flight uses (the current one, or a fresh one when it may be in
    // use), with every binding written.
    void write_set();
    // The pipeline of `metric`, with or without counting (built when first asked for).
    VkPipeline pipeline_for(Metric metric, bool count, bool shadows, bool one_slab, bool compact);
    // Makes `counters` hold at least `pixels` counters and points its binding at it.
    void prepare_counters(std::size_t pixels);
    // The dispatch time recorded in timestamp pair `pair` (-1 without timestamp queries);
    // wait: until it is available, else -1 when it is not yet.
    double pair_ms(std::uint32_t pair, bool wait);
    // Makes `target` an image of width x height (no-op when it already is).
    void prepare_target(std::uint32_t width, std::uint32_t height, const std::string& what);
    void upload_palette(const Palette& p);
    // The number of blocks of the current field (layout.h VF_RAYMARCH_BLOCK).
    Dims block_grid() const;
    // The placeholder bound while there is no table: one word, never read.
    Buffer no_table();
    // Points the block-minimum binding at `table` (kept in block_min); the old table is
    // retired (frames in flight may read it).
    void bind_block_min(Buffer table, bool coarse_now, bool shared);
    // Copies a compact field into new device-local slabs laid out as `l`; adds their size to
    // `bytes`.
    std::vector<Buffer> copy_compact(const FieldLayout& l, std::span<const std::uint16_t> compact,
                                     std::uint64_t& bytes);
    // Copies `words` (staged, 4-byte words or 2-byte halves) into `dst` at the given regions,
    // after every earlier use of the buffers in queue order (frames in flight read them, earlier
    // copies wrote them) and before every later one, without a CPU wait.
    void copy_in_place(const void* bytes, VkDeviceSize size,
                       const std::vector<std::pair<VkBuffer, std::vector<VkBufferCopy>>>& regions,
                       const std::string& what);
    // Takes the new field buffers and points every binding at them.
    void install(std::vector<Buffer> new_field, std::vector<Buffer> new_material,
                 const FieldLayout& new_layout, SharingPath path);
};

Raymarcher::Raymarcher(Context& ctx, std::uint64_t max_binding_bytes)
    : impl_(std::make_unique<Impl>(ctx)) {
    Impl& m = *impl_;
    const VkDevice dev = ctx.device();
    m.max_binding = ctx.info().max_storage_buffer_range;
    if (max_binding_bytes != 0) {
        m.max_binding = std::min<VkDeviceSize>(m.max_binding, max_binding_bytes);
    }
    m.max_binding = m.max_binding / 4 * 4;

    std::vector<VkDescriptorSetLayoutBinding> bindings;
    for (std::uint32_t b = 0; b <= VF_RAYMARCH_BINDING_BLOCK_MIN; ++b) {
        if (b >= VF_RAYMARCH_BINDING_FIELD + VF_RAYMARCH_MAX_SLABS &&
            b < VF_RAYMARCH_BINDING_MATERIAL) {
            continue;
        }
        VkDescriptorSetLayoutBinding x{};
        x.binding = b;
        x.descriptorType = b == VF_RAYMARCH_BINDING_IMAGE ? VK_DESCRIPTOR_TYPE_STORAGE_IMAGE
                                                          : VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
        x.descriptorCount = 1;
        x.stageFlags = VK_SHADER_STAGE_COMPUTE_BIT;
        bindings.push_back(x);
    }
    VkDescriptorSetLayoutCreateInfo sl{};
    sl.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_LAYOUT_CREATE_INFO;
    sl.bindingCount = static_cast<std::uint32_t>(bindings.size());
    sl.pBindings = bindings.data();
    VkDescriptorSetLayout set_layout = VK_NULL_HANDLE;
    check(vkCreateDescriptorSetLayout(dev, &sl, nullptr, &set_layout),
          "vkCreateDescriptorSetLayout", "ray marcher");
    m.set_layout = Owned<VkDescriptorSetLayout>(dev, set_layout, vkDestroyDescriptorSetLayout);

    VkPushConstantRange range{VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof(PushConstants)};
    VkPipelineLayoutCreateInfo pl{};
    pl.sType = VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO;
    pl.setLayoutCount = 1;
    pl.pSetLayouts = &set_layout;
    pl.pushConstantRangeCount = 1;
    pl.pPushConstantRanges = &range;
    VkPipelineLayout pipeline_layout = VK_NULL_HANDLE;
    check(vkCreatePipelineLayout(dev, &pl, nullptr, &pipeline_layout), "vkCreatePipelineLayout",
          "ray marcher");
    m.pipeline_layout = Owned<VkPipelineLayout>(dev, pipeline_layout, vkDestroyPipelineLayout);

    VkShaderModuleCreateInfo sm{};
    sm.sType = VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO;
    sm.codeSize = sizeof(vf_raymarch_spv);
    sm.pCode = vf_raymarch_spv;
    VkShaderModule shader = VK_NULL_HANDLE;
    check(vkCreateShaderModule(dev, &sm, nullptr, &shader), "vkCreateShaderModule",
          "raymarch.comp");
    m.shader = Owned<VkShaderModule>(dev, shader, vkDestroyShaderModule);

    m.write_set();

    if (ctx.info().timestamps) {
        VkQueryPoolCreateInfo qp{};
        qp.sType = VK_STRUCTURE_TYPE_QUERY_POOL_CREATE_INFO;
        qp.queryType = VK_QUERY_TYPE_TIMESTAMP;
        qp.queryCount = 2 * kQueryPairs;
        VkQueryPool q = VK_NULL_HANDLE;
        check(vkCreateQueryPool(dev, &qp, nullptr, &q), "vkCreateQueryPool", "ray marcher");
        m.queries = Owned<VkQueryPool>(dev, q, vkDestroyQueryPool);
    }
    m.palette = ctx.make_buffer(
        256 * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
        MemoryIntent::device_local, "palette");
    m.prepare_counters(1);
    m.bind_block_min(m.no_table(), false, false);
}

Raymarcher::~Raymarcher() {
    // Recorded frames may still use the pipelines, the set and the buffers.
    impl_->ctx.wait_frames_in_flight();
}

void Raymarcher::Impl::write_set() {
    const VkDevice dev = ctx.device();
    if (!pool || (set_recorded && ctx.busy())) {
        if (pool) {
            ctx.retire(std::move(pool));  // frees the set once the frames using it finished
        }
        const std::array<VkDescriptorPoolSize, 2> sizes = {
            VkDescriptorPoolSize{VK_DESCRIPTOR_TYPE_STORAGE_IMAGE, 1},
            VkDescriptorPoolSize{VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                 VF_RAYMARCH_BINDING_BLOCK_MIN + 1}};
        VkDescriptorPoolCreateInfo dp{};
        dp.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
        dp.maxSets = 1;
        dp.poolSizeCount = static_cast<std::uint32_t>(sizes.size());
        dp.pPoolSizes = sizes.data();
        VkDescriptorPool handle = VK_NULL_HANDLE;
        check(vkCreateDescriptorPool(dev, &dp, nullptr, &handle), "vkCreateDescriptorPool",
              "ray marcher");
        pool = Owned<VkDescriptorPool>(dev, handle, vkDestroyDescriptorPool);
        const VkDescriptorSetLayout layout_handle = set_layout.get();
        VkDescriptorSetAllocateInfo da{};
        da.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO;
        da.descriptorPool = handle;
        da.descriptorSetCount = 1;
        da.pSetLayouts = &layout_handle;
        check(vkAllocateDescriptorSets(dev, &da, &set), "vkAllocateDescriptorSets", "ray marcher");
        set_recorded = false;
    }
    std::vector<VkDescriptorBufferInfo> infos;
    infos.reserve(VF_RAYMARCH_BINDING_BLOCK_MIN + 1);
    std::vector<VkWriteDescriptorSet> writes;
    auto write = [&](std::uint32_t binding, VkDescriptorType type) {
        VkWriteDescriptorSet w{};
        w.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
        w.dstSet = set;
        w.dstBinding = binding;
        w.descriptorCount = 1;
        w.descriptorType = type;
        return w;
    };
    auto add = [&](std::uint32_t binding, const Buffer& b, VkDeviceSize range) {
        if (b.get() == VK_NULL_HANDLE) {
            return;
        }
        infos.push_back(VkDescriptorBufferInfo{b.get(), 0, range});
        VkWriteDescriptorSet w = write(binding, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER);
        w.pBufferInfo = &infos.back();
        writes.push_back(w);
    };
    add(VF_RAYMARCH_BINDING_PALETTE, palette, VK_WHOLE_SIZE);
    add(kCounterBinding, counters, VK_WHOLE_SIZE);
    add(VF_RAYMARCH_BINDING_BLOCK_MIN, block_min, VK_WHOLE_SIZE);
    for (std::uint32_t s = 0; s < VF_RAYMARCH_MAX_SLABS && !field.empty(); ++s) {
        // Unused bindings alias slab 0 and are never read; compact fields have no material
        // buffers, so those bindings alias field slab 0 too.
        const std::uint32_t k = s < layout.slabs ? s : 0;
        add(VF_RAYMARCH_BINDING_FIELD + s, field[k], layout.slab_bytes(k));
        if (material.empty()) {
            add(VF_RAYMARCH_BINDING_MATERIAL + s, field[0], layout.slab_bytes(0));
        } else {
            add(VF_RAYMARCH_BINDING_MATERIAL + s, material[k], VK_WHOLE_SIZE);
        }
    }
    const VkDescriptorImageInfo image_info{VK_NULL_HANDLE, target.view.get(),
                                           VK_IMAGE_LAYOUT_GENERAL};
    if (target.view) {
        VkWriteDescriptorSet w = write(VF_RAYMARCH_BINDING_IMAGE, VK_DESCRIPTOR_TYPE_STORAGE_IMAGE);
        w.pImageInfo = &image_info;
        writes.push_back(w);
    }
    vkUpdateDescriptorSets(dev, static_cast<std::uint32_t>(writes.size()), writes.data(), 0,
                           nullptr);
}

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

FieldLayout Raymarcher::plan(Dims d, FieldFormat format) const {
    const Impl& m = *impl_;
    const VkDeviceSize slice = VkDeviceSize{d.x} * d.y * element_size(format);
    if (slice > m.max_binding) {
        throw InputError("world " + d.to_string() + ": one z-slice of the " + to_string(format) +
                         " field (" + std::to_string(slice) + " bytes) exceeds the Vulkan " +
                         "device's storage-buffer binding limit of " +
                         std::to_string(m.max_binding) + " bytes");
    }
    FieldLayout l;
    l.format = format;
    l.dims = d;
    // max_binding is a multiple of 4, so rounding a slab up to whole words stays within it.
    l.slab_depth = static_cast<std::uint32_t>(std::min<VkDeviceSize>(d.z, m.max_binding / slice));
    l.slabs = (d.z + l.slab_depth - 1) / l.slab_depth;
    if (l.slabs > VF_RAYMARCH_MAX_SLABS) {
        throw InputError("world " + d.to_string() + " needs " + std::to_string(l.slabs) +
                         " storage-buffer bindings of at most " + std::to_string(m.max_binding) +
                         " bytes for its " + to_string(format) + " field; the ray marcher has " +
                         std::to_string(VF_RAYMARCH_MAX_SLABS));
    }
    const std::uint64_t align = VF_FIELD_SLAB_ALIGN;
    l.slab_stride = (l.slab_bytes(0) + align - 1) / align * align;
    l.total_bytes = l.slab_stride * l.slabs;
    return l;
}

void Raymarcher::Impl::upload_palette(const Palette& p) {
    std::array<std::uint32_t, 256> colours{};
    for (std::size_t i = 0; i < 256; ++i) {
        colours[i] = pack(p[static_cast<std::uint8_t>(i)]);
    }
    // Frames in flight may read the old colours: those keep a buffer of their own.
    if (set_recorded && ctx.busy()) {
        ctx.retire(std::move(palette));
        palette = ctx.make_buffer(
            sizeof colours, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT | VK_BUFFER_USAGE_TRANSFER_DST_BIT,
            MemoryIntent::device_local, "palette");
        ctx.upload(palette, colours.data(), sizeof colours);
        write_set();
    } else {
        ctx.upload(palette, colours.data(), sizeof colours);
    }
    coarse = false;              // a new field: the old minima no longer hold
    metric = Metric::manhattan;  // nor the old metric; manhattan's step is safe for any field
    if (block_min_shared) {
        // It may lie in memory the new field no longer keeps alive.
        bind_block_min(no_table(), false, false);
    }
}

Dims Raymarcher::Impl::block_grid() const {
    const std::uint32_t b = VF_RAYMARCH_BLOCK;
    const Dims d = layout.dims;
    return Dims{(d.x + b - 1) / b, (d.y + b - 1) / b, (d.z + b - 1) / b};
}

Buffer Raymarcher::Impl::no_table() {
    return ctx.make_buffer(4, kTableUsage, MemoryIntent::device_local, "no block minima");
}

void Raymarcher::Impl::bind_block_min(Buffer table, bool coarse_now, bool shared) {
    ctx.retire(std::move(block_min));
    block_min = std::move(table);
    coarse = coarse_now;
    block_min_shared = shared;
    write_set();
}

VkPipeline Raymarcher::Impl::pipeline_for(Metric which, bool count, bool shadows, bool one_slab,
                                          bool compact) {
    const std::uint32_t code = metric_code(which);
    const std::size_t flags =
        (count ? 1u : 0u) | (shadows ? 2u : 0u) | (one_slab ? 4u : 0u) | (compact ? 8u : 0u);
    Owned<VkPipeline>& slot = pipelines[code * 16 + flags];
    if (slot) {
        return slot.get();
    }
    const auto flag = [](bool b) { return b ? VkBool32{VK_TRUE} : VkBool32{VK_FALSE}; };
    const Specialization data{code, flag(count), flag(shadows), flag(one_slab), flag(compact)};
    const std::array<VkSpecializationMapEntry, 5> entries = {
        VkSpecializationMapEntry{0, offsetof(Specialization, metric), sizeof data.metric},
        VkSpecializationMapEntry{1, offsetof(Specialization, count), sizeof data.count},
        VkSpecializationMapEntry{2, offsetof(Specialization, shadows), sizeof data.shadows},
        VkSpecializationMapEntry{3, offsetof(Specialization, one_slab), sizeof data.one_slab},
        VkSpecializationMapEntry{4, offsetof(Specialization, compact), sizeof data.compact}};
    VkSpecializationInfo spec{};
    spec.mapEntryCount = static_cast<std::uint32_t>(entries.size());
    spec.pMapEntries = entries.data();
    spec.dataSize = sizeof data;
    spec.pData = &data;
    VkComputePipelineCreateInfo cp{};
    cp.sType = VK_STRUCTURE_TYPE_COMPUTE_PIPELINE_CREATE_INFO;
    cp.stage.sType = VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO;
    cp.stage.stage = VK_SHADER_STAGE_COMPUTE_BIT;
    cp.stage.module = shader.get();
    cp.stage.pName = "main";
    cp.stage.pSpecializationInfo = &spec;
    cp.layout = pipeline_layout.get();
    const VkDevice dev = ctx.device();
    VkPipeline pipeline = VK_NULL_HANDLE;
    check(vkCreateComputePipelines(dev, VK_NULL_HANDLE, 1, &cp, nullptr, &pipeline),
          "vkCreateComputePipelines",
          "raymarch.comp, " + to_string(which) + (count ? ", counting" : "") +
              (shadows ? ", shadows" : "") + (one_slab ? ", one binding" : "") +
              (compact ? ", compact" : ", packed32"));
    slot = Owned<VkPipeline>(dev, pipeline, vkDestroyPipeline);
    return pipeline;
}

void Raymarcher::Impl::prepare_counters(std::size_t pixels) {
    const VkDeviceSize bytes = VkDeviceSize{8} * pixels;
    if (counters.get() != VK_NULL_HANDLE && counters.size() >= bytes) {
        return;
    }
    ctx.retire(std::move(counters));
    counters = ctx.make_buffer(bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, MemoryIntent::readback,
                               "ray counters");
    write_set();
}

void Raymarcher::Impl::install(std::vector<Buffer> new_field, std::vector<Buffer> new_material,
                               const FieldLayout& new_layout, SharingPath path) {
    // Frames in flight may still read the old buffers.
    ctx.retire(std::move(field));
    ctx.retire(std::move(material));
    field = std::move(new_field);
    material = std::move(new_material);
    layout = new_layout;
    sharing = path;
    write_set();
}

void Raymarcher::upload(const World& world, const Palette& palette,
                        std::span<const std::uint32_t> packed32) {
    Impl& m = *impl_;
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
        field.push_back(m.ctx.make_buffer(voxels * 4, usage, MemoryIntent::device_local,
                                          "field slab " + std::to_string(s)));
        m.ctx.upload(field.back(), packed32.data() + first, voxels * 4);
        // Material bytes, padded to whole words (the padding is never read).
        const std::size_t words = (voxels + 3) / 4;
        material.push_back(m.ctx.make_buffer(words * 4, usage, MemoryIntent::device_local,
                                             "material slab " + std::to_string(s)));
        std::vector<std::uint8_t> bytes(words * 4, 0);
        std::memcpy(bytes.data(), world.voxels().data() + first, voxels);
        m.ctx.upload(material.back(), bytes.data(), bytes.size());
        copied += voxels * 4 + bytes.size();
    }
    m.upload_palette(palette);
    m.install(std::move(field), std::move(material), l, SharingPath::copy);
    m.copied += copied;
}

void Raymarcher::upload_compact(Dims d, const Palette& palette,
                                std::span<const std::uint16_t> compact) {
    Impl& m = *impl_;
    if (compact.size() != d.count()) {
        throw InputError("compact field has " + std::to_string(compact.size()) +
                         " elements, the world " + std::to_string(d.count()));
    }
    const FieldLayout l = plan(d, FieldFormat::compact);
    std::uint64_t copied = 0;
    std::vector<Buffer> field = m.copy_compact(l, compact, copied);
    m.upload_palette(palette);
    m.install(std::move(field), {}, l, SharingPath::copy);
    m.copied += copied;
}

void Raymarcher::update_compact(std::span<const std::uint16_t> compact) {
    const Dims d = impl_->layout.dims;
    if (compact.size() != d.count()) {
        throw InputError("compact field has " + std::to_string(compact.size()) +
                         " elements, the world " + std::to_string(d.count()));
    }
    const Box whole{{0, 0, 0}, {d.x, d.y, d.z}};
    update_compact(std::span<const Box>(&whole, 1), compact);
}

void Raymarcher::update_compact(std::span<const Box> boxes, std::span<const std::uint16_t> values) {
    Impl& m = *impl_;
    if (m.field.empty() || m.layout.format != FieldFormat::compact ||
        m.sharing != SharingPath::copy) {
        throw std::logic_error("Raymarcher::update_compact: the field is not a copied compact one");
    }
    const FieldLayout& l = m.layout;
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
        regions[s].first = m.field[s].get();
    }
    VkDeviceSize src = 0;
    for_each_row(boxes, l, [&](std::uint32_t slab, VkDeviceSize at, VkDeviceSize length) {
        append_copy(regions[slab].second, src, 2 * at, 2 * length);
        src += 2 * length;
    });
    m.copy_in_place(values.data(), 2 * voxels, regions, "compact field update");
    m.copied += 2 * voxels;
}

void Raymarcher::update_packed32(std::span<const Box> boxes,
                                 std::span<const std::uint32_t> packed32,
                                 std::span<const std::uint8_t> materials) {
    Impl& m = *impl_;
    if (m.field.empty() || m.layout.format != FieldFormat::packed32) {
        throw std::logic_error("Raymarcher::update_packed32: the field is not a packed32 one");
    }
    const FieldLayout& l = m.layout;
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
        regions.push_back({m.field[s].get(), {}});
    }
    for (std::uint32_t s = 0; s < l.slabs; ++s) {
        regions.push_back({m.material[s].get(), {}});
    }
    VkDeviceSize n = 0;  // voxels staged so far
    for_each_row(boxes, l, [&](std::uint32_t slab, VkDeviceSize at, VkDeviceSize length) {
        append_copy(regions[slab].second, 4 * n, 4 * at, 4 * length);
        append_copy(regions[l.slabs + slab].second, 4 * voxels + n, at, length);
        n += length;
    });
    m.copy_in_place(staged.data(), staged.size(), regions, "packed32 field update");
    m.copied += staged.size();
}

void Raymarcher::Impl::copy_in_place(
    const void* bytes, VkDeviceSize size,
    const std::vector<std::pair<VkBuffer, std::vector<VkBufferCopy>>>& regions,
    const std::string& what) {
    Buffer staging =
        ctx.make_buffer(size, VK_BUFFER_USAGE_TRANSFER_SRC_BIT, MemoryIntent::upload, what);
    std::memcpy(staging.data(), bytes, size);
    ctx.submit_unwaited(
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
    ctx.retire(std::move(staging));  // read by the copy until it has finished
}

std::vector<std::uint16_t> Raymarcher::read_compact() {
    Impl& m = *impl_;
    if (m.field.empty() || m.layout.format != FieldFormat::compact ||
        m.sharing != SharingPath::copy) {
        throw std::logic_error("Raymarcher::read_compact: the field is not a copied compact one");
    }
    const FieldLayout& l = m.layout;
    const Dims d = l.dims;
    const VkDeviceSize plane = VkDeviceSize{d.x} * d.y;
    Buffer readback = m.ctx.make_buffer(2 * d.count() + 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                        MemoryIntent::readback, "compact field readback");
    m.ctx.submit_and_wait(
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
                vkCmdCopyBuffer(cmd, m.field[s].get(), readback.get(), 1, &c);
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

void Raymarcher::wait_for_readers() {
    impl_->ctx.wait_for(impl_->last_reader);
}

std::vector<Buffer> Raymarcher::Impl::copy_compact(const FieldLayout& l,
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
        out.push_back(ctx.make_buffer(l.slab_bytes(s), usage, MemoryIntent::device_local,
                                      "compact field slab " + std::to_string(s)));
        if (voxels % 2 == 0) {
            ctx.upload(out.back(), compact.data() + first, voxels * 2);
        } else {  // padded to a whole word (the padding is never read)
            std::vector<std::uint16_t> padded(voxels + 1, 0);
            std::memcpy(padded.data(), compact.data() + first, voxels * 2);
            ctx.upload(out.back(), padded.data(), padded.size() * 2);
        }
        bytes += l.slab_bytes(s);
    }
    return out;
}

void Raymarcher::bind_shared(const ExternalMemory& memory, const FieldLayout& l,
                             const Palette& palette) {
    Impl& m = *impl_;
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
        field.push_back(m.ctx.make_external_buffer(
            l.slab_bytes(s), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT, memory.handle_type(), what));
        m.ctx.bind(field.back(), memory.memory(), std::uint64_t{s} * l.slab_stride, what);
    }
    m.upload_palette(palette);
    m.install(std::move(field), {}, l, memory.path());
}

void Raymarcher::Impl::prepare_target(std::uint32_t width, std::uint32_t height,
                                      const std::string& what) {
    if (target.width == width && target.height == height) {
        return;
    }
    const VkDevice dev = ctx.device();
    // Frames in flight may still use the old target (view, image, then its memory go).
    ctx.retire(std::move(target));
    target = Target{};
    // Offscreen target: one r32ui texel per RGBA8 pixel, read back through a buffer.
    VkImageCreateInfo ii{};
    ii.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO;
    ii.imageType = VK_IMAGE_TYPE_2D;
    ii.format = VK_FORMAT_R32_UINT;
    ii.extent = {width, height, 1};
    ii.mipLevels = 1;
    ii.arrayLayers = 1;
    ii.samples = VK_SAMPLE_COUNT_1_BIT;
    ii.tiling = VK_IMAGE_TILING_OPTIMAL;
    ii.usage = VK_IMAGE_USAGE_STORAGE_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
    ii.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    ii.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    VkImage image_handle = VK_NULL_HANDLE;
    check(vkCreateImage(dev, &ii, nullptr, &image_handle), "vkCreateImage", what);
    target.image = Owned<VkImage>(dev, image_handle, vkDestroyImage);
    VkMemoryRequirements req{};
    vkGetImageMemoryRequirements(dev, image_handle, &req);
    target.memory = ctx.allocate(req, MemoryIntent::device_local, "offscreen image");
    check(vkBindImageMemory(dev, image_handle, target.memory.get(), 0), "vkBindImageMemory", what);
    VkImageViewCreateInfo vi{};
    vi.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO;
    vi.image = image_handle;
    vi.viewType = VK_IMAGE_VIEW_TYPE_2D;
    vi.format = VK_FORMAT_R32_UINT;
    vi.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    VkImageView view_handle = VK_NULL_HANDLE;
    check(vkCreateImageView(dev, &vi, nullptr, &view_handle), "vkCreateImageView", what);
    target.view = Owned<VkImageView>(dev, view_handle, vkDestroyImageView);
    target.readback =
        ctx.make_buffer(VkDeviceSize{width} * height * 4, VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                        MemoryIntent::readback, "image readback");
    target.width = width;
    target.height = height;
    write_set();
}

Image Raymarcher::render(const RenderOptions& o) {
    Image out;
    render(o, out);
    return out;
}

std::uint32_t Raymarcher::Impl::record(VkCommandBuffer cmd, const RenderOptions& o) {
    Impl& m = *this;
    if (m.field.empty()) {
        throw std::logic_error("Raymarcher::render before upload");
    }
    validate(o);
    const CameraBasis basis = camera_basis(o.camera, o.width, o.height);
    const std::string what = "ray march " + std::to_string(o.width) + "x" +
                             std::to_string(o.height) + " of " + m.layout.dims.to_string();
    m.prepare_target(o.width, o.height, what);
    if (o.count) {
        m.prepare_counters(std::size_t{o.width} * o.height);
    }
    const VkPipeline pipeline =
        m.pipeline_for(m.metric, o.count, o.shading == Shading::lit, m.layout.slabs <= 1,
                       m.layout.format == FieldFormat::compact);
    const VkImage image_handle = m.target.image.get();

    PushConstants pc{};
    to4(pc.origin, o.camera.position);
    to4(pc.forward, basis.forward);
    to4(pc.right, basis.right);
    to4(pc.up, basis.up);
    pc.dims[0] = m.layout.dims.x;
    pc.dims[1] = m.layout.dims.y;
    pc.dims[2] = m.layout.dims.z;
    pc.dims[3] = m.layout.slab_depth;
    pc.image[0] = o.width;
    pc.image[1] = o.height;
    pc.image[2] =
        (o.shading == Shading::lit ? VF_RAYMARCH_FLAG_LIT : 0u) |
        (o.shading == Shading::lit && o.sky_gradient ? VF_RAYMARCH_FLAG_SKY_GRADIENT : 0u) |
        (m.coarse ? VF_RAYMARCH_FLAG_BLOCK_MIN : 0u) | (o.bgra ? VF_RAYMARCH_FLAG_BGRA : 0u);
    pc.image[3] = pack(o.sky);

    const std::uint32_t pair = m.next_pair;
    m.next_pair = (m.next_pair + 1) % kQueryPairs;
    m.pair_serial[pair] = m.ctx.next_serial();
    m.last_reader = m.ctx.next_serial();

    // The previous march's writes and the copy out of the image (an earlier frame, maybe
    // still running) come before the image is written again.
    VkImageMemoryBarrier to_general{};
    to_general.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER;
    to_general.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    to_general.dstAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    to_general.oldLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    to_general.newLayout = VK_IMAGE_LAYOUT_GENERAL;
    to_general.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    to_general.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
    to_general.image = image_handle;
    to_general.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
    // Host writes to mapped buffers are visible to the device at submission; staged uploads
    // finished (and were waited for) before it.
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 0, nullptr, 0, nullptr, 1,
                         &to_general);
    // Path 1: OpenCL wrote the field through its fd, so the field is acquired from
    // VK_QUEUE_FAMILY_EXTERNAL before the dispatch reads it and released back after.
    const bool external = m.sharing == SharingPath::opaque_fd;
    std::vector<VkBufferMemoryBarrier> ownership;
    if (external) {
        std::vector<VkBuffer> shared;
        for (const Buffer& b : m.field) {
            shared.push_back(b.get());
        }
        if (m.block_min_shared) {
            shared.push_back(m.block_min.get());  // written by OpenCL in the same memory
        }
        for (const VkBuffer b : shared) {
            VkBufferMemoryBarrier acquire{};
            acquire.sType = VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER;
            acquire.srcAccessMask = 0;
            acquire.dstAccessMask = VK_ACCESS_SHADER_READ_BIT;
            acquire.srcQueueFamilyIndex = VK_QUEUE_FAMILY_EXTERNAL;
            acquire.dstQueueFamilyIndex = m.ctx.queue_family();
            acquire.buffer = b;
            acquire.offset = 0;
            acquire.size = VK_WHOLE_SIZE;
            ownership.push_back(acquire);
        }
        vkCmdPipelineBarrier(
            cmd, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, 0, 0,
            nullptr, static_cast<std::uint32_t>(ownership.size()), ownership.data(), 0, nullptr);
    }
    const VkQueryPool timer = m.queries.get();
    if (timer != VK_NULL_HANDLE) {
        vkCmdResetQueryPool(cmd, timer, 2 * pair, 2);
        // Both timestamps at the compute stage, so that they bracket the dispatch on every
        // driver: TOP_OF_PIPE/BOTTOM_OF_PIPE let lavapipe under a window write the pair before
        // the dispatch ran (0.019 ms for a 37 ms ray march).
        vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, timer, 2 * pair);
    }
    vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, pipeline);
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_COMPUTE, m.pipeline_layout.get(), 0, 1,
                            &m.set, 0, nullptr);
    m.set_recorded = true;
    vkCmdPushConstants(cmd, m.pipeline_layout.get(), VK_SHADER_STAGE_COMPUTE_BIT, 0, sizeof pc,
                       &pc);
    const std::uint32_t g = VF_RAYMARCH_LOCAL_SIZE;
    vkCmdDispatch(cmd, (o.width + g - 1) / g, (o.height + g - 1) / g, 1);
    if (timer != VK_NULL_HANDLE) {
        vkCmdWriteTimestamp(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, timer, 2 * pair + 1);
    }
    if (external) {
        for (VkBufferMemoryBarrier& b : ownership) {
            b.srcAccessMask = 0;
            b.dstAccessMask = 0;
            std::swap(b.srcQueueFamilyIndex, b.dstQueueFamilyIndex);
        }
        vkCmdPipelineBarrier(
            cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0, 0,
            nullptr, static_cast<std::uint32_t>(ownership.size()), ownership.data(), 0, nullptr);
    }
    if (o.count) {
        VkMemoryBarrier counted{};
        counted.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
        counted.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
        counted.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
        vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_HOST_BIT,
                             0, 1, &counted, 0, nullptr, 0, nullptr);
    }
    VkImageMemoryBarrier to_copy = to_general;
    to_copy.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT;
    to_copy.dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
    to_copy.oldLayout = VK_IMAGE_LAYOUT_GENERAL;
    to_copy.newLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
    vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                         0, 0, nullptr, 0, nullptr, 1, &to_copy);
    return pair;
}

std::uint32_t Raymarcher::Impl::march(const RenderOptions& o, VkBuffer dst, bool external) {
    Impl& m = *this;
    std::uint32_t pair = 0;
    m.ctx.submit_and_wait(
        [&](VkCommandBuffer cmd) {
            pair = m.record(cmd, o);
            if (dst == VK_NULL_HANDLE) {
                dst = m.target.readback.get();
            }
            VkBufferImageCopy region{};
            region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
            region.imageExtent = {o.width, o.height, 1};
            vkCmdCopyImageToBuffer(cmd, m.target.image.get(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                                   dst, 1, &region);
            if (external) {
                // Release the buffer to the device that imports it (another VkDevice).
                VkBufferMemoryBarrier release{};
                release.sType = VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER;
                release.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
                release.dstAccessMask = 0;
                release.srcQueueFamilyIndex = m.ctx.queue_family();
                release.dstQueueFamilyIndex = VK_QUEUE_FAMILY_EXTERNAL;
                release.buffer = dst;
                release.offset = 0;
                release.size = VkDeviceSize{o.width} * o.height * 4;
                vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                                     VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT, 0, 0, nullptr, 1,
                                     &release, 0, nullptr);
            } else {
                VkMemoryBarrier to_host{};
                to_host.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
                to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
                to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
                vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT,
                                     VK_PIPELINE_STAGE_HOST_BIT, 0, 1, &to_host, 0, nullptr, 0,
                                     nullptr);
            }
        },
        "ray march " + std::to_string(o.width) + "x" + std::to_string(o.height));
    return pair;
}

double Raymarcher::Impl::pair_ms(std::uint32_t pair, bool wait) {
    if (!queries) {
        return -1;
    }
    std::array<std::uint64_t, 2> ts{};
    const VkResult r = vkGetQueryPoolResults(
        ctx.device(), queries.get(), 2 * pair, 2, sizeof ts, ts.data(), sizeof(std::uint64_t),
        wait ? VK_QUERY_RESULT_64_BIT | VK_QUERY_RESULT_WAIT_BIT : VK_QUERY_RESULT_64_BIT);
    if (r == VK_NOT_READY) {
        return -1;
    }
    check(r, "vkGetQueryPoolResults", "ray march timestamps");
    return static_cast<double>(ts[1] - ts[0]) * static_cast<double>(ctx.timestamp_period_ns()) *
           1e-6;
}

void Raymarcher::render(const RenderOptions& o, Image& out) {
    Impl& m = *impl_;
    const std::uint32_t pair = m.march(o, VK_NULL_HANDLE, false);
    const VkDeviceSize bytes = VkDeviceSize{o.width} * o.height * 4;
    out.width = o.width;
    out.height = o.height;
    out.rgba.resize(bytes);
    std::memcpy(out.rgba.data(), m.target.readback.data(), bytes);
    out.raymarch_ms = m.pair_ms(pair, true);
    out.fetches = out.steps = 0;
    if (o.count) {
        const auto* c = static_cast<const std::uint32_t*>(m.counters.data());
        for (std::size_t i = 0; i < std::size_t{o.width} * o.height; ++i) {
            out.fetches += c[2 * i];
            out.steps += c[2 * i + 1];
        }
    }
}

double Raymarcher::render_to(const RenderOptions& o, const ExternalMemory& frame) {
    Impl& m = *impl_;
    const VkDeviceSize bytes = VkDeviceSize{o.width} * o.height * 4;
    if (o.count) {
        throw std::logic_error("Raymarcher::render_to does not count; use render()");
    }
    if (frame.path() != SharingPath::opaque_fd || frame.size() < bytes) {
        throw std::logic_error("Raymarcher::render_to needs exportable memory of " +
                               std::to_string(bytes) + " bytes");
    }
    if (m.frame_memory != frame.memory() || m.frame.size() < bytes) {
        m.ctx.retire(std::move(m.frame));
        m.frame = m.ctx.make_external_buffer(frame.size(), VK_BUFFER_USAGE_TRANSFER_DST_BIT,
                                             frame.handle_type(), "shared frame");
        m.ctx.bind(m.frame, frame.memory(), 0, "shared frame");
        m.frame_memory = frame.memory();
    }
    return m.pair_ms(m.march(o, m.frame.get(), true), true);
}

VkImage Raymarcher::record(VkCommandBuffer cmd, const RenderOptions& o) {
    if (o.count) {
        throw std::logic_error("Raymarcher::record does not count; use render()");
    }
    impl_->record(cmd, o);
    return impl_->target.image.get();
}

double Raymarcher::finished_raymarch_ms() {
    Impl& m = *impl_;
    std::uint32_t latest = kQueryPairs;
    for (std::uint32_t p = 0; p < kQueryPairs; ++p) {
        const std::uint64_t serial = m.pair_serial[p];
        if (serial > m.reported_serial && m.ctx.finished(serial) &&
            (latest == kQueryPairs || serial > m.pair_serial[latest])) {
            latest = p;
        }
    }
    if (latest != kQueryPairs) {
        m.reported_serial = m.pair_serial[latest];
        m.reported_ms = m.pair_ms(latest, false);
    }
    return m.reported_ms;
}

void Raymarcher::set_block_min(std::span<const std::uint32_t> block_min) {
    Impl& m = *impl_;
    const Dims d = m.layout.dims;
    const std::uint64_t blocks = m.block_grid().count();
    if (m.layout.slabs == 0 || block_min.size() != blocks) {
        throw InputError("block minima: " + std::to_string(block_min.size()) +
                         " entries for a field of " + d.to_string() + " (" +
                         std::to_string(blocks) + " blocks of " +
                         std::to_string(VF_RAYMARCH_BLOCK) + "^3)");
    }
    const VkDeviceSize bytes = 4 * blocks;
    // Frames in flight may read the old table: those keep it (retired), this one gets a new one.
    if (m.block_min_shared || m.block_min.size() != bytes || (m.set_recorded && m.ctx.busy())) {
        m.bind_block_min(
            m.ctx.make_buffer(bytes, kTableUsage, MemoryIntent::device_local, "block minima"),
            false, false);
    }
    m.ctx.upload(m.block_min, block_min.data(), bytes);
    m.coarse = true;
    m.block_min_copied += bytes;
}

void Raymarcher::update_block_min(std::span<const Box> blocks,
                                  std::span<const std::uint32_t> minima) {
    Impl& m = *impl_;
    if (!m.coarse || m.block_min_shared) {
        throw std::logic_error("Raymarcher::update_block_min without a table from set_block_min");
    }
    const Dims g = m.block_grid();
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
    m.copy_in_place(minima.data(), bytes, {{m.block_min.get(), rows}}, "block minima update");
    m.block_min_copied += bytes;
}

void Raymarcher::bind_shared_block_min(const ExternalMemory& memory, std::uint64_t offset) {
    Impl& m = *impl_;
    if (m.field.empty() || m.sharing == SharingPath::copy) {
        throw std::logic_error("Raymarcher::bind_shared_block_min: the field is not shared");
    }
    const VkDeviceSize bytes = 4 * m.block_grid().count();
    if (memory.memory() == VK_NULL_HANDLE || offset + bytes > memory.size()) {
        throw std::logic_error("Raymarcher::bind_shared_block_min: the table (" +
                               std::to_string(bytes) + " bytes at " + std::to_string(offset) +
                               ") does not fit in the shared memory (" +
                               std::to_string(memory.size()) + " bytes)");
    }
    Buffer table = m.ctx.make_external_buffer(bytes, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT,
                                              memory.handle_type(), "shared block minima");
    m.ctx.bind(table, memory.memory(), offset, "shared block minima");
    m.bind_block_min(std::move(table), true, true);
}

std::uint64_t Raymarcher::block_min_bytes_copied() const {
    return impl_->block_min_copied;
}

void Raymarcher::set_metric(Metric metric) {
    impl_->metric = metric;
}

Metric Raymarcher::metric() const {
    return impl_->metric;
}

std::uint32_t Raymarcher::field_bindings() const {
    return static_cast<std::uint32_t>(impl_->field.size());
}

std::uint32_t Raymarcher::slab_depth() const {
    return impl_->layout.slab_depth;
}

const FieldLayout& Raymarcher::layout() const {
    return impl_->layout;
}

std::uint64_t Raymarcher::bytes_copied() const {
    return impl_->copied;
}

SharingPath Raymarcher::sharing() const {
    return impl_->sharing;
}

std::string Raymarcher::sharing_path() const {
    return describe(impl_->sharing);
}

}  // namespace voxfield::vk
