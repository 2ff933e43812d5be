// The sparse world's 64-trees shared between OpenCL and the Vulkan tracer (shared_trees.hpp).
#include "voxfield/pipeline/shared_trees.hpp"

#include <algorithm>
#include <functional>
#include <stdexcept>
#include <utility>

#include "voxfield/cl/interop.hpp"
#include "voxfield/core/chunks.hpp"
#include "voxfield/pipeline/render_field.hpp"

namespace voxfield::pipeline {

// One buffer of shared memory: the Vulkan memory, then OpenCL's buffer over it (released
// first: members are destroyed in reverse order), and a serial no other allocation gets.
struct SharedTrees::Allocation {
    vk::ExternalMemory memory;
    cl::Buffer buffer;
    std::uint64_t serial = 0;
};

namespace {

// Drops the last "; " of choose_sharing_path's reasons.
void trim(std::string& why_not) {
    if (why_not.size() >= 2 && why_not.compare(why_not.size() - 2, 2, "; ") == 0) {
        why_not.resize(why_not.size() - 2);
    }
}

}  // namespace

SharedTrees::SharedTrees(ocl::Context& cl_ctx, vk::Context& vk_ctx, vk::SharingPath fastest,
                         std::uint64_t max_allocation_bytes)
    : cl_(cl_ctx), vk_(vk_ctx), max_allocation_(vk_ctx.info().max_buffer_size) {
    if (max_allocation_bytes != 0) {
        max_allocation_ = max_allocation_ == 0 ? max_allocation_bytes
                                               : std::min(max_allocation_, max_allocation_bytes);
    }
    if (!vk_ctx.buffer_device_address()) {
        why_not_ =
            "the Vulkan device lacks buffer device addresses, through which the tracer "
            "reads shared trees";
        return;
    }
    path_ = choose_sharing_path(cl_ctx, vk_ctx, why_not_, fastest);
    if (path_ == vk::SharingPath::opaque_fd) {
        // As RenderField falls back: a small allocation exported, imported, acquired and
        // released first, so that a driver that refuses fails here rather than in the field.
        try {
            allocate(4096, "sharing probe");
            ocl::release_external(cl_, allocations_.back()->buffer);
            cl_.queue().finish();
            allocations_.clear();
        } catch (const std::exception& e) {
            try {
                cl_.queue().finish();  // the import's commands, before its memory goes
            } catch (const cl::Error&) {
            }
            allocations_.clear();
            why_not_ += std::string("path 1 failed: ") + e.what() + "; ";
            path_ = vk::supports(vk_ctx, vk::SharingPath::host_pointer) &&
                            ocl::can_use_host_memory(cl_ctx)
                        ? vk::SharingPath::host_pointer
                        : vk::SharingPath::copy;
        }
    }
    trim(why_not_);
}

SharedTrees::~SharedTrees() {
    free_where([](const Allocation&) { return true; });
}

void SharedTrees::free_where(const std::function<bool(const Allocation&)>& drop) {
    if (std::none_of(allocations_.begin(), allocations_.end(),
                     [&](const std::unique_ptr<Allocation>& a) { return drop(*a); })) {
        return;
    }
    // On path 1 OpenCL holds the buffers (acquired) outside trace scopes: it gives back those
    // that go, and its queue finishes, before their memory is freed. Each step is tried
    // whatever the others did; the memory goes in any case (the world no longer uses it), and
    // a device that failed here reports it at its next command.
    if (path_ == vk::SharingPath::opaque_fd && !tracing_) {
        for (const auto& a : allocations_) {
            if (drop(*a)) {
                try {
                    ocl::release_external(cl_, a->buffer);
                } catch (const std::exception&) {
                }
            }
        }
    }
    try {
        cl_.queue().finish();
    } catch (const std::exception&) {
    }
    std::erase_if(allocations_, [&](const std::unique_ptr<Allocation>& a) { return drop(*a); });
}

ocl::TreeAllocator SharedTrees::allocator() {
    if (!shares()) {
        return {};
    }
    ocl::TreeAllocator a;
    a.allocate = [this](std::size_t bytes, const std::string& what) {
        return allocate(bytes, what);
    };
    a.dropped = [this](const std::vector<cl::Buffer>& kept) { dropped(kept); };
    return a;
}

cl::Buffer SharedTrees::allocate(std::size_t bytes, const std::string& what) {
    auto a = std::make_unique<Allocation>();
    const std::string name = what + " (shared with Vulkan)";
    if (max_allocation_ != 0 && bytes > max_allocation_) {
        throw AllocationError(name + ": " + std::to_string(bytes) + " bytes exceed one buffer of " +
                              vk_.info().name + " (" + std::to_string(max_allocation_) + " bytes)");
    }
    try {
        if (path_ == vk::SharingPath::opaque_fd) {
            a->memory = vk::ExternalMemory::exportable(vk_, bytes, vk::kSharedTreeUsage, name);
            // The import takes the fd on every way out.
            a->buffer = ocl::import_opaque_fd(cl_, a->memory.export_fd(), bytes);
            ocl::acquire_external(cl_, a->buffer);  // OpenCL's outside trace scopes
        } else {
            a->memory = vk::ExternalMemory::host_allocation(vk_, bytes, vk::kSharedTreeUsage, name);
            a->buffer = ocl::wrap_host_memory(cl_, a->memory.host_pointer(),
                                              static_cast<std::size_t>(a->memory.size()));
        }
    } catch (const std::exception& e) {
        throw AllocationError(name + ": " + e.what());
    }
    a->serial = next_serial_++;
    cl::Buffer b = a->buffer;
    allocations_.push_back(std::move(a));
    return b;
}

void SharedTrees::dropped(const std::vector<cl::Buffer>& kept) {
    // The world finished its queue and holds only `kept`: no command uses the others.
    const auto unused = [&](const Allocation& a) {
        return std::none_of(kept.begin(), kept.end(),
                            [&](const cl::Buffer& b) { return b() == a.buffer(); });
    };
    if (std::none_of(allocations_.begin(), allocations_.end(),
                     [&](const std::unique_ptr<Allocation>& a) { return unused(*a); })) {
        return;
    }
    if (tracer_ != nullptr) {
        tracer_->drop_shared();  // it reads nothing of them before the next (whole) sync
    }
    traced_main_ = 0;
    free_where(unused);
}

const SharedTrees::Allocation* SharedTrees::allocation_of(const cl::Buffer& buffer) const {
    for (const auto& a : allocations_) {
        if (a->buffer() == buffer()) {
            return a.get();
        }
    }
    return nullptr;
}

std::vector<vk::SharedTreeSet> SharedTrees::sets_of(
    const ocl::SparseDeviceWorld::TreeBuffers& b) const {
    const auto set = [&](const cl::Buffer& masks, const cl::Buffer& offsets,
                         const cl::Buffer& materials) {
        vk::SharedTreeSet s;
        const Allocation* parts[3] = {allocation_of(masks), allocation_of(offsets),
                                      allocation_of(materials)};
        if (parts[0] == nullptr || parts[1] == nullptr || parts[2] == nullptr) {
            throw std::logic_error(
                "SharedTrees::sync: the world's trees are not in shared memory (make the field "
                "with allocator())");
        }
        s.masks = &parts[0]->memory;
        s.offsets = &parts[1]->memory;
        s.materials = &parts[2]->memory;
        s.serials = {parts[0]->serial, parts[1]->serial, parts[2]->serial};
        return s;
    };
    return {set(b.masks, b.offsets, b.materials),
            set(b.slot_masks, b.slot_offsets, b.slot_materials)};
}

void SharedTrees::free_unused(const ocl::SparseDeviceWorld::TreeBuffers& b) {
    const cl_mem live[] = {b.masks(),      b.offsets(),      b.materials(),
                           b.slot_masks(), b.slot_offsets(), b.slot_materials()};
    free_where([&](const Allocation& a) {
        return std::find(std::begin(live), std::end(live), a.buffer()) == std::end(live);
    });
}

vk::SparseTileUpdate SharedTrees::sync(vk::SparseTracer& tracer,
                                       const ocl::SparseDeviceWorld& world, const Dims& dims,
                                       const Palette& palette, const Box& changed) {
    const Box box = intersect(changed, Box{{0, 0, 0}, {dims.x, dims.y, dims.z}});
    return sync_tiles(tracer, world, dims, palette, tiles_overlapping(box));
}

vk::SparseTileUpdate SharedTrees::sync(vk::SparseTracer& tracer,
                                       const ocl::SparseDeviceWorld& world, const Dims& dims,
                                       const Palette& palette,
                                       const std::vector<Int3>& changed_tiles) {
    return sync_tiles(tracer, world, dims, palette, changed_tiles);
}

vk::SparseTileUpdate SharedTrees::sync_tiles(vk::SparseTracer& tracer,
                                             const ocl::SparseDeviceWorld& world, const Dims& dims,
                                             const Palette& palette,
                                             const std::vector<Int3>& changed_tiles) {
    if (!shares()) {
        throw std::logic_error("SharedTrees::sync on path 3 (nothing is shared)");
    }
    if (tracing_) {
        throw std::logic_error("SharedTrees::sync inside a trace scope");
    }
    ocl::cl_call("finishing the world's edits before the tracer reads them",
                 [&] { cl_.queue().finish(); });
    const ocl::SparseDeviceWorld::TreeBuffers b = world.tree_buffers();
    const std::vector<vk::SharedTreeSet> sets = sets_of(b);
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
    if (tracer_ != &tracer) {
        traced_main_ = 0;  // another tracer: its directory is made whole
    }
    tracer_ = &tracer;
    try {
        if (sets[0].serials[0] != traced_main_) {
            std::vector<vk::SharedTile> tiles;
            for (const auto& [c, ref] : world.refs()) {
                tiles.push_back(tile_of(c, ref));
            }
            tracer.upload_shared(dims, palette, sets, tiles);
            traced_main_ = sets[0].serials[0];
            u.whole = true;
            u.tiles_written = static_cast<std::uint32_t>(tiles.size());
        } else {
            std::vector<vk::SharedTile> tiles;
            std::vector<Int3> removed;
            for (const Int3& c : changed_tiles) {
                const auto ref = world.ref(c.x, c.y, c.z);
                if (ref.first == ocl::SparseDeviceWorld::kNoRef) {
                    removed.push_back(c);
                } else {
                    tiles.push_back(tile_of(c, ref));
                }
            }
            u = tracer.repoint(sets, tiles, removed);
        }
    } catch (...) {
        traced_main_ = 0;  // the next sync makes the tracer's directory whole
        throw;
    }
    free_unused(b);
    return u;
}

SharedTrees::TraceScope::TraceScope(SharedTrees& shared) : shared_(shared) {
    shared_.begin_trace();
}

SharedTrees::TraceScope::~TraceScope() {
    shared_.end_trace();
}

void SharedTrees::forget(const vk::SparseTracer& tracer) {
    if (tracer_ == &tracer) {
        tracer_ = nullptr;
        traced_main_ = 0;
    }
}

void SharedTrees::begin_trace() {
    if (tracing_) {
        throw std::logic_error("SharedTrees: a trace scope inside another");
    }
    if (!shares()) {
        return;
    }
    ocl::cl_call("handing the shared trees to Vulkan", [&] {
        auto& q = cl_.queue();
        try {
            for (const auto& a : allocations_) {
                if (path_ == vk::SharingPath::opaque_fd) {
                    ocl::release_external(cl_, a->buffer);
                    held_.emplace_back(a->buffer, nullptr);
                } else {
                    void* p = q.enqueueMapBuffer(a->buffer, CL_FALSE, CL_MAP_READ, 0,
                                                 a->buffer.getInfo<CL_MEM_SIZE>());
                    held_.emplace_back(a->buffer, p);
                }
            }
            q.finish();
        } catch (...) {
            end_trace();
            throw;
        }
    });
    tracing_ = true;
}

void SharedTrees::end_trace() noexcept {
    try {
        for (const auto& [buffer, mapped] : held_) {
            if (path_ == vk::SharingPath::opaque_fd) {
                ocl::acquire_external(cl_, buffer);
            } else {
                cl_.queue().enqueueUnmapMemObject(buffer, mapped);
            }
        }
    } catch (const std::exception&) {
        // A destructor's path: the next OpenCL call reports the device's state.
    }
    held_.clear();
    tracing_ = false;
}

std::uint64_t SharedTrees::bytes() const {
    std::uint64_t n = 0;
    for (const auto& a : allocations_) {
        n += a->memory.size();
    }
    return n;
}

}  // namespace voxfield::pipeline
