#include "cli_util.hpp"

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <iostream>

#include <unistd.h>
#include <vector>

#include "voxfield/core/error.hpp"
#include "voxfield/core/output.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/stats.hpp"
#include "voxfield_commit.hpp"

namespace voxfield::cli {

NpyType npy_type(Format f) {
    switch (f) {
        case Format::u8:
            return NpyType::u8;
        case Format::u16:
            return NpyType::u16;
        case Format::u32:
        case Format::packed32:
            return NpyType::u32;
        case Format::i8:
            return NpyType::i8;
        case Format::i16:
            return NpyType::i16;
        case Format::i32:
            return NpyType::i32;
        case Format::f32:
            return NpyType::f32;
        case Format::f64:
            return NpyType::f64;
    }
    return NpyType::u32;
}

void require_output_folder(const std::filesystem::path& path) {
    check_output_path(path);
}

void require_input_file(const std::filesystem::path& path) {
    std::error_code ec;
    const auto status = std::filesystem::status(path, ec);
    if (!std::filesystem::exists(status)) {
        throw InputError("'" + path.string() + "': no such file");
    }
    if (std::filesystem::is_directory(status)) {
        throw InputError("'" + path.string() + "': is a directory, not a file");
    }
}

void require_png_name(const std::string& option, const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (ext != ".png") {
        throw InputError(option + " '" + path +
                         "' must be a .png file (PNG is the only image "
                         "format written)");
    }
}

void write_text_file(const std::filesystem::path& path, const std::string& text) {
    write_output_file(path, text);
}

void write_json_file(const std::filesystem::path& path, const nlohmann::json& j) {
    write_text_file(path, j.dump(2) + "\n");
}

nlohmann::json device_json(const ocl::DeviceInfo& d) {
    return {{"index", d.index},
            {"name", d.name},
            {"vendor", d.vendor},
            {"platform", d.platform},
            {"type", d.type},
            {"version", d.version},
            {"driver", d.driver},
            {"compute_units", d.compute_units},
            {"global_mem_bytes", d.global_mem},
            {"max_alloc_bytes", d.max_alloc},
            {"local_mem_bytes", d.local_mem},
            {"max_work_group_size", d.max_work_group},
            {"available", d.available},
            {"extensions", d.extensions}};
}

namespace {

// "X,Y,Z,SIZE" in chunk coordinates.
Focus parse_focus(const std::string& text) {
    std::vector<std::int64_t> v;
    std::size_t pos = 0;
    while (pos <= text.size()) {
        const std::size_t end = std::min(text.find(',', pos), text.size());
        const std::string part = text.substr(pos, end - pos);
        std::size_t used = 0;
        long long value = 0;
        try {
            value = std::stoll(part, &used);
        } catch (const std::exception&) {
            used = 0;
        }
        if (part.empty() || used != part.size()) {
            throw InputError("invalid --focus '" + text +
                             "': expected X,Y,Z,SIZE (integers, chunk coordinates), e.g. 4,1,4,2");
        }
        v.push_back(value);
        pos = end + 1;
    }
    if (v.size() != 4) {
        throw InputError("invalid --focus '" + text + "': expected 4 integers X,Y,Z,SIZE, got " +
                         std::to_string(v.size()));
    }
    return Focus{{v[0], v[1], v[2]}, v[3]};
}

}  // namespace

void add_generator_flags(CLI::App& app, GeneratorFlags& flags) {
    app.add_option("--algorithm", flags.algorithm,
                   "Generator: exact (ours, global, exact) or one of the dissertation's: brute, "
                   "brute-chunked, fim, fim-host, jfa, jfa-host, jfa-fim, lod, monolithic")
        ->check(CLI::IsMember(ocl::algorithm_names()))
        ->capture_default_str();
    app.add_option("--chunk", flags.chunk,
                   "Chunk-local semantics (the dissertation's): chunks of C^3 voxels, C a power "
                   "of two, everything outside a chunk solid. Omitted: global semantics, except "
                   "brute-chunked, lod and monolithic, which default to 16")
        ->check(CLI::Range(1u, 1u << 20));
    app.add_option("--focus", flags.focus,
                   "lod and monolithic: run FIM only in chunks within SIZE chunks of chunk "
                   "X,Y,Z (X,Y,Z,SIZE in chunk coordinates; default: the centre chunk, size 1)");
    app.add_option("--jfa-extra", flags.jfa_extra,
                   "JFA-based algorithms: 1 or 2 extra passes at the end (JFA+1, JFA+2)")
        ->capture_default_str();
    add_metric_flags(app, flags);
}

void add_metric_flags(CLI::App& app, GeneratorFlags& flags) {
    // The clause about algorithms only where the command has them (simulate has none).
    std::string metric_help =
        "Distance metric: manhattan (L1, the dissertation's), chebyshev (L-inf) or euclidean (L2)";
    if (app.get_option_no_throw("--algorithm") != nullptr) {
        metric_help += "; other than manhattan needs --algorithm exact";
    } else if (app.get_option_no_throw("--algorithms") != nullptr) {
        metric_help += "; other than manhattan is computed by exact only";
    }
    app.add_option("--metric", flags.metric, metric_help)
        ->check(CLI::IsMember(metric_names()))
        ->capture_default_str();
    // An empty value is refused, not taken as the option left out.
    const CLI::Validator given(
        [](const std::string& v) { return v.empty() ? std::string("an empty value") : ""; }, "",
        "given");
    app.add_option("--spacing", flags.spacing,
                   "Voxel size per world axis X,Y,Z (positive; default 1,1,1); each axis offset "
                   "is scaled by it before the metric (SciPy's sampling, in x,y,z order)")
        ->check(given);
    app.add_option("--max-distance", flags.max_distance,
                   "Bounded field: exact up to D, D beyond (a positive number, in the units of "
                   "--spacing); an edit's update then touches only voxels within D of it")
        ->check(given);
}

void add_signed_flag(CLI::App& app, GeneratorFlags& flags) {
    app.add_flag("--signed", flags.signed_field,
                 "Signed field: empty voxels +distance to the nearest solid, solid voxels "
                 "-distance to the nearest empty one (the world surrounded by empty space); "
                 "needs a signed format: i8, i16, i32, f32 or f64");
}

void add_format_option(CLI::App& app, std::string& format) {
    app.add_option("--format", format,
                   "u8, u16, u32 (distance rounded down, saturated), packed32 "
                   "((min(d,255)<<8)|rgb332), i8, i16, i32 (signed, toward zero), f32, f64. "
                   "Default: u16 (i16 with --signed) for manhattan and chebyshev with unit "
                   "spacing, f32 otherwise")
        ->check(CLI::IsMember(format_names()));
}

Format field_format(const GeneratorFlags& flags, const std::string& format) {
    if (!format.empty()) {
        return parse_format(format);
    }
    const Spacing spacing = flags.spacing.empty() ? Spacing{} : parse_spacing(flags.spacing);
    return ocl::default_format(parse_metric(flags.metric), spacing, flags.signed_field);
}

ocl::GeneratorOptions generator_options(const GeneratorFlags& flags, Format format, Dims world) {
    ocl::GeneratorOptions o;
    o.algorithm = ocl::parse_algorithm(flags.algorithm);
    o.format = format;
    o.chunk = flags.chunk;
    if (!flags.focus.empty()) {
        o.focus = parse_focus(flags.focus);
    }
    o.jfa_extra = flags.jfa_extra;
    o.metric = parse_metric(flags.metric);
    if (!flags.spacing.empty()) {
        o.spacing = parse_spacing(flags.spacing);
    }
    o.signed_field = flags.signed_field;
    if (!flags.max_distance.empty()) {
        char* end = nullptr;
        const double d = std::strtod(flags.max_distance.c_str(), &end);
        if (end != flags.max_distance.c_str() + flags.max_distance.size()) {
            throw InputError("--max-distance '" + flags.max_distance + "' is not a number");
        }
        o.max_distance = d;
    }
    return ocl::resolve_options(o, world);
}

Accuracy accuracy_of(const World& world, const Palette& palette,
                     const ocl::GeneratorOptions& options, const std::vector<std::uint8_t>& field,
                     const std::vector<double>* distance) {
    const bool plain = options.metric == Metric::manhattan && options.spacing.unit() &&
                       !options.signed_field && !holds_sign(options.format) &&
                       !options.max_distance;
    if (plain) {
        return compare_to_exact(field, options.format, ocl::exact_reference(world, options));
    }
    auto exact = options.signed_field  ? reference_signed(world, options.metric, options.spacing)
                 : distance != nullptr ? *distance
                                       : reference_distance(world, options.metric, options.spacing);
    if (options.max_distance) {
        const double bound = *options.max_distance;
        for (double& v : exact) {
            v = v < 0 ? -std::min(-v, bound) : std::min(v, bound);
        }
    }
    return compare_fields(field, encode_real_field(exact, world, palette, options.format),
                          options.format);
}

std::string commit() {
    return VOXFIELD_GIT_COMMIT;
}

std::string utc_now() {
    const std::time_t t = std::time(nullptr);
    char buf[32];
    std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
    return buf;
}

std::string fixed(double v, int digits) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.*f", digits, v);
    return buf;
}

