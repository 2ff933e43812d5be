// End-to-end tests of `voxfield bench --suite ...` (issue 7): the quick suites run to the
// end on the CPU device and write JSON of the documented structure. Timings are never
// asserted; only that every row is either timed (finite statistics) or skipped with a reason.
#include <sys/wait.h>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <map>
#include <set>
#include <string>

#include "cli_test_util.hpp"
#include "voxfield/core/brush.hpp"
#include "voxfield/core/undo.hpp"

namespace voxfield::test {
namespace {

using nlohmann::json;

class BenchSuite : public TempDirsTest {
  protected:
    BenchSuite() : TempDirsTest("voxfield_bench_suite") {}
};

bool finite_number(const json& v) {
    return v.is_number() && std::isfinite(v.get<double>());
}

// The DESIGN §4 keys every timed row carries, all finite, plus the suites' accuracy fields.
void expect_timed_row(const json& r, const std::string& where) {
    for (const char* key : {"median_ms", "mean_ms", "std_ms", "min_ms", "max_ms", "max_error",
                            "mean_error", "over_fraction", "under_fraction"}) {
        ASSERT_TRUE(r.contains(key)) << where << " lacks " << key;
        EXPECT_TRUE(finite_number(r[key])) << where << " " << key << " = " << r[key];
    }
    ASSERT_TRUE(r.contains("ci95_ms") && r["ci95_ms"].is_array() && r["ci95_ms"].size() == 2)
        << where;
    EXPECT_TRUE(finite_number(r["ci95_ms"][0]) && finite_number(r["ci95_ms"][1])) << where;
    EXPECT_LE(r["ci95_ms"][0].get<double>(), r["ci95_ms"][1].get<double>()) << where;
    EXPECT_GE(r["median_ms"].get<double>(), 0.0) << where;
    for (const char* key : {"gvox_per_s", "iterations"}) {
        ASSERT_TRUE(r.contains(key)) << where << " lacks " << key;
        EXPECT_TRUE(r[key].is_null() || finite_number(r[key])) << where << " " << key;
    }
}

void expect_common(const json& doc, const std::string& suite) {
    for (const char* key : {"device", "commit", "date", "suite", "results"}) {
        ASSERT_TRUE(doc.contains(key)) << key;
    }
    EXPECT_EQ(doc["suite"], suite);
    EXPECT_TRUE(doc["device"].contains("name"));
    EXPECT_TRUE(doc["device"].contains("driver"));
    ASSERT_TRUE(doc["results"].is_array());
    ASSERT_FALSE(doc["results"].empty());
}

// Each row: algorithm, size, chunk, metric, table; either skipped with a reason or timed, and
// not every row skipped (a run that timed nothing proves nothing).
void expect_rows(const json& doc) {
    std::size_t timed = 0;
    for (const json& r : doc["results"]) {
        const std::string where = r.dump().substr(0, 200);
        for (const char* key : {"table", "algorithm", "size", "chunk", "metric"}) {
            ASSERT_TRUE(r.contains(key)) << where << " lacks " << key;
        }
        ASSERT_TRUE(r["size"].is_array() && r["size"].size() == 3) << where;
        if (r.contains("skipped")) {
            ASSERT_TRUE(r["skipped"].is_string()) << where;
            EXPECT_FALSE(r["skipped"].get<std::string>().empty()) << where;
        } else {
            expect_timed_row(r, where);
            ++timed;
        }
    }
    EXPECT_GT(timed, 0u) << "every row was skipped";
}

TEST_F(BenchSuite, DissertationQuickWritesEveryTableWithExactBesideIt) {
    const fs::path js = dir_ / "d.json";
    const fs::path csv = dir_ / "d.csv";
    const RunResult r = run({"bench", "--suite", "dissertation", "--quick", "--device", "cpu",
                             "--json", js.string(), "--csv", csv.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    // Progress on stderr: which row of how many.
    EXPECT_NE(r.err.find("[1/"), std::string::npos) << r.err.substr(0, 400);
    const json doc = json::parse(read_text(js));
    expect_common(doc, "dissertation");
    EXPECT_EQ(doc["quick"], true);
    ASSERT_TRUE(doc.contains("mapping"));
    expect_rows(doc);

    std::set<std::string> tables;
    std::map<std::string, std::set<std::string>> algorithms_by_group;
    for (const json& row : doc["results"]) {
        const std::string table = row["table"];
        tables.insert(table);
        algorithms_by_group[table + " / " + row["group"].get<std::string>()].insert(
            row["algorithm"].get<std::string>());
        if (row["algorithm"] == "exact") {
            ASSERT_FALSE(row.contains("skipped")) << row.dump().substr(0, 200);
            EXPECT_EQ(row["max_error"], 0) << row.dump().substr(0, 200);
            EXPECT_TRUE(row["chunk"].is_null());
        }
    }
    EXPECT_EQ(tables, (std::set<std::string>{"Table 4.2", "Table 4.3", "Table 4.4", "Table 4.5",
                                             "Table 4.6", "Table 4.7", "Table 5.1", "Figure 4.8"}));
    for (const auto& [group, algorithms] : algorithms_by_group) {
        EXPECT_TRUE(algorithms.count("exact") == 1) << group;
        EXPECT_GE(algorithms.size(), 2u) << group;
    }
    const auto lines = split_lines(read_text(csv));
    EXPECT_EQ(lines.size(), doc["results"].size() + 1);
}

TEST_F(BenchSuite, EditsQuickRecordsPerEditTimesAndFullRegeneration) {
    const fs::path js = dir_ / "e.json";
    const RunResult r = run({"bench", "--suite", "edits", "--quick", "--device", "cpu", "--world",
                             "32", "--edits", "6", "--json", js.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    const json doc = json::parse(read_text(js));
    expect_common(doc, "edits");
    EXPECT_EQ(doc["edits"], 6);
    EXPECT_EQ(doc["seed"], 6683787);
    expect_rows(doc);
    std::set<std::string> algorithms;
    std::string first_sequence;
    for (const json& row : doc["results"]) {
        algorithms.insert(row["algorithm"].get<std::string>());
        if (row.contains("skipped")) {
            EXPECT_NE(row["algorithm"], "exact") << "the exact row was skipped";
            continue;
        }
        EXPECT_TRUE(finite_number(row["full_regeneration_ms"]));
        ASSERT_TRUE(row["edits"].is_array());
        EXPECT_EQ(row["edits"].size(), row["edits_done"].get<std::size_t>());
        json sequence = json::array();
        for (const json& e : row["edits"]) {
            EXPECT_TRUE(finite_number(e["update_ms"]));
            EXPECT_TRUE(e["voxels_recomputed"].is_number_unsigned());
            EXPECT_GE(e["size"].get<int>(), 1);
            EXPECT_LE(e["size"].get<int>(), 15);
            sequence.push_back({e["op"], e["centre"], e["size"], e["material"]});
        }
        // The same seeded edits for every algorithm, and those view --benchmark makes (core's
        // RandomEdits, same world, chunk and seed).
        RandomEdits view_edits(Dims{32, 32, 32}, 16, 6683787);
        for (const json& e : row["edits"]) {
            const Brush b = view_edits.next();
            EXPECT_EQ(e["centre"], json::array({b.centre.x, b.centre.y, b.centre.z}));
            EXPECT_EQ(e["radius"], b.radius);
            EXPECT_EQ(e["size"], view_edits.last_size());
            EXPECT_EQ(e["op"], to_string(b.op));
            EXPECT_EQ(e["material"], b.op == BrushOp::erase ? 0 : b.material);
        }
        if (first_sequence.empty()) {
            first_sequence = sequence.dump();
        } else if (row["edits"].size() == 6) {
            EXPECT_EQ(sequence.dump(), first_sequence) << row["algorithm"];
        }
        if (row["algorithm"] == "exact") {
            EXPECT_EQ(row["max_error"], 0);
        }
    }
    EXPECT_EQ(algorithms,
              (std::set<std::string>{"exact", "brute-chunked", "fim-host", "fim", "jfa-host", "jfa",
                                     "jfa-fim", "lod", "monolithic"}));
}

// A suite's progress is the progress line (progress.hpp, issue 29): on a terminal (script(1)
// gives the command one) "\rbench: [i/n] ..." erased before every result line, so that each
// table line starts a line of its own; with stderr a file, no '\r' at all, the log lines alone.
TEST_F(BenchSuite, ProgressShowsOnATerminalOnly) {
    if (!fs::exists("/usr/bin/script")) {
        GTEST_SKIP() << "/usr/bin/script (bsdutils) is not installed";
    }
    const std::vector<std::string> args = {"bench",   "--suite", "edits",    "--world", "32",
                                           "--edits", "6",       "--device", "cpu"};
    const RunResult file = run(args);
    ASSERT_EQ(file.code, 0) << describe(file);
    EXPECT_EQ(file.err.find('\r'), std::string::npos) << file.err;
    EXPECT_NE(file.err.find("bench: [1/12] edits exact: setting up\n"), std::string::npos)
        << file.err;
    std::string command = kExe.string();
    for (const std::string& a : args) {
        command += " " + a;
    }
    const fs::path log = io_ / "script.out";
    const std::string shell =
        "/usr/bin/script -qec '" + command + "' /dev/null > " + log.string() + " 2>&1";
    ASSERT_EQ(std::system(shell.c_str()), 0) << read_text(log);
    const std::string seen = read_text(log);
    EXPECT_NE(seen.find("\rbench: ["), std::string::npos) << seen;
    EXPECT_NE(seen.find("\r\033[K"), std::string::npos) << seen;
    for (const char* row : {"exact          32x32x32", "monolithic     32x32x32"}) {
        const std::size_t at = seen.find(row);
        ASSERT_NE(at, std::string::npos) << row << " missing from:\n" << seen;
        ASSERT_GT(at, 0u);
        EXPECT_TRUE(seen[at - 1] == '\n' || seen[at - 1] == 'K')
            << "the table line follows other text: "
            << seen.substr(at - std::min<std::size_t>(at, 120), 160);
    }
}

TEST_F(BenchSuite, RenderTimesFramesOnLavapipe) {
    const fs::path js = dir_ / "r.json";
    const RunResult r =
        run({"bench", "--suite", "render", "--quick", "--device", "cpu", "--json", js.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    const json doc = json::parse(read_text(js));
    expect_common(doc, "render");
    ASSERT_EQ(doc["results"].size(), 2u);  // --quick: 32^3 and 64^3 at 320x240
    for (const json& row : doc["results"]) {
        ASSERT_TRUE(row.contains("median_ms")) << row.dump();
        EXPECT_GT(row["median_ms"].get<double>(), 0.0);
        EXPECT_GT(row["mrays_per_s"].get<double>(), 0.0);
        EXPECT_EQ(row["width"], 320);
        EXPECT_EQ(row["height"], 240);
    }
}

TEST_F(BenchSuite, SandRunsTheSimulationInPlaceAndTimesItBothWays) {
    const fs::path js = dir_ / "s.json";
    const RunResult r = run({"bench", "--suite", "sand", "--world", "24", "--repeat", "5",
                             "--device", "cpu", "--json", js.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    const json doc = json::parse(read_text(js));
    EXPECT_EQ(doc["suite"], "sand");
    EXPECT_EQ(doc["steps"], 5);
    ASSERT_EQ(doc["results"].size(), 2u);  // unbounded, and bounded at D = 16
    for (const json& row : doc["results"]) {
        const std::string where = row.dump().substr(0, 200);
        EXPECT_EQ(row["steps"], 5) << where;
        ASSERT_EQ(row["per_step"].size(), 5u) << where;
        EXPECT_GT(row["steps_per_s_device"].get<double>(), 0.0) << where;
        EXPECT_GT(row["steps_per_s_wall"].get<double>(), 0.0) << where;
        EXPECT_GT(row["voxels_changed"].get<std::size_t>(), 0u) << where;
        for (const json& step : row["per_step"]) {
            EXPECT_GT(step["simulate_ms"].get<double>(), 0.0) << where;  // the kernel ran
            EXPECT_TRUE(step["wall_ms"].is_number()) << where;
        }
    }
}

// The implicit suite reads its part from share/voxfield/parts beside the binary when the
// working directory has no data/parts: a binary copied into a prefix of its own (bin/ and
// share/voxfield/parts/, as installed) needs no source tree, and without the part it says so.
TEST_F(BenchSuite, ImplicitFindsItsPartBesideTheBinary) {
    const fs::path prefix = dir_ / "prefix";
    fs::create_directories(prefix / "bin");
    fs::create_directories(prefix / "share" / "voxfield" / "parts");
    fs::copy_file(kExe, prefix / "bin" / "voxfield");
    fs::copy_file(
        kExe.parent_path().parent_path() / "share" / "voxfield" / "parts" / "bracket.sdf.json",
        prefix / "share" / "voxfield" / "parts" / "bracket.sdf.json");
    const fs::path js = dir_ / "i.json";
    const auto run_in_io = [&](const std::string& log) {
        const std::string command = "cd " + io_.string() + " && " +
                                    (prefix / "bin" / "voxfield").string() +
                                    " bench --suite implicit --quick --repeat 1 --warmup 0 "
                                    "--device cpu --json " +
                                    js.string() + " > " + log + " 2>&1";
        const int status = std::system(command.c_str());
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    };
    const std::string log = (io_ / "implicit.log").string();
    ASSERT_EQ(run_in_io(log), 0) << read_text(log);
    const json doc = json::parse(read_text(js));
    expect_common(doc, "implicit");
    // --quick: 256^3 at tile depths 1-4 (depth 1 again with the other readback), then the part
    // traced at 1920x1080, lit and flat.
    ASSERT_EQ(doc["results"].size(), 7u);
    for (const json& row : doc["results"]) {
        EXPECT_EQ(row["part"], "bracket.sdf.json");
        EXPECT_GT(row["median_ms"].get<double>(), 0.0) << row.dump().substr(0, 200);
        // DESIGN §4's keys of every bench result.
        for (const char* key :
             {"algorithm", "size", "chunk", "metric", "median_ms", "mean_ms", "std_ms", "ci95_ms",
              "gvox_per_s", "iterations", "max_error", "mean_error"}) {
            EXPECT_TRUE(row.contains(key)) << key << " in " << row.dump().substr(0, 200);
        }
        if (row["table"] == "implicit") {
            EXPECT_GT(row["leaves"].get<std::uint64_t>(), 0u) << row.dump().substr(0, 200);
            // One run (no warm-up): the first, counted, run: a wait per level and more.
            EXPECT_TRUE(row["counted"].get<bool>());
            EXPECT_GT(row["syncs"].get<std::uint32_t>(), row["tile_depth"].get<std::uint32_t>());
            EXPECT_GT(row["kernel_median_ms"].get<double>(), 0.0);
        } else {
            EXPECT_EQ(row["table"], "implicit_trace");
            EXPECT_EQ(row["width"], 1920);
            EXPECT_GT(row["crossed_voxels"].get<std::uint64_t>(), 0u);
        }
    }
    fs::remove(js);
    fs::remove_all(prefix / "share" / "voxfield" / "parts");
    EXPECT_EQ(run_in_io(log), 2) << read_text(log);
    EXPECT_NE(read_text(log).find("share/voxfield/parts/"), std::string::npos) << read_text(log);
    EXPECT_FALSE(fs::exists(js));
}

// The sparse suite on small city worlds: one row per --sizes entry, none skipped, the whole
// field and the device edits timed, the edited regions equal to the dense bounded field, the
// memory records present; bad sizes and options refused before any work.
TEST_F(BenchSuite, SparseTimesTheFieldAndDeviceEditsAndChecksThemExact) {
    const fs::path js = dir_ / "sparse.json";
    const RunResult r =
        run({"bench", "--suite", "sparse", "--sizes", "200x70x150,130x40x64", "--max-distance", "6",
             "--edits", "4", "--warmup", "1", "--device", "cpu", "--json", js.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    const json doc = json::parse(read_text(js));
    expect_common(doc, "sparse");
    EXPECT_EQ(doc["scene"], "city");
    ASSERT_EQ(doc["results"].size(), 2u);
    const std::vector<std::vector<std::uint32_t>> sizes = {{200, 70, 150}, {130, 40, 64}};
    for (std::size_t i = 0; i < 2; ++i) {
        const json& row = doc["results"][i];
        const std::string where = row.dump().substr(0, 200);
        EXPECT_FALSE(row.contains("skipped")) << where;
        EXPECT_EQ(row["size"], sizes[i]) << where;
        EXPECT_EQ(row["max_distance"], 6.0) << where;
        EXPECT_EQ(row["format"], "u8") << where;
        EXPECT_EQ(row["metric"], "manhattan") << where;
        EXPECT_EQ(row["exact"], true) << where;
        EXPECT_GT(row["exact_checked_voxels"].get<std::uint64_t>(), 0u) << where;
        EXPECT_EQ(row["exact_differing_voxels"], 0) << where;
        EXPECT_EQ(row["edits"], 4) << where;
        EXPECT_EQ(row["edit_radius"], 8) << where;
        // The timed edits alternate: lean ones (the row's times) and profiled ones.
        ASSERT_EQ(row["samples_ms"].size(), 2u) << where;
        EXPECT_EQ(row["profiled_edits"], 2) << where;
        ASSERT_EQ(row["profiled_edit_samples_ms"].size(), 2u) << where;
        for (const char* key : {"median_ms",
                                "mean_ms",
                                "std_ms",
                                "min_ms",
                                "max_ms",
                                "profiled_edit_ms_median",
                                "field_wall_ms",
                                "field_kernel_ms",
                                "edit_kernel_ms_median",
                                "edit_world_kernel_ms_median",
                                "build_ms",
                                "world_upload_ms",
                                "peak_rss_bytes",
                                "peak_bytes_per_stored_voxel",
                                "world_bytes",
                                "world_bytes_per_stored_voxel",
                                "world_bytes_per_solid_voxel",
                                "field_bytes",
                                "stored_voxels",
                                "host_sync_ms"}) {
            ASSERT_TRUE(row.contains(key)) << where << " lacks " << key;
            EXPECT_TRUE(finite_number(row[key])) << where << " " << key;
        }
        EXPECT_GT(row["median_ms"].get<double>(), 0.0) << where;
        EXPECT_GT(row["field_kernel_ms"].get<double>(), 0.0) << where;
        EXPECT_GT(row["tiles_stored"].get<std::uint32_t>(), 0u) << where;
        EXPECT_GT(row["solid_voxels"].get<std::uint64_t>(), 0u) << where;
        EXPECT_EQ(row["peak_within_target"].is_boolean(), true) << where;
        EXPECT_TRUE(row.contains("load_average_start")) << where;
        // Radius-8 edits at D = 6 are one block each: where their time went.
        EXPECT_EQ(row["edit_single_block_edits"], 2) << where;
        for (const char* key : {"edit_host_stage_ms_median", "lean_edit_host_stage_ms_median"}) {
            const json& host = row[key];
            for (const char* stage :
                 {"world edit", "field tables", "field enqueue", "wait", "after"}) {
                ASSERT_TRUE(host.contains(stage)) << key << host.dump() << " lacks " << stage;
                EXPECT_GE(host[stage].get<double>(), 0.0) << stage;
            }
        }
        EXPECT_GT(row["edit_device_span_ms_median"].get<double>(), 0.0) << where;
        EXPECT_LE(row["edit_device_idle_ms_median"].get<double>(),
                  row["edit_device_span_ms_median"].get<double>())
            << where;
    }
    for (const std::vector<std::string>& bad : {std::vector<std::string>{"--sizes", "2000000x8x8"},
                                                {"--chunk", "8"},
                                                {"--max-distance", "0", "--format", "u8"},
                                                {"--metric", "cosine"}}) {
        std::vector<std::string> args = {"bench",
                                         "--suite",
                                         "sparse",
                                         "--device",
                                         "cpu",
                                         "--json",
                                         (dir_ / "bad.json").string()};
        args.insert(args.end(), bad.begin(), bad.end());
        const RunResult b = run(args);
        EXPECT_EQ(b.code, 2) << describe(b);
        EXPECT_FALSE(fs::exists(dir_ / "bad.json")) << bad[0];
    }
}

// --peer: OpenVDB's fast sweeping on the same small city in the same run, after the row's own
// work, with its times, band, memory and error against the exact field beside voxfield's time;
// refused with a one-line exit 2 for a field it cannot be compared with, and outside --suite
// sparse.
TEST_F(BenchSuite, SparsePeerSweepsTheSameWorldWithOpenVdb) {
    const fs::path js = dir_ / "sparse-peer.json";
    // The row's own field in u8 (the suite's default); the peer's error is against f32.
    const RunResult r = run({"bench", "--suite", "sparse", "--quick", "--peer", "--metric",
                             "euclidean", "--max-distance", "8", "--edits", "2", "--warmup", "0",
                             "--device", "cpu", "--json", js.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    const json doc = json::parse(read_text(js));
    expect_common(doc, "sparse");
    ASSERT_EQ(doc["results"].size(), 1u);
    const json& row = doc["results"][0];
    EXPECT_EQ(row["exact"], true);
    EXPECT_EQ(row["format"], "u8");
    ASSERT_TRUE(row.contains("peer")) << row.dump().substr(0, 200);
    const json& peer = row["peer"];
    const std::string where = peer.dump();
    for (const char* key : {"topology_ms", "sweep_ms", "total_ms", "voxfield_field_wall_ms",
                            "voxfield_speedup_vs_sweep", "mean_abs_error_voxels",
                            "max_abs_error_voxels", "rss_before_bytes", "peak_rss_bytes"}) {
        ASSERT_TRUE(peer.contains(key)) << where << " lacks " << key;
        EXPECT_TRUE(finite_number(peer[key])) << where << " " << key;
    }
    EXPECT_EQ(peer["openvdb_version"].get<std::string>().empty(), false) << where;
    EXPECT_GT(peer["topology_ms"].get<double>(), 0.0) << where;
    EXPECT_GT(peer["sweep_ms"].get<double>(), 0.0) << where;
    EXPECT_EQ(peer["voxfield_field_wall_ms"], row["field_wall_ms"]) << where;
    // The band: more than the solid surface alone, less than the stored voxels.
    EXPECT_GT(peer["band_voxels"].get<double>(), 0.0) << where;
    EXPECT_LT(peer["band_voxels"].get<double>(), row["stored_voxels"].get<double>()) << where;
    EXPECT_GT(peer["leaf_nodes"].get<std::uint64_t>(), 0u) << where;
    EXPECT_GT(peer["compared_voxels"].get<std::uint64_t>(), 1000u) << where;
    // Fast sweeping is first-order: within a voxel or so, about a tenth of one on average.
    EXPECT_GT(peer["mean_abs_error_voxels"].get<double>(), 0.0) << where;
    EXPECT_LT(peer["mean_abs_error_voxels"].get<double>(), 0.3) << where;
    EXPECT_LT(peer["max_abs_error_voxels"].get<double>(), 2.0) << where;
    EXPECT_GE(peer["peak_rss_bytes"].get<double>(), peer["rss_before_bytes"].get<double>() * 0.5)
        << where;
    for (const std::vector<std::string>& bad :
         {std::vector<std::string>{"--suite", "sparse", "--peer"},
          {"--suite", "sparse", "--peer", "--metric", "euclidean", "--signed"},
          {"--suite", "sparse", "--peer", "--metric", "euclidean", "--spacing", "1,2,1"},
          {"--suite", "sparse-sand", "--peer"},
          {"--peer"}}) {
        std::vector<std::string> args = {"bench", "--device", "cpu", "--json",
                                         (dir_ / "bad.json").string()};
        args.insert(args.end(), bad.begin(), bad.end());
        const RunResult b = run(args);
        EXPECT_EQ(b.code, 2) << describe(b);
        EXPECT_EQ(split_lines(b.err).size(), 1u) << describe(b);
        EXPECT_FALSE(fs::exists(dir_ / "bad.json")) << bad.back();
    }
}

// The sparse-sand suite on a small city: balls of sand and water dropped, the timed steps
// recorded, the world and field after the last step equal to the CPU automaton's and the dense
// bounded field; every option it does not take refused with one line before any work.
TEST_F(BenchSuite, SparseSandStepsTheCityAndChecksItExact) {
    const fs::path js = dir_ / "sparse-sand.json";
    const RunResult r =
        run({"bench", "--suite", "sparse-sand", "--sizes", "150x90x130", "--max-distance", "5",
             "--repeat", "12", "--warmup", "1", "--device", "cpu", "--json", js.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    const json doc = json::parse(read_text(js));
    expect_common(doc, "sparse-sand");
    EXPECT_EQ(doc["scene"], "city");
    EXPECT_EQ(doc["steps"], 12);
    ASSERT_EQ(doc["results"].size(), 1u);
    const json& row = doc["results"][0];
    const std::string where = row.dump().substr(0, 200);
    EXPECT_EQ(row["size"], std::vector<std::uint32_t>({150, 90, 130})) << where;
    EXPECT_EQ(row["max_distance"], 5.0) << where;
    EXPECT_EQ(row["format"], "u8") << where;
    EXPECT_EQ(row["steps"], 12) << where;
    EXPECT_EQ(row["step_warmup"], 1) << where;
    EXPECT_EQ(row["exact"], true) << where;
    EXPECT_GT(row["voxels_changed"].get<std::uint64_t>(), 0u) << where;
    EXPECT_GT(row["drops"].get<std::uint64_t>(), 0u) << where;
    ASSERT_EQ(row["samples_ms"].size(), 12u) << where;
    for (const char* key : {"median_ms", "simulate_ms_median", "update_ms_median",
                            "field_update_ms_median", "encode_ms_median", "tiles_run_median",
                            "steps_per_s_wall", "field_kernel_ms", "peak_rss_bytes"}) {
        ASSERT_TRUE(row.contains(key)) << where << " lacks " << key;
        EXPECT_TRUE(finite_number(row[key])) << where << " " << key;
    }
    EXPECT_TRUE(row.contains("load_average_start")) << where;
    for (const std::vector<std::string>& bad : {std::vector<std::string>{"--edits", "3"},
                                                {"--compare-blocks"},
                                                {"--world", "64"},
                                                {"--scene", "city"},
                                                {"--chunk", "8"},
                                                {"--sizes", "2000000x8x8"},
                                                {"--max-distance", "0", "--format", "u8"}}) {
        std::vector<std::string> args = {"bench",
                                         "--suite",
                                         "sparse-sand",
                                         "--device",
                                         "cpu",
                                         "--json",
                                         (dir_ / "bad.json").string()};
        args.insert(args.end(), bad.begin(), bad.end());
        const RunResult b = run(args);
        EXPECT_EQ(b.code, 2) << describe(b);
        EXPECT_EQ(split_lines(b.err).size(), 1u) << describe(b);
        EXPECT_FALSE(fs::exists(dir_ / "bad.json")) << bad[0];
    }
}

TEST_F(BenchSuite, SuiteRefusesGridOptions) {
    const RunResult r = run({"bench", "--suite", "dissertation", "--sizes", "64"});
    EXPECT_EQ(r.code, 2) << describe(r);
    EXPECT_NE(r.err.find("--sizes"), std::string::npos) << r.err;
    const RunResult q = run({"bench", "--quick", "--sizes", "8", "--device", "cpu"});
    EXPECT_EQ(q.code, 2) << describe(q);
    EXPECT_NE(q.err.find("--suite"), std::string::npos) << q.err;
    EXPECT_TRUE(list_dir(dir_).empty());
}

}  // namespace
}  // namespace voxfield::test
