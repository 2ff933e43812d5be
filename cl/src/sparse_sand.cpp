// Falling sand and water on sparse worlds (kernels: cl/kernels/sand.cl sand_step_windows,
// sparse_world.cl gather and the encoding passes; rules: core/sand.hpp).
// Source: Toffoli & Margolus, "Cellular Automata Machines" (1987), ch. 12 (Margolus blocks).
#include "voxfield/cl/sparse_sand.hpp"

#include <algorithm>
#include <string>

#include "util.hpp"
#include "voxfield/core/error.hpp"

namespace voxfield::cl_sources {
extern const char* const sand_cl;
}  // namespace voxfield::cl_sources

namespace voxfield::ocl {

namespace {

// sand.cl's window (VF_WIN_*): a tile, one voxel more on every side and two below.
constexpr std::int64_t kWinX = 66, kWinY = 67, kWinZ = 66;
constexpr std::uint64_t kWinVoxels = kWinX * kWinY * kWinZ;
// The window index of the tile's voxel (0, 0, 0).
constexpr std::uint64_t kTileFirst = (1 * kWinY + 2) * kWinX + 1;
constexpr std::int64_t kWinCorner[3] = {1, 2, 1};
// A change reaches the blocks within one voxel of it, and their cells and those below them.
constexpr std::int64_t kReach = 2;
// The block partition repeats every kPeriod steps (sand_block_offset).
constexpr std::uint64_t kPeriod = 8;
// sand_step_windows' summary words per window.
constexpr std::size_t kSummaryWords = 8;
// sand_step_windows' work-group: a row of block columns.
constexpr std::size_t kColumns = 33;

cl_int4 int4_of(std::int64_t x, std::int64_t y, std::int64_t z) {
    return {{static_cast<cl_int>(x), static_cast<cl_int>(y), static_cast<cl_int>(z), 0}};
}

}  // namespace

SparseSand::SparseSand(Context& ctx, SparseField& field, const SandRules& rules)
    : ctx_(ctx),
      field_(field),
      dims_(field.world().dims()),
      rules_(rules),
      gpu_layout_(field.options().layout == Layout::automatic
                      ? !ctx.is_cpu()
                      : field.options().layout == Layout::gpu) {
    check_sand_rules(rules);
    const cl::Program program = ctx.program("sand.cl", {cl_sources::sand_cl}, "-cl-std=CL1.2");
    cl_call("making the sparse sand kernel",
            [&] { kernel_ = cl::Kernel(program, "sand_step_windows"); });
}

void SparseSand::ensure_capacity(std::size_t windows) {
    if (windows <= capacity_) {
        return;
    }
    const std::size_t cap = std::max({windows, 2 * capacity_, std::size_t{8}});
    cl_call("allocating " + std::to_string(cap) + " sand windows", [&] {
        auto& c = ctx_.context();
        windows_ = cl::Buffer(c, CL_MEM_READ_WRITE, cap * kWinVoxels);
        jobs_ = cl::Buffer(c, CL_MEM_READ_ONLY, cap * 8 * sizeof(std::int64_t));
        refs_ = cl::Buffer(c, CL_MEM_READ_ONLY, cap * 27 * 2 * sizeof(std::uint64_t));
        tiles_ = cl::Buffer(c, CL_MEM_READ_ONLY, cap * 3 * sizeof(cl_int));
        summary_ = cl::Buffer(c, CL_MEM_READ_WRITE, cap * kSummaryWords * sizeof(cl_uint));
    });
    capacity_ = cap;
}

void SparseSand::activate_sandy(std::uint64_t s) {
    const SparseWorld& w = field_.world();
    const auto& materials = w.materials();
    for (std::uint32_t t = 0; t < w.tile_count(); ++t) {
        const auto first = materials.begin() + static_cast<std::ptrdiff_t>(w.material_bases()[t]);
        const auto last = first + w.material_counts()[t];
        if (std::any_of(first, last,
                        [&](std::uint8_t v) { return v == rules_.sand || v == rules_.water; })) {
            active_.emplace_back(tile_voxels(w.tile_coord(t)), s + kPeriod - 1);
        }
    }
}

void SparseSand::touched(const Box& box) {
    if (next_ && !box.empty()) {
        active_.emplace_back(box, *next_ + kPeriod - 1);
    }
}

std::vector<std::uint64_t> SparseSand::tiles_to_run(std::uint64_t s) {
    std::erase_if(active_, [&](const auto& a) { return a.second < s; });
    const Dims d = dims_;
    const Box all{{0, 0, 0}, {d.x, d.y, d.z}};
    std::vector<std::uint64_t> keys;
    for (const auto& [box, until] : active_) {
        const Box r = intersect(Box{{box.min.x - kReach, box.min.y - kReach, box.min.z - kReach},
                                    {box.max.x + kReach, box.max.y + kReach, box.max.z + kReach}},
                                all);
        if (r.empty()) {
            continue;
        }
        const std::int64_t ts = kTileSize;
        for (std::int64_t z = r.min.z / ts; z <= (r.max.z - 1) / ts; ++z) {
            for (std::int64_t y = r.min.y / ts; y <= (r.max.y - 1) / ts; ++y) {
                for (std::int64_t x = r.min.x / ts; x <= (r.max.x - 1) / ts; ++x) {
                    keys.push_back(tile_key(static_cast<std::uint32_t>(x),
                                            static_cast<std::uint32_t>(y),
                                            static_cast<std::uint32_t>(z)));
                }
            }
        }
    }
    std::sort(keys.begin(), keys.end());
    keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
    return keys;
}

SparseSand::Step SparseSand::step(std::uint64_t seed, std::uint64_t s) {
    if (!next_ || *next_ != s) {
        active_.clear();
        activate_sandy(s);
    }
    next_ = s + 1;
    const std::vector<std::uint64_t> keys = tiles_to_run(s);
    Step result;
    if (keys.empty()) {
        return result;
    }
    const auto n = keys.size();
    const Dims d = dims_;
    SparseDeviceWorld& world = field_.device_world();
    host_jobs_.clear();
    host_refs_.clear();
    host_tiles_.clear();
    for (std::size_t w = 0; w < n; ++w) {
        const Int3 t = tile_of_key(keys[w]);
        const std::int64_t ts = kTileSize;
        host_jobs_.insert(host_jobs_.end(), {t.x * ts - kWinCorner[0], t.y * ts - kWinCorner[1],
                                             t.z * ts - kWinCorner[2], t.x - 1, t.y - 1, t.z - 1,
                                             3 | std::int64_t{3} << 16 | std::int64_t{3} << 32,
                                             static_cast<std::int64_t>(w * 27)});
        for (std::int64_t z = t.z - 1; z <= t.z + 1; ++z) {
            for (std::int64_t y = t.y - 1; y <= t.y + 1; ++y) {
                for (std::int64_t x = t.x - 1; x <= t.x + 1; ++x) {
                    const auto [node_base, material_base] = world.ref(x, y, z);
                    host_refs_.insert(host_refs_.end(), {node_base, material_base});
                }
            }
        }
        host_tiles_.insert(host_tiles_.end(), {static_cast<cl_int>(t.x), static_cast<cl_int>(t.y),
                                               static_cast<cl_int>(t.z)});
    }
    ensure_capacity(n);
    host_summary_.assign(n * kSummaryWords, 0);
    const Int3 o = sand_block_offset(s);
    const cl_int4 nb = int4_of((d.x + o.x + 1) / 2, (d.y + o.y + 1) / 2, (d.z + o.z + 1) / 2);
    // `wall` marks cells outside the world: a value other than air, sand and water.
    const cl_uint wall = rules_.sand != 1 && rules_.water != 1   ? 1
                         : rules_.sand != 2 && rules_.water != 2 ? 2
                                                                 : 3;
    cl_call("sparse sand step " + std::to_string(s) + " on " + std::to_string(n) + " tiles", [&] {
        auto& q = ctx_.queue();
        cl::Event first, last;
        q.enqueueWriteBuffer(jobs_, CL_FALSE, 0, host_jobs_.size() * 8, host_jobs_.data(), nullptr,
                             &first);
        q.enqueueWriteBuffer(refs_, CL_FALSE, 0, host_refs_.size() * 8, host_refs_.data());
        q.enqueueWriteBuffer(tiles_, CL_FALSE, 0, host_tiles_.size() * sizeof(cl_int),
                             host_tiles_.data());
        q.enqueueWriteBuffer(summary_, CL_FALSE, 0, host_summary_.size() * sizeof(cl_uint),
                             host_summary_.data());
        world.enqueue_gather(
            jobs_, refs_, windows_,
            Dims{static_cast<std::uint32_t>(kWinX), static_cast<std::uint32_t>(kWinY),
                 static_cast<std::uint32_t>(kWinZ)},
            n);
        kernel_.setArg(0, windows_);
        kernel_.setArg(1, tiles_);
        kernel_.setArg(2, int4_of(d.x, d.y, d.z));
        kernel_.setArg(3, int4_of(o.x, o.y, o.z));
        kernel_.setArg(4, nb);
        kernel_.setArg(5, static_cast<cl_ulong>(sand_step_key(seed, s)));
        kernel_.setArg(6, static_cast<cl_uint>(rules_.sand));
        kernel_.setArg(7, static_cast<cl_uint>(rules_.water));
        kernel_.setArg(8, wall);
        kernel_.setArg(9, summary_);
        q.enqueueNDRangeKernel(kernel_, cl::NullRange, cl::NDRange(kColumns, kColumns, n),
                               cl::NDRange(kColumns, 1, 1));
        q.enqueueReadBuffer(summary_, CL_TRUE, 0, host_summary_.size() * sizeof(cl_uint),
                            host_summary_.data(), nullptr, &last);
        result.simulate_ms = elapsed_ms(first, last);
    });
    result.tiles_run = static_cast<std::uint32_t>(n);
    std::vector<SparseDeviceWorld::DenseTile> changed_tiles;
    std::vector<Box> boxes;
    for (std::size_t w = 0; w < n; ++w) {
        const cl_uint* sw = host_summary_.data() + w * kSummaryWords;
        if (sw[0] == 0) {
            continue;
        }
        const Int3 t = tile_of_key(keys[w]);
        const std::int64_t ts = kTileSize;
        const Int3 corner{t.x * ts - kWinCorner[0], t.y * ts - kWinCorner[1],
                          t.z * ts - kWinCorner[2]};
        const Box box{
            {corner.x + kWinX - sw[1], corner.y + kWinY - sw[2], corner.z + kWinZ - sw[3]},
            {corner.x + sw[4], corner.y + sw[5], corner.z + sw[6]}};
        result.changed += sw[0];
        result.bounds = result.bounds.empty() ? box : hull(result.bounds, box);
        changed_tiles.push_back({t, w * kWinVoxels + kTileFirst});
        result.tiles.push_back(t);
        boxes.push_back(box);
        active_.emplace_back(box, s + kPeriod);
    }
    result.tiles_changed = static_cast<std::uint32_t>(changed_tiles.size());
    if (!changed_tiles.empty()) {
        result.update =
            field_.apply_dense_tiles(windows_, kWinX, kWinX * kWinY, changed_tiles, boxes);
        result.update_ms = result.update.kernel_ms;
    }
    return result;
}

}  // namespace voxfield::ocl