namespace {

std::string gib(double bytes) {
    return fixed(bytes / double(1ull << 30), 1) + " GiB";
}

}  // namespace

void require_memory_for(Dims dims, Format format, const ocl::DeviceInfo& device,
                        const std::string& what) {
    const double n = static_cast<double>(dims.x) * dims.y * dims.z;
    const double es = static_cast<double>(element_size(format));
    // Host: the world (1 byte a voxel) and the field read back; device: the world, the field
    // and a 4-byte work buffer a voxel (the least any generator allocates).
    const double host = n * (1 + es);
    const double on_device = n * (1 + es + 4);
    const long pages = ::sysconf(_SC_PHYS_PAGES);
    const long page = ::sysconf(_SC_PAGESIZE);
    const double host_total =
        pages > 0 && page > 0 ? static_cast<double>(pages) * static_cast<double>(page) : 0;
    if (host_total > 0 && host > host_total) {
        throw InputError(what + ": a " + dims.to_string() + " world needs at least " + gib(host) +
                         " of host memory (" + gib(n) + " world + " + gib(n * es) + " " +
                         to_string(format) + " field), this machine has " + gib(host_total));
    }
    if (device.global_mem > 0 && on_device > static_cast<double>(device.global_mem)) {
        throw InputError(what + ": a " + dims.to_string() + " world needs at least " +
                         gib(on_device) + " of device memory (world, " + to_string(format) +
                         " field and a 4-byte buffer a voxel), " + device.name + " has " +
                         gib(static_cast<double>(device.global_mem)));
    }
}

