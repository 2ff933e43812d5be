#pragma once
// Every distance-field generator behind one interface: `exact` (ours) and the family of the
// dissertation (chapter 4), selected by name as DESIGN §4 lists them.
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "voxfield/cl/runtime.hpp"
#include "voxfield/core/chunks.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/metric.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield::ocl {

enum class Algorithm {
    exact,
    brute,
    brute_chunked,
    fim_host,
    fim,
    jfa_host,
    jfa,
    jfa_fim,
    lod,
    monolithic
};

// Names in DESIGN §4 order ("exact", "brute", "brute-chunked", ...).
const std::vector<std::string>& algorithm_names();
// Throws InputError naming the known algorithms.
Algorithm parse_algorithm(const std::string& name);
std::string to_string(Algorithm a);

// jfa, jfa-host and lod can over-estimate (never under-estimate); the rest are exact for
// their semantics (lod and monolithic only inside their focus).
bool is_approximate(Algorithm a);

// brute-chunked, lod and monolithic are chunk-local by definition; without --chunk they use
// the dissertation's 16^3 chunks.
inline constexpr std::uint32_t kDefaultChunk = 16;
bool always_chunked(Algorithm a);

// Which kernel layout `exact` runs: `automatic` picks by device type; tests force each one
// on PoCL so that the GPU kernels are checked where CI runs.
enum class Layout { automatic, cpu, gpu };

struct GeneratorOptions {
    Algorithm algorithm = Algorithm::exact;
    Format format = Format::u16;
    // 0: global semantics (DESIGN §3); C: chunk-local with the solid padding shell.
    std::uint32_t chunk = 0;
    // lod and monolithic: FIM only in these chunks; default: the centre chunk, size 1.
    std::optional<Focus> focus;
    // JFA+1 / JFA+2 (Rong & Tan): extra passes at steps (2,) 1 after the regular ones.
    std::uint32_t jfa_extra = 0;
    Layout layout = Layout::automatic;  // exact only
    // exact only (the dissertation's algorithms are Manhattan with unit spacing):
    Metric metric = Metric::manhattan;
    Spacing spacing;            // world axis order x, y, z
    bool signed_field = false;  // DESIGN §3 signed field; needs a format that holds_sign
    bool indices = false;       // also compute the feature transform (unsigned fields only)
    // Bounded field (DESIGN §3): exact up to D, D beyond; an incremental update then touches
    // only voxels within D of an edit. Positive and finite.
    std::optional<double> max_distance;
};

// The format a field gets when none is asked for (DESIGN §3): u16 (i16 when signed) for
// manhattan and chebyshev with unit spacing, f32 otherwise.
Format default_format(Metric metric, const Spacing& spacing, bool signed_field);

// Fills in defaults (chunk for always-chunked algorithms, focus) and checks the options
// against the world; throws InputError with what to change.
GeneratorOptions resolve_options(const GeneratorOptions& options, Dims world);

// The field a generator must match (exactly, or as the bound of an approximate one):
// global or chunk-local by options.chunk. Unsaturated, kInfinite where nothing is reached.
std::vector<std::uint32_t> exact_reference(const World& world, const GeneratorOptions& options);

// One kernel launch of a generator's run(): its name (per-kernel timings) and its ranges.
struct KernelLaunch {
    std::string name;
    cl::Kernel kernel;
    cl::NDRange global, local;
};

// A world resident on the device with its output buffer, transformed any number of times
// (benchmarks repeat run() without re-uploading).
class Generator {
  public:
    // Waits for the queue when kernels use host memory of the generator's own.
    virtual ~Generator();
    Generator(const Generator&) = delete;
    Generator& operator=(const Generator&) = delete;

