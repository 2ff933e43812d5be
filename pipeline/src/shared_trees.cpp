// The sparse world's 64-trees shared between OpenCL and the Vulkan tracer (shared_trees.hpp).
#include "voxfield/pipeline/shared_trees.hpp"

#include <algorithm>
#include <stdexcept>
#include <utility>

#include "voxfield/cl/interop.hpp"
#include "voxfield/core/chunks.hpp"
#include "voxfield/pipeline/render_field.hpp"

namespace voxfield::pipeline {

// One buffer of shared memory: the Vulkan memory, then OpenCL's buffer over it (released
// first: members are destroyed in reverse order).
struct SharedTrees::Allocation {
    vk::ExternalMemory memory;
    cl::Buffer buffer;
};

SharedTrees::SharedTrees(ocl::Context& cl_ctx, vk::Context& vk_ctx, vk::SharingPath fastest)
    : cl_(cl_ctx), vk_(vk_ctx) {
    path_ = choose_sharing_path(cl_ctx, vk_ctx, why_not_, fastest);
    if (why_not_.size() >= 2) {
        why_not_.resize(why_not_.size() - 2);  // the last "; "
    }
}

SharedTrees::~SharedTrees() {
    try {
        cl_.queue().finish();
    } catch (const cl::Error&) {
    }
}

ocl::TreeAllocator SharedTrees::allocator() {
    if (!shares()) {
        return {};
    }
    return [this](std::size_t bytes, const std::string& what) { return allocate(bytes, what); };
}

cl::Buffer SharedTrees::allocate(std::size_t bytes, const std::string& what) {
    auto a = std::make_unique<Allocation>();
    const std::string name = what + " (shared with Vulkan)";
    if (path_ == vk::SharingPath::opaque_fd) {
        a->memory = vk::ExternalMemory::exportable(vk_, bytes, vk::kSharedTreeUsage, name);
        // The import takes the fd on every way out.
        a->buffer = ocl::import_opaque_fd(cl_, a->memory.export_fd(), bytes);
        ocl::acquire_external(cl_, a->buffer);  // OpenCL's until before_trace
    } else {
        a->memory = vk::ExternalMemory::host_allocation(vk_, bytes, vk::kSharedTreeUsage, name);
        a->buffer = ocl::wrap_host_memory(cl_, a->memory.host_pointer(),
                                          static_cast<std::size_t>(a->memory.size()));
    }
    cl::Buffer b = a->buffer;
    allocations_.push_back(std::move(a));
    return b;
}

const vk::ExternalMemory* SharedTrees::memory_of(const cl::Buffer& buffer) const {
    for (const auto& a : allocations_) {
        if (a->buffer() == buffer()) {
            return &a->memory;
        }
    }
    return nullptr;
}

std::vector<vk::SharedTreeSet> SharedTrees::sets_of(
    const ocl::SparseDeviceWorld::TreeBuffers& b) const {
    return {{memory_of(b.masks), memory_of(b.offsets), memory_of(b.materials)},
            {memory_of(b.slot_masks), memory_of(b.slot_offsets), memory_of(b.slot_materials)}};
}

void SharedTrees::free_unused(const ocl::SparseDeviceWorld::TreeBuffers& b) {
    const cl_mem live[] = {b.masks(),      b.offsets(),      b.materials(),
                           b.slot_masks(), b.slot_offsets(), b.slot_materials()};
    std::erase_if(allocations_, [&](const std::unique_ptr<Allocation>& a) {
        return std::find(std::begin(live), std::end(live), a->buffer()) == std::end(live);
    });
}

vk::SparseTileUpdate SharedTrees::sync(vk::SparseTracer& tracer,
                                       const ocl::SparseDeviceWorld& world, const Dims& dims,
                                       const Palette& palette, const Box& changed) {
    if (!shares()) {
        throw std::logic_error("SharedTrees::sync on path 3 (nothing is shared)");
    }
    ocl::cl_call("finishing the world's edits before the tracer reads them",
                 [&] { cl_.queue().finish(); });
    const ocl::SparseDeviceWorld::TreeBuffers b = world.tree_buffers();
    const std::vector<vk::SharedTreeSet> sets = sets_of(b);
    for (const vk::SharedTreeSet& s : sets) {
        if (s.masks == nullptr || s.offsets == nullptr || s.materials == nullptr) {
            throw std::logic_error(
                "SharedTrees::sync: the world's trees are not in shared memory (make the field "
                "with allocator())");
        }
    }
    const auto tile_of = [](const Int3& c, const std::pair<std::uint64_t, std::uint64_t>& ref) {
        vk::SharedTile t;
        t.tile = c;
        const bool slot = (ref.first & ocl::SparseDeviceWorld::kSlotRef) != 0;
        t.set = slot ? 1 : 0;
        t.node = ref.first & ~ocl::SparseDeviceWorld::kSlotRef;
        t.material = ref.second;
        return t;
    };
    vk::SparseTileUpdate u;
    if (b.masks() != traced_main_) {
        std::vector<vk::SharedTile> tiles;
        for (const auto& [c, ref] : world.refs()) {
            tiles.push_back(tile_of(c, ref));
        }
        tracer.upload_shared(dims, palette, sets, tiles);
        traced_main_ = b.masks();
        u.whole = true;
        u.tiles_written = static_cast<std::uint32_t>(tiles.size());
    } else {
        std::vector<vk::SharedTile> tiles;
        std::vector<Int3> removed;
        const Box box = intersect(changed, Box{{0, 0, 0}, {dims.x, dims.y, dims.z}});
        if (!box.empty()) {
            const std::int64_t ts = kTileSize;
            for (std::int64_t tz = box.min.z / ts; tz <= (box.max.z - 1) / ts; ++tz) {
                for (std::int64_t ty = box.min.y / ts; ty <= (box.max.y - 1) / ts; ++ty) {
                    for (std::int64_t tx = box.min.x / ts; tx <= (box.max.x - 1) / ts; ++tx) {
                        const auto ref = world.ref(tx, ty, tz);
                        if (ref.first == ocl::SparseDeviceWorld::kNoRef) {
                            removed.push_back({tx, ty, tz});
                        } else {
                            tiles.push_back(tile_of({tx, ty, tz}, ref));
                        }
                    }
                }
            }
        }
        u = tracer.repoint(sets, tiles, removed);
    }
    free_unused(b);
    return u;
}

void SharedTrees::before_trace() {
    if (path_ != vk::SharingPath::opaque_fd) {
        return;
    }
    ocl::cl_call("handing the shared trees to Vulkan", [&] {
        for (const auto& a : allocations_) {
            ocl::release_external(cl_, a->buffer);
            released_.push_back(a->buffer);
        }
        cl_.queue().finish();
    });
}

void SharedTrees::after_trace() {
    if (path_ != vk::SharingPath::opaque_fd) {
        return;
    }
    for (const cl::Buffer& b : released_) {
        ocl::acquire_external(cl_, b);
    }
    released_.clear();
}

std::uint64_t SharedTrees::bytes() const {
    std::uint64_t n = 0;
    for (const auto& a : allocations_) {
        n += a->memory.size();
    }
    return n;
}

}  // namespace voxfield::pipeline
