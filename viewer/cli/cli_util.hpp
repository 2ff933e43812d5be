#pragma once
// Shared pieces of the `voxfield` subcommands.
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include <filesystem>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include "voxfield/cl/generator.hpp"
#include "voxfield/cl/runtime.hpp"
#include "voxfield/core/accuracy.hpp"
#include "voxfield/core/npy.hpp"

namespace voxfield::cli {

// A registered subcommand and what to run when it was chosen; run returns the exit code.
struct Command {
    CLI::App* app = nullptr;
    std::function<int()> run;
};

Command add_devices(CLI::App& root);
Command add_generate(CLI::App& root);
Command add_replay(CLI::App& root);
Command add_simulate(CLI::App& root);
Command add_bench(CLI::App& root);
Command add_render(CLI::App& root);
Command add_view(CLI::App& root);
Command add_info(CLI::App& root);

// --help of a world input: the files every command reads (DESIGN §4).
inline constexpr const char* kWorldInputHelp =
    "World: MagicaVoxel .vox (scene graph), .npy label volume (Z,Y,X) of any integer or bool "
    "type (nonzero = solid), OpenVDB .vdb, implicit surface .sdf.json or mixed scene "
    ".scene.json (.vox models and .sdf.json parts placed together)";
// --help of --device where the command runs OpenCL only (DESIGN §4).
inline constexpr const char* kDeviceHelp =
    "cpu, gpu or an index from `voxfield devices` (default: $VOXFIELD_DEVICE, else the first "
    "GPU, else the first CPU)";

// Options shared by the subcommands that run generators (--algorithm, --chunk, --focus,
// --jfa-extra, --metric, --spacing, --signed), as typed, and their registration.
struct GeneratorFlags {
    std::string algorithm = "exact", focus, metric = "manhattan", spacing, max_distance;
    std::uint32_t chunk = 0, jfa_extra = 0;
    bool signed_field = false;
};
void add_generator_flags(CLI::App& app, GeneratorFlags& flags);
// Only --metric, --spacing and --max-distance (add_generator_flags includes them).
void add_metric_flags(CLI::App& app, GeneratorFlags& flags);
// --signed, for the subcommands that write signed fields (generate, bench).
void add_signed_flag(CLI::App& app, GeneratorFlags& flags);
// --format into `format`; empty (the default) means the metric's default format.
void add_format_option(CLI::App& app, std::string& format);
// The format asked for, or the default of the flags' metric, spacing and sign (DESIGN §3).
Format field_format(const GeneratorFlags& flags, const std::string& format);
// Turns the flags into resolved options for `world` (InputError on any bad combination).
ocl::GeneratorOptions generator_options(const GeneratorFlags& flags, Format format, Dims world);

// Accuracy of `field` (encoded in options.format) against the exact CPU reference of the
// same options: metric, spacing, sign, global or chunk-local. `distance`: the unsigned
// reference_distance of the options' metric and spacing where the caller has it already.
Accuracy accuracy_of(const World& world, const Palette& palette,
                     const ocl::GeneratorOptions& options, const std::vector<std::uint8_t>& field,
                     const std::vector<double>* distance = nullptr);

// The .npy element type a field of format `f` is stored as (packed32 as uint32).
NpyType npy_type(Format f);

// Throws InputError unless `path` can be written as an output (check_output_path of
// voxfield/core/output.hpp: its folder exists and is writable, it is not a directory, a
// socket or a block device); checked before long work starts.
void require_output_folder(const std::filesystem::path& path);
// Throws InputError, with the readers' words, when `path` does not exist or is a directory:
// for checking the inputs exist before the outputs, without reading them yet.
void require_input_file(const std::filesystem::path& path);
// Throws InputError unless `path` ends in .png (any case): the images written are PNG only.
void require_png_name(const std::string& option, const std::string& path);
// Writes `text` to `path` through the output writer (voxfield/core/output.hpp): never a
// partial file, a device or FIFO written directly.
void write_text_file(const std::filesystem::path& path, const std::string& text);
void write_json_file(const std::filesystem::path& path, const nlohmann::json& j);

nlohmann::json device_json(const ocl::DeviceInfo& d);

// Each kernel's times over a generator's timed runs, for the "stages" rows of the JSON.
class StageTimes {
  public:
    void add(const ocl::Generator& job);  // after each timed run()
    // [{"kernel": name, "median_ms": median}] in launch order.
    nlohmann::json json() const;

  private:
    std::vector<std::pair<std::string, std::vector<double>>> kernels_;
};
std::string commit();
// Now in UTC, ISO 8601 ("2026-11-22T05:16:00Z"), for benchmark records.
std::string utc_now();
// `v` with `digits` decimals ("%.*f").
std::string fixed(double v, int digits);
// Throws InputError, with the numbers, when a world of `dims` and its `format` field cannot
// fit this machine's physical memory or `device`'s global memory (checked before any work;
// `what` starts the message, e.g. "--sizes 100000").
void require_memory_for(Dims dims, Format format, const ocl::DeviceInfo& device,
                        const std::string& what);
// CLI11 check for counts and durations that must be above zero, in plain words
// ("--repeat: must be a positive number, got '0'") where CLI::PositiveNumber prints the range
// 0 to DBL_MAX in 309 digits.
CLI::Validator positive();
// A rate such as Gvox/s: two decimals from 0.1 up, two significant digits below (0.0026),
// so that a slow algorithm never reads 0.00.
std::string rate(double v);
// Ends the process with `status` once a command's outputs are committed and its report printed:
// flushes the standard streams, then leaves without running destructors or exit handlers, so
// that the device objects still in scope (an NVIDIA context, its buffers, pinned host memory)
// are reclaimed by the operating system instead of torn down call by call after the user's
// files are already there (bench/README.md, "the whole process").
[[noreturn]] void exit_after_outputs(int status);

}  // namespace voxfield::cli
