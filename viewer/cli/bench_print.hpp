#pragma once
// How `voxfield bench` shows a run of the harness (bench/bench_suites.hpp, bench_grid.hpp): the
// harness's log as "bench: ..." lines on stderr, what it is doing now on the progress line
// (progress.hpp: on a terminal only), each finished row as a table line on stdout (the
// implicit suite's on stderr), and the rows as CSV.
#include <nlohmann/json.hpp>

#include <string>

#include "bench_suites.hpp"
#include "progress.hpp"

namespace voxfield::cli {

class BenchPrinter final : public BenchObserver {
  public:
    // `suite`: the --suite name, or "" for the grid of --algorithms x --sizes. Starts the
    // progress line; the table's header line (the grid, dissertation, edits) follows the run's
    // first log line, so that a suite refusing its options prints no table.
    explicit BenchPrinter(const std::string& suite);

    void stage(const std::string& text) override;
    void progress(const std::string& what) override;
    void measured(const nlohmann::json& measurement) override;
    void row(const nlohmann::json& row) override;
    // Clears the progress line (before the command's own last lines).
    void stop() { progress_.stop(); }

  private:
    void header();

    const std::string suite_;
    bool header_done_ = false;
    Progress progress_;
};

// The suite rows as CSV: one header line and one line per row (a skipped row with its
// reason, empty cells for what it lacks).
std::string suite_csv(const nlohmann::json& rows);
// The grid's rows as CSV: one header line and one line per timed row (chunk 0: global).
std::string grid_csv(const nlohmann::json& rows);

}  // namespace voxfield::cli