    // Enqueues the transform, waits, and returns the time from the first kernel's start to
    // the last one's end (profiling events; host round trips of the *-host variants
    // included, as that is what they cost).
    virtual double run() = 0;
    // Enqueues the transform without waiting and appends (kernel name, event) per launch to
    // `events`; false, with nothing enqueued, where the transform needs a host round trip
    // (run() it then). Stage times are the caller's to read once the queue passed them.
    virtual bool enqueue(std::vector<std::pair<std::string, cl::Event>>& events) {
        static_cast<void>(events);
        return false;
    }
    // Whether enqueue() gives each launch a profiling event (the default) or none, appending
    // nothing to its `events`: NVIDIA's driver spends about 7 us more host time on a launch
    // that returns an event (bench/cl_overhead.c). run() always profiles its stages.
    void set_stage_events(bool on) { stage_events_ = on; }
    // The launches the last enqueue() enqueued.
    std::size_t last_enqueued() const { return last_enqueued_; }
    // Reads the field back (element_size(format) bytes per voxel, little-endian).
    std::vector<std::uint8_t> read(double* download_ms = nullptr);
    // Reads the feature transform back: int32 planes z, y, x of the nearest solid voxel of
    // every voxel (shape (3, Z, Y, X)), -1 where there is none. Only for generators made
    // with options.indices; std::logic_error otherwise.
    std::vector<std::int32_t> read_indices();
    // The same bytes (little-endian int32, plane z, then y, then x) handed to `sink` in order,
    // a slab of at most `slab_bytes` at a time, mapped rather than copied: in place on a
    // device that computes in host memory, else into the driver's host copy of that slab. The
    // next slab's map is queued while `sink` takes one, so the host holds at most two slabs
    // besides the device's buffer (a caller can write the planes out without a whole-volume
    // copy). Only for generators made with options.indices; std::logic_error otherwise.
    using IndexSink = std::function<void(std::span<const std::uint8_t>)>;
    static constexpr std::size_t kIndexSlabBytes = std::size_t{32} << 20;
    void read_indices(const IndexSink& sink, std::size_t slab_bytes = kIndexSlabBytes);

    double upload_ms() const { return upload_ms_; }
    // Per-kernel time of the last run(), in first-enqueue order, summed over repeated
    // launches of one kernel: {kernel name, ms}.
    const std::vector<std::pair<std::string, double>>& stage_ms() const { return stage_ms_; }
    // FIM passes of the last run that changed some voxel (the slowest chunk's count for
    // per-chunk kernels); 0 for algorithms without FIM.
    std::uint32_t iterations() const { return iterations_; }
    // Short description of how it ran (kernel layout, chunking), for reports.
    virtual std::string variant() const = 0;
    // The buffer the field is written to (for later consumers such as the renderer).
    const cl::Buffer& field_buffer() const { return out_; }

  protected:
    Generator(Context& ctx, Dims dims, Format format) : ctx_(ctx), dims_(dims), format_(format) {}
    // Records stage times from (name, event) pairs in enqueue order.
    void record_stages(const std::vector<std::pair<std::string, cl::Event>>& events);
    // Enqueues `stages` in order, appending (kernel name, event) per launch to `events`, or
    // nothing and no events without `with_events` (enqueue() passes stage_events_).
    void enqueue_stages(std::span<const KernelLaunch> stages,
                        std::vector<std::pair<std::string, cl::Event>>& events,
                        bool with_events = true);
    // A buffer of `bytes` (flags: its CL_MEM_READ_* access). On a device that computes in
    // host memory it lies in HostMemory the generator keeps (CL_MEM_USE_HOST_PTR), never
    // zero-filled: the first kernel that writes it touches its pages, in parallel, and the
    // host maps it without a copy. Elsewhere it is device memory.
    cl::Buffer make_buffer(std::size_t bytes, cl_mem_flags flags);

    Context& ctx_;
    Dims dims_;
    Format format_;
    std::vector<HostMemory> host_memory_;  // behind make_buffer's buffers; released after them
    cl::Buffer out_;
    cl::Buffer indices_;  // set by generators that compute the feature transform
    double upload_ms_ = 0;
    std::uint32_t iterations_ = 0;
    std::vector<std::pair<std::string, double>> stage_ms_;
    bool stage_events_ = true;
    std::size_t last_enqueued_ = 0;
};

// Uploads the world and palette and sets up the kernels of options.algorithm (options as
// returned by resolve_options). Throws InputError for work it refuses (brute force on a
// grid that would take minutes), ClError / BuildError for device failures.
std::unique_ptr<Generator> make_generator(Context& ctx, const World& world, const Palette& palette,
                                          const GeneratorOptions& options);

struct FieldTiming {
    double kernel_ms = 0;    // first kernel start to last kernel end (profiling events)
    double upload_ms = 0;    // world + palette upload (profiling events)
    double download_ms = 0;  // field readback (profiling events)
};

struct FieldResult {
    std::vector<std::uint8_t> bytes;
    std::vector<std::int32_t> indices;  // with options.indices
    FieldTiming timing;
    std::uint32_t iterations = 0;
};

// Uploads, transforms once and reads back.
FieldResult generate(Context& ctx, const World& world, const Palette& palette,
                     const GeneratorOptions& options);

}  // namespace voxfield::ocl