CLI::Validator positive() {
    return CLI::Validator(
        [](std::string& text) -> std::string {
            char* end = nullptr;
            const double v = std::strtod(text.c_str(), &end);
            if (text.empty() || end != text.c_str() + text.size() || !(v > 0)) {
                return "must be a positive number, got '" + text + "'";
            }
            return {};
        },
        "POSITIVE");
}

std::string rate(double v) {
    if (!(v > 0) || v >= 0.1) {
        return fixed(v, 2);
    }
    char buf[64];
    std::snprintf(buf, sizeof buf, "%.2g", v);
    return buf;
}

void StageTimes::add(const ocl::Generator& job) {
    const auto& stages = job.stage_ms();
    kernels_.resize(stages.size());
    for (std::size_t k = 0; k < stages.size(); ++k) {
        kernels_[k].first = stages[k].first;
        kernels_[k].second.push_back(stages[k].second);
    }
}

nlohmann::json StageTimes::json() const {
    nlohmann::json rows = nlohmann::json::array();
    for (const auto& [name, samples] : kernels_) {
        rows.push_back({{"kernel", name}, {"median_ms", summarize(samples).median}});
    }
    return rows;
}

void exit_after_outputs(int status) {
    std::cout.flush();
    std::cerr.flush();
    std::fflush(nullptr);
    std::_Exit(status);
}

}  // namespace voxfield::cli
