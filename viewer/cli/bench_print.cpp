// How `voxfield bench --suite` shows a run (bench_print.hpp).
#include "bench_print.hpp"

#include <cstdarg>
#include <cstdint>
#include <cstdio>
#include <sstream>
#include <vector>

#include "cli_util.hpp"

namespace voxfield::cli {
namespace {

using nlohmann::json;

// "XxYxZ" of a row's "size" (Dims::to_string's form).
std::string size_text(const json& size) {
    return std::to_string(size[0].get<std::uint32_t>()) + "x" +
           std::to_string(size[1].get<std::uint32_t>()) + "x" +
           std::to_string(size[2].get<std::uint32_t>());
}

// A row's "chunk": the number, or "-" where the row has none (global semantics).
std::string chunk_text(const json& row) {
    return row["chunk"].is_null() ? "-" : std::to_string(row["chunk"].get<std::uint32_t>());
}

// printf into a string.
__attribute__((format(printf, 1, 2))) std::string format_line(const char* format, ...) {
    std::va_list args, again;
    va_start(args, format);
    va_copy(again, args);
    const int n = std::vsnprintf(nullptr, 0, format, args);
    va_end(args);
    std::vector<char> buffer(static_cast<std::size_t>(n) + 1);
    std::vsnprintf(buffer.data(), buffer.size(), format, again);
    va_end(again);
    return std::string(buffer.data(), static_cast<std::size_t>(n));
}

// `bench --algorithms ... --sizes ...`: a row, and before it on stderr its kernels' medians.
std::string grid_line(const json& r) {
    const std::string algorithm = r["algorithm"], size = size_text(r["size"]);
    if (r.contains("skipped")) {
        return format_line("%-14s %-14s skipped: %s\n", algorithm.c_str(), size.c_str(),
                           r["skipped"].get<std::string>().c_str());
    }
    return format_line("%-14s %-14s %-6s %-8s %10.3f %10.3f %10.3f %10s %6u %9u\n",
                       algorithm.c_str(), size.c_str(), chunk_text(r).c_str(),
                       r["format"].get<std::string>().c_str(), r["median_ms"].get<double>(),
                       r["mean_ms"].get<double>(), r["std_ms"].get<double>(),
                       rate(r["gvox_per_s"].get<double>()).c_str(),
                       r["iterations"].get<std::uint32_t>(), r["max_error"].get<std::uint32_t>());
}

std::string grid_kernels_line(const json& r) {
    std::string text = "bench: " + r["algorithm"].get<std::string>() + " " + size_text(r["size"]) +
                       ": median per kernel:";
    for (const json& stage : r["stages"]) {
        text += " " + stage["kernel"].get<std::string>() + " " +
                std::to_string(stage["median_ms"].get<double>()) + " ms";
    }
    return text + "\n";
}

std::string dissertation_line(const json& r) {
    const std::string table = r["table"], algorithm = r["algorithm"];
    const std::string size = size_text(r["size"]), chunk = chunk_text(r);
    if (r.contains("skipped")) {
        return format_line("%-11s %-14s %-14s %-6s skipped: %s\n", table.c_str(), algorithm.c_str(),
                           size.c_str(), chunk.c_str(), r["skipped"].get<std::string>().c_str());
    }
    return format_line("%-11s %-14s %-14s %-6s %-8s %12.3f %12.3f %6u %7u %9.4f\n", table.c_str(),
                       algorithm.c_str(), size.c_str(), chunk.c_str(),
                       r["format"].get<std::string>().c_str(), r["median_ms"].get<double>(),
                       r["std_ms"].get<double>(), r["iterations"].get<std::uint32_t>(),
                       r["max_error"].get<std::uint32_t>(), r["mean_error"].get<double>());
}

std::string edits_line(const json& r) {
    std::string shown = r["algorithm"];
    if (!r["max_distance"].is_null()) {
        shown += " D=" + fixed(r["max_distance"].get<double>(), 0);
    }
    return format_line("%-14s %-14s %-6s %12.3f %12.3f %12.3f %12.3f %14.0f %7u\n", shown.c_str(),
                       size_text(r["size"]).c_str(), chunk_text(r).c_str(),
                       r["median_ms"].get<double>(), r["mean_ms"].get<double>(),
                       r["max_ms"].get<double>(), r["full_regeneration_ms"].get<double>(),
                       r["voxels_recomputed_mean"].get<double>(),
                       r["max_error"].get<std::uint32_t>());
}

std::string render_line(const json& m) {
    return format_line(
        "render %-14s %-9s %5ux%-5u median %8.3f ms  mean %8.3f  std %7.3f  %8.1f "
        "Mrays/s  %7.2f fetches  %7.2f steps per ray%s\n",
        size_text(m["size"]).c_str(), m["metric"].get<std::string>().c_str(),
        m["width"].get<std::uint32_t>(), m["height"].get<std::uint32_t>(),
        m["median_ms"].get<double>(), m["mean_ms"].get<double>(), m["std_ms"].get<double>(),
        m["mrays_per_s"].get<double>(), m["fetches_per_ray"].get<double>(),
        m["steps_per_ray"].get<double>(),
        m["same_image_as_manhattan"].get<bool>() ? "" : "  IMAGE DIFFERS FROM MANHATTAN'S");
}

std::string sand_line(const json& r) {
    return format_line(
        "sand %-14s %-10s %4zu steps  %8.1f steps/s (device)  %8.1f (wall)  simulate %8.3f "
        "ms  update %8.3f ms median  full %8.3f ms  step/full %.2f  %zu voxels changed, %zu "
        "full regenerations\n",
        size_text(r["size"]).c_str(), r["max_distance"].is_null() ? "unbounded" : "D=16",
        r["steps"].get<std::size_t>(), r["steps_per_s_device"].get<double>(),
        r["steps_per_s_wall"].get<double>(), r["simulate_ms_median"].get<double>(),
        r["update_ms_median"].get<double>(), r["full_regeneration_ms"].get<double>(),
        r["step_over_full"].get<double>(), r["voxels_changed"].get<std::size_t>(),
        r["full_regenerations"].get<std::size_t>());
}

// The implicit suite's row, a log line on stderr.
std::string implicit_line(const json& r) {
    const json& t = r["tiles"];
    return "bench: implicit " + std::to_string(r["effective_resolution"].get<std::uint32_t>()) +
           "^3 " + size_text(r["size"]) + " depth " +
           std::to_string(r["tile_depth"].get<std::uint32_t>()) + " (" + size_text(t) +
           " tiles of " + std::to_string(r["tile_edge"].get<std::uint32_t>()) +
           "^3): " + fixed(r["median_ms"].get<double>(), 2) + " ms, " +
           std::to_string(r["leaves"].get<std::uint64_t>()) + " leaves, " +
           std::to_string(r["crossed_voxels"].get<std::uint64_t>()) + " crossed voxels, " +
           fixed(r["bytes"].get<double>() / 1048576.0, 1) + " MiB\n";
}

}  // namespace

BenchPrinter::BenchPrinter(const std::string& suite) : suite_(suite), progress_("bench") {}

void BenchPrinter::header() {
    if (header_done_) {
        return;
    }
    header_done_ = true;
    if (suite_.empty()) {
        progress_.print(stdout, format_line("%-14s %-14s %-6s %-8s %10s %10s %10s %10s %6s %9s\n",
                                            "algorithm", "size", "chunk", "format", "median ms",
                                            "mean ms", "std ms", "Gvox/s", "iters", "max err"));
    } else if (suite_ == "dissertation") {
        progress_.print(stdout, format_line("%-11s %-14s %-14s %-6s %-8s %12s %12s %6s %7s %9s\n",
                                            "table", "algorithm", "size", "chunk", "format",
                                            "median ms", "std ms", "iters", "max err", "mean err"));
    } else if (suite_ == "edits") {
        progress_.print(stdout, format_line("%-14s %-14s %-6s %12s %12s %12s %12s %14s %7s\n",
                                            "algorithm", "size", "chunk", "median ms", "mean ms",
                                            "max ms", "full ms", "recomputed/ed", "max err"));
    }
}

void BenchPrinter::stage(const std::string& text) {
    progress_.print(stderr, "bench: " + text + "\n");
    // What starts now, until the harness says more (no stale text from the previous row).
    progress_.set(text);
    header();
}

void BenchPrinter::progress(const std::string& what) {
    progress_.set(what);
}

void BenchPrinter::measured(const json& measurement) {
    header();
    if (suite_ == "render") {
        progress_.print(stdout, render_line(measurement));
    }
}

void BenchPrinter::row(const json& row) {
    header();
    if (suite_.empty()) {
        if (!row.contains("skipped")) {
            progress_.print(stderr, grid_kernels_line(row));
        }
        progress_.print(stdout, grid_line(row));
    } else if (suite_ == "dissertation") {
        progress_.print(stdout, dissertation_line(row));
    } else if (suite_ == "edits") {
        // A skipped row is in the log already (stage).
        if (!row.contains("skipped")) {
            progress_.print(stdout, edits_line(row));
        }
    } else if (suite_ == "sand") {
        progress_.print(stdout, sand_line(row));
    } else if (suite_ == "implicit") {
        progress_.print(stderr, implicit_line(row));
    }
}

std::string suite_csv(const json& rows) {
    std::ostringstream csv;
    csv << "table,group,algorithm,x,y,z,chunk,focus_size,format,median_ms,mean_ms,std_ms,ci95_lo_"
           "ms,ci95_hi_ms,min_ms,max_ms,iterations,max_error,mean_error,over_fraction,under_"
           "fraction,full_regeneration_ms,skipped\n";
    const auto num = [](const json& row, const char* key) -> std::string {
        if (!row.contains(key) || row[key].is_null()) {
            return "";
        }
        std::ostringstream s;
        s << row[key].get<double>();
        return s.str();
    };
    const auto quoted = [](const std::string& s) {
        std::string out = "\"";
        for (char c : s) {
            out += c == '"' ? std::string("\"\"") : std::string(1, c);
        }
        return out + "\"";
    };
    for (const json& r : rows) {
        const bool has_size = r.contains("size") && r["size"].is_array();
        csv << quoted(r.value("table", "")) << ',' << quoted(r.value("group", "")) << ','
            << (r.contains("algorithm") && r["algorithm"].is_string()
                    ? r["algorithm"].get<std::string>()
                    : "")
            << ',' << (has_size ? std::to_string(r["size"][0].get<std::uint32_t>()) : "") << ','
            << (has_size ? std::to_string(r["size"][1].get<std::uint32_t>()) : "") << ','
            << (has_size ? std::to_string(r["size"][2].get<std::uint32_t>()) : "") << ','
            << num(r, "chunk") << ','
            << (r.contains("focus") && r["focus"].is_array()
                    ? std::to_string(r["focus"][3].get<std::int64_t>())
                    : "")
            << ',' << r.value("format", "") << ',' << num(r, "median_ms") << ','
            << num(r, "mean_ms") << ',' << num(r, "std_ms") << ','
            << (r.contains("ci95_ms") ? std::to_string(r["ci95_ms"][0].get<double>()) : "") << ','
            << (r.contains("ci95_ms") ? std::to_string(r["ci95_ms"][1].get<double>()) : "") << ','
            << num(r, "min_ms") << ',' << num(r, "max_ms") << ',' << num(r, "iterations") << ','
            << num(r, "max_error") << ',' << num(r, "mean_error") << ',' << num(r, "over_fraction")
            << ',' << num(r, "under_fraction") << ',' << num(r, "full_regeneration_ms") << ','
            << (r.contains("skipped") ? quoted(r["skipped"].get<std::string>()) : "") << '\n';
    }
    return csv.str();
}

std::string grid_csv(const json& rows) {
    std::ostringstream csv;
    csv << "algorithm,x,y,z,chunk,format,scene,repeat,median_ms,mean_ms,std_ms,ci95_lo_ms,ci95_hi_"
           "ms,min_ms,max_ms,gvox_per_s,max_error,mean_error\n";
    for (const json& r : rows) {
        if (r.contains("skipped")) {
            continue;
        }
        const json& size = r["size"];
        csv << r["algorithm"].get<std::string>() << ',' << size[0].get<std::uint32_t>() << ','
            << size[1].get<std::uint32_t>() << ',' << size[2].get<std::uint32_t>() << ','
            << (r["chunk"].is_null() ? 0u : r["chunk"].get<std::uint32_t>()) << ','
            << r["format"].get<std::string>() << ',' << r["scene"].get<std::string>() << ','
            << r["repeat"].get<std::uint32_t>() << ',' << r["median_ms"].get<double>() << ','
            << r["mean_ms"].get<double>() << ',' << r["std_ms"].get<double>() << ','
            << r["ci95_ms"][0].get<double>() << ',' << r["ci95_ms"][1].get<double>() << ','
            << r["min_ms"].get<double>() << ',' << r["max_ms"].get<double>() << ','
            << r["gvox_per_s"].get<double>() << ',' << r["max_error"].get<std::uint32_t>() << ','
            << r["mean_error"].get<double>() << '\n';
    }
    return csv.str();
}

}  // namespace voxfield::cli
