#pragma once
// The one measurement harness of the dissertation's editing protocol, shared by
// `bench --suite edits` and `view --benchmark`: both draw their edits from core's RandomEdits
// (one seed, the same edits), record every edit here with what its update cost, and write the
// same per-edit records and the same summary keys (DESIGN §4: median, mean, std, 95% CI, min,
// max in ms).
#include <nlohmann/json.hpp>

#include <cstdint>
#include <vector>

#include "voxfield/core/brush.hpp"
#include "voxfield/core/stats.hpp"

namespace voxfield::cli {

struct EditSample {
    Brush brush;
    std::int64_t size = 0;  // the protocol's edit size (RandomEdits::last_size)
    double update_ms = 0;   // device time of the update (view: field + render field)
    std::uint64_t voxels_recomputed = 0;
    std::size_t voxels_changed = 0;  // voxels the brush changed in the world
    bool full_regeneration = false;
};

// The summary keys of a series of times in ms, into `out` (an object).
void put_summary(nlohmann::json& out, const Summary& s);

class EditLog {
  public:
    void add(const EditSample& sample) { samples_.push_back(sample); }
    const std::vector<EditSample>& samples() const { return samples_; }
    std::size_t size() const { return samples_.size(); }
    std::vector<double> update_ms() const;
    Summary update_summary() const;
    std::uint64_t voxels_recomputed_total() const;
    std::size_t full_regenerations() const;
    // One record per edit: op, centre, size, radius, material, update_ms, voxels_recomputed,
    // voxels_changed, full_regeneration.
    nlohmann::json edits_json() const;

  private:
    std::vector<EditSample> samples_;
};

}  // namespace voxfield::cli
