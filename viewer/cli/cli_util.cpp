#include "cli_util.hpp"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <vector>

#include "voxfield/core/error.hpp"
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
    const auto folder = path.parent_path();
    if (!folder.empty() && !std::filesystem::is_directory(folder)) {
        throw InputError("cannot write '" + path.string() + "': folder '" + folder.string() +
                         "' does not exist");
    }
}

void write_text_file(const std::filesystem::path& path, const std::string& text) {
    require_output_folder(path);
    const auto tmp = std::filesystem::path(path.string() + ".tmp");
    {
        std::ofstream out(tmp);
        out << text;
        out.flush();
        if (!out) {
            out.close();
            std::filesystem::remove(tmp);
            throw InputError("cannot write '" + path.string() + "'");
        }
    }
    std::filesystem::rename(tmp, path);
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
    app.add_option("--metric", flags.metric,
                   "Distance metric: manhattan (L1, the dissertation's), chebyshev (L-inf) or "
                   "euclidean (L2); other than manhattan needs --algorithm exact")
        ->check(CLI::IsMember(metric_names()))
        ->capture_default_str();
    app.add_option("--spacing", flags.spacing,
                   "Voxel size per world axis X,Y,Z (positive; default 1,1,1); each axis offset "
                   "is scaled by it before the metric (SciPy's sampling, in x,y,z order)");
    app.add_option("--max-distance", flags.max_distance,
                   "Bounded field: exact up to D, D beyond (a positive number, in the units of "
                   "--spacing); an edit's update then touches only voxels within D of it");
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
                     const ocl::GeneratorOptions& options, const std::vector<std::uint8_t>& field) {
    const bool plain = options.metric == Metric::manhattan && options.spacing.unit() &&
                       !options.signed_field && !holds_sign(options.format) &&
                       !options.max_distance;
    if (plain) {
        return compare_to_exact(field, options.format, ocl::exact_reference(world, options));
    }
    auto exact = options.signed_field ? reference_signed(world, options.metric, options.spacing)
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

}  // namespace voxfield::cli
