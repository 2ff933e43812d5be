// The benchmark harness as a library (viewer/bench, voxfield_bench): a run on PoCL returns
// its rows with their keys and values in range, tells its observer what it does in order, and
// writes nothing to stdout or stderr (the command line does the printing). Timings are never
// asserted beyond being finite and positive.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "bench_grid.hpp"
#include "bench_suites.hpp"
#include "voxfield/core/error.hpp"

namespace voxfield::test {
namespace {

using cli::BenchObserver;
using cli::SuiteOptions;
using nlohmann::json;

// PoCL, the CPU device every kernel test runs on; null when it is not installed.
ocl::Context* pocl() {
    static std::unique_ptr<ocl::Context> ctx = [] {
        for (const auto& d : ocl::list_devices()) {
            if (d.platform.find("Portable Computing Language") != std::string::npos) {
                return std::make_unique<ocl::Context>(d);
            }
        }
        return std::unique_ptr<ocl::Context>();
    }();
    return ctx.get();
}

// Every call, in order.
struct Recorder final : BenchObserver {
    void stage(const std::string& text) override { events.push_back("stage " + text); }
    void progress(const std::string& what) override { progress_lines.push_back(what); }
    void measured(const json& m) override { measurements.push_back(m); }
    void row(const json& r) override {
        events.push_back("row");
        rows.push_back(r);
    }
    std::vector<std::string> events, progress_lines;
    std::vector<json> measurements, rows;
};

// The suite run with stdout and stderr captured: what reached them, besides the document.
struct Captured {
    json doc;
    std::string out, err;
};

Captured run_captured(const SuiteOptions& o, BenchObserver& observer) {
    Captured c;
    testing::internal::CaptureStdout();
    testing::internal::CaptureStderr();
    try {
        c.doc = cli::run_suite(*pocl(), o, observer);
    } catch (...) {
        testing::internal::GetCapturedStdout();
        testing::internal::GetCapturedStderr();
        throw;
    }
    c.out = testing::internal::GetCapturedStdout();
    c.err = testing::internal::GetCapturedStderr();
    return c;
}

bool positive(const json& v) {
    return v.is_number() && std::isfinite(v.get<double>()) && v.get<double>() > 0;
}

bool non_negative(const json& v) {
    return v.is_number() && std::isfinite(v.get<double>()) && v.get<double>() >= 0;
}

// The document's common keys (DESIGN §4 bench JSON).
void expect_document(const json& doc, const std::string& suite) {
    for (const char* key : {"device", "commit", "date", "suite", "quick", "seed", "repeat",
                            "warmup", "time_budget_s", "results"}) {
        EXPECT_TRUE(doc.contains(key)) << key;
    }
    EXPECT_EQ(doc["suite"], suite);
    EXPECT_NE(doc["device"]["platform"].get<std::string>().find("Portable Computing Language"),
              std::string::npos);
    ASSERT_TRUE(doc["results"].is_array());
}

class BenchLibrary : public ::testing::Test {
  protected:
    void SetUp() override {
        if (pocl() == nullptr) {
            GTEST_SKIP() << "PoCL (pocl-opencl-icd) is not installed: no device to run on";
        }
    }
};

TEST_F(BenchLibrary, SandRowsComeBackAndNothingIsPrinted) {
    SuiteOptions o;
    o.suite = "sand";
    o.world = 24;
    o.repeat = 4;  // steps
    Recorder seen;
    const Captured c = run_captured(o, seen);
    EXPECT_EQ(c.out, "");
    EXPECT_EQ(c.err, "");
    expect_document(c.doc, "sand");
    EXPECT_EQ(c.doc["steps"], 4);
    EXPECT_EQ(c.doc["world"], 24);
    const json& rows = c.doc["results"];
    ASSERT_EQ(rows.size(), 2u);  // unbounded, then bounded at D = 16
    EXPECT_TRUE(rows[0]["max_distance"].is_null());
    EXPECT_EQ(rows[1]["max_distance"], 16.0);
    for (const json& r : rows) {
        const std::string where = r.dump().substr(0, 200);
        EXPECT_EQ(r["size"], json::array({24, 24, 24})) << where;
        EXPECT_EQ(r["metric"], "manhattan") << where;
        EXPECT_EQ(r["format"], "u16") << where;
        EXPECT_EQ(r["steps"], 4) << where;
        for (const char* key : {"steps_per_s_device", "steps_per_s_wall", "simulate_ms_median",
                                "step_ms_median", "full_regeneration_ms", "step_over_full"}) {
            EXPECT_TRUE(positive(r[key])) << where << " " << key << " = " << r[key];
        }
        for (const char* key : {"update_ms_median", "update_ms_mean", "update_ms_max"}) {
            EXPECT_TRUE(non_negative(r[key])) << where << " " << key << " = " << r[key];
        }
        EXPECT_LE(r["update_ms_median"].get<double>(), r["update_ms_max"].get<double>()) << where;
        // Sand falls from the first step on (scene_sand's grains in the upper half).
        EXPECT_GT(r["voxels_changed"].get<std::size_t>(), 0u) << where;
        EXPECT_LE(r["full_regenerations"].get<std::size_t>(), 4u) << where;
        ASSERT_EQ(r["per_step"].size(), 4u) << where;
        std::size_t changed = 0;
        for (std::size_t i = 0; i < 4; ++i) {
            const json& s = r["per_step"][i];
            EXPECT_EQ(s["step"], i) << where;
            EXPECT_TRUE(positive(s["simulate_ms"])) << where;
            EXPECT_TRUE(non_negative(s["update_ms"])) << where;
            EXPECT_TRUE(positive(s["wall_ms"])) << where;
            changed += s["voxels_changed"].get<std::size_t>();
        }
        EXPECT_EQ(changed, r["voxels_changed"].get<std::size_t>()) << where;
    }
    // The observer saw each row as it was done: set-up, then its row, per bound.
    ASSERT_EQ(seen.rows.size(), 2u);
    EXPECT_EQ(seen.rows[0], rows[0]);
    EXPECT_EQ(seen.rows[1], rows[1]);
    EXPECT_EQ(seen.events,
              (std::vector<std::string>{"stage sand 24x24x24 unbounded, L1: set-up", "row",
                                        "stage sand 24x24x24 bounded at 16, L1: set-up", "row"}));
    ASSERT_EQ(seen.progress_lines.size(), 8u);  // every step of both runs
    EXPECT_EQ(seen.progress_lines[3], "sand 24x24x24 unbounded, L1: step 4/4");
    EXPECT_TRUE(seen.measurements.empty());
}

TEST_F(BenchLibrary, EditsRowsCarryTheirKeysAndExactRowsAreExact) {
    SuiteOptions o;
    o.suite = "edits";
    o.world = 16;
    o.chunk = 8;
    o.edits = 3;
    o.repeat = 1;
    o.warmup = 0;
    o.quick = true;
    Recorder seen;
    const Captured c = run_captured(o, seen);
    EXPECT_EQ(c.out, "");
    EXPECT_EQ(c.err, "");
    expect_document(c.doc, "edits");
    EXPECT_EQ(c.doc["edits"], 3);
    EXPECT_EQ(c.doc["chunk"], 8);
    const json& rows = c.doc["results"];
    // exact unbounded and at D = 4, 16, 64, then the dissertation's eight algorithms.
    ASSERT_EQ(rows.size(), 12u);
    std::size_t timed = 0;
    std::uint64_t recomputed = 0;
    for (const json& r : rows) {
        const std::string where = r.dump().substr(0, 200);
        EXPECT_EQ(r["table"], "edits") << where;
        EXPECT_EQ(r["size"], json::array({16, 16, 16})) << where;
        EXPECT_EQ(r["chunk"].is_null(), r["algorithm"] == "exact") << where;
        if (r.contains("skipped")) {
            EXPECT_NE(r["algorithm"], "exact") << where;
            EXPECT_FALSE(r["skipped"].get<std::string>().empty()) << where;
            continue;
        }
        ++timed;
        EXPECT_EQ(r["edits_requested"], 3) << where;
        EXPECT_EQ(r["edits_done"], 3) << where;  // far inside the default time budget
        ASSERT_EQ(r["edits"].size(), 3u) << where;
        EXPECT_EQ(r["n"], 3) << where;
        for (const char* key : {"median_ms", "mean_ms", "min_ms", "max_ms", "std_ms"}) {
            EXPECT_TRUE(non_negative(r[key])) << where << " " << key << " = " << r[key];
        }
        EXPECT_LE(r["min_ms"].get<double>(), r["median_ms"].get<double>()) << where;
        EXPECT_LE(r["median_ms"].get<double>(), r["max_ms"].get<double>()) << where;
        EXPECT_TRUE(positive(r["full_regeneration_ms"])) << where;
        EXPECT_EQ(r["full_regeneration_ms_samples"].size(), 1u) << where;
        for (const char* key : {"over_fraction", "under_fraction"}) {
            EXPECT_TRUE(non_negative(r[key])) << where << " " << key;
            EXPECT_LE(r[key].get<double>(), 1.0) << where << " " << key;
        }
        EXPECT_TRUE(non_negative(r["mean_error"])) << where;
        EXPECT_LE(r["mean_error"].get<double>(), r["max_error"].get<double>()) << where;
        if (r["algorithm"] == "exact") {
            EXPECT_EQ(r["max_error"], 0) << where;
        }
        for (const json& e : r["edits"]) {
            EXPECT_GE(e["size"].get<int>(), 1) << where;
            EXPECT_LE(e["size"].get<int>(), 7) << where;  // 1..C-1
            EXPECT_TRUE(non_negative(e["update_ms"])) << where;
        }
        recomputed += r["voxels_recomputed_total"].get<std::uint64_t>();
    }
    EXPECT_GE(timed, 4u) << "the exact rows were skipped";
    EXPECT_GT(recomputed, 0u);
    // Every row reached the observer as it was done, each after its set-up line.
    ASSERT_EQ(seen.rows.size(), rows.size());
    for (std::size_t i = 0; i < rows.size(); ++i) {
        EXPECT_EQ(seen.rows[i], rows[i]);
    }
    ASSERT_FALSE(seen.events.empty());
    EXPECT_EQ(seen.events.front().rfind("stage suite edits", 0), 0u) << seen.events.front();
    EXPECT_EQ(seen.events.back().rfind("stage suite edits done in ", 0), 0u) << seen.events.back();
    EXPECT_FALSE(seen.progress_lines.empty());
}

// `bench --algorithms exact,brute --sizes 16,200`: exact timed and exact on both sizes, brute
// timed at 16^3 and skipped (estimated far over a minute) at 200^3, in that order.
TEST_F(BenchLibrary, GridRowsAreTimedOrSkippedWithTheirReason) {
    cli::GridOptions o;
    o.algorithms = {"exact", "brute"};
    o.sizes = {Dims{16, 16, 16}, Dims{200, 200, 200}};
    o.repeat = 2;
    o.warmup = 1;
    Recorder seen;
    testing::internal::CaptureStdout();
    testing::internal::CaptureStderr();
    const json doc = cli::run_grid(*pocl(), o, seen);
    EXPECT_EQ(testing::internal::GetCapturedStdout(), "");
    EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
    for (const char* key : {"device", "commit", "date", "results"}) {
        EXPECT_TRUE(doc.contains(key)) << key;
    }
    const json& rows = doc["results"];
    ASSERT_EQ(rows.size(), 4u);
    for (std::size_t i = 0; i < rows.size(); ++i) {
        const json& r = rows[i];
        const std::string where = r.dump().substr(0, 300);
        EXPECT_EQ(r["algorithm"], i < 2 ? "exact" : "brute") << where;
        EXPECT_EQ(r["size"][0], i % 2 == 0 ? 16 : 200) << where;
        EXPECT_TRUE(r["chunk"].is_null()) << where;
        if (i == 3) {
            ASSERT_TRUE(r.contains("skipped")) << where;
            EXPECT_NE(r["skipped"].get<std::string>().find("brute on 200x200x200"),
                      std::string::npos)
                << where;
            continue;
        }
        ASSERT_FALSE(r.contains("skipped")) << where;
        EXPECT_EQ(r["samples_ms"].size(), 2u) << where;
        for (const char* key : {"median_ms", "mean_ms", "min_ms", "max_ms", "gvox_per_s"}) {
            EXPECT_TRUE(positive(r[key])) << where << " " << key << " = " << r[key];
        }
        EXPECT_LE(r["min_ms"].get<double>(), r["median_ms"].get<double>()) << where;
        EXPECT_LE(r["median_ms"].get<double>(), r["max_ms"].get<double>()) << where;
        EXPECT_EQ(r["max_error"], 0) << where;  // both algorithms are exact
        EXPECT_EQ(r["mean_error"], 0.0) << where;
        EXPECT_EQ(r["metric"], "manhattan") << where;
        EXPECT_EQ(r["format"], "u16") << where;
        EXPECT_FALSE(r["stages"].empty()) << where;
    }
    ASSERT_EQ(seen.rows.size(), 4u);
    EXPECT_EQ(seen.rows[3], rows[3]);
    EXPECT_EQ(seen.events.front(), "stage exact 16x16x16: building scene 'spheres'");
    EXPECT_NE(
        std::find(seen.events.begin(), seen.events.end(),
                  "stage brute 200x200x200: skipped: " + rows[3]["skipped"].get<std::string>()),
        seen.events.end());
    EXPECT_NE(std::find(seen.progress_lines.begin(), seen.progress_lines.end(),
                        "exact 16x16x16: run 2/2"),
              seen.progress_lines.end());
}

TEST_F(BenchLibrary, RefusedOptionsThrowBeforeAnyRow) {
    SuiteOptions o;
    o.suite = "edits";
    o.world = 8;
    o.chunk = 16;  // larger than the world
    Recorder seen;
    testing::internal::CaptureStdout();
    testing::internal::CaptureStderr();
    EXPECT_THROW(cli::run_suite(*pocl(), o, seen), InputError);
    EXPECT_EQ(testing::internal::GetCapturedStdout(), "");
    EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
    EXPECT_TRUE(seen.events.empty());
    EXPECT_TRUE(seen.rows.empty());
}

}  // namespace
}  // namespace voxfield::test
