// The editing protocol's measurement harness (see edit_log.hpp).
#include "edit_log.hpp"

namespace voxfield::cli {

void put_summary(nlohmann::json& out, const Summary& s) {
    out["n"] = s.n;
    out["median_ms"] = s.median;
    out["mean_ms"] = s.mean;
    out["std_ms"] = s.std;
    out["ci95_ms"] = {s.ci95_lo, s.ci95_hi};
    out["min_ms"] = s.min;
    out["max_ms"] = s.max;
}

std::vector<double> EditLog::update_ms() const {
    std::vector<double> ms;
    ms.reserve(samples_.size());
    for (const EditSample& e : samples_) {
        ms.push_back(e.update_ms);
    }
    return ms;
}

Summary EditLog::update_summary() const {
    return summarize(update_ms());
}

std::uint64_t EditLog::voxels_recomputed_total() const {
    std::uint64_t n = 0;
    for (const EditSample& e : samples_) {
        n += e.voxels_recomputed;
    }
    return n;
}

std::size_t EditLog::full_regenerations() const {
    std::size_t n = 0;
    for (const EditSample& e : samples_) {
        n += e.full_regeneration ? 1 : 0;
    }
    return n;
}

nlohmann::json EditLog::edits_json() const {
    nlohmann::json edits = nlohmann::json::array();
    for (const EditSample& e : samples_) {
        const Brush& b = e.brush;
        edits.push_back({{"op", to_string(b.op)},
                         {"centre", {b.centre.x, b.centre.y, b.centre.z}},
                         {"size", e.size},
                         {"radius", b.radius},
                         {"material", b.op == BrushOp::erase ? 0 : b.material},
                         {"update_ms", e.update_ms},
                         {"voxels_recomputed", e.voxels_recomputed},
                         {"voxels_changed", e.voxels_changed},
                         {"full_regeneration", e.full_regeneration}});
    }
    return edits;
}

}  // namespace voxfield::cli
