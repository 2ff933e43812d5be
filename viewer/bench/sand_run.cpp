// The falling-sand loop of `simulate` and `bench --suite sand` (sand_run.hpp).
#include "sand_run.hpp"

#include <chrono>

namespace voxfield::cli {

void warm_up_updates(ocl::IncrementalField& field) {
    const std::uint8_t v0 = field.world().voxels()[0];
    const std::uint8_t other = v0 != 0 ? std::uint8_t{0} : std::uint8_t{1};
    field.apply_changes({{0, v0, other}});
    field.apply_changes({{0, other, v0}});
}

std::vector<SandStepRecord> run_sand_steps(
    ocl::SandSimulator& sim, ocl::IncrementalField& field, std::uint64_t seed, std::uint64_t steps,
    const std::function<bool(const SandStepRecord&)>& after) {
    using Clock = std::chrono::steady_clock;
    std::vector<SandStepRecord> records;
    for (std::uint64_t step = 0; step < steps; ++step) {
        const auto t0 = Clock::now();
        const ocl::SandStepResult r = sim.step(seed, step);
        const ocl::UpdateStats u = field.apply_changes(r.changes);
        const auto t1 = Clock::now();
        records.push_back({step, r.simulate_ms, u.update_ms,
                           std::chrono::duration<double, std::milli>(t1 - t0).count(),
                           r.changes.size(), u.voxels_recomputed, u.full_regeneration});
        if (after && !after(records.back())) {
            break;
        }
    }
    return records;
}

SandRunSummary summarize_run(const std::vector<SandStepRecord>& records) {
    SandRunSummary out;
    std::vector<double> simulate_ms, update_ms, step_ms;
    for (const SandStepRecord& r : records) {
        simulate_ms.push_back(r.simulate_ms);
        update_ms.push_back(r.update_ms);
        step_ms.push_back(r.simulate_ms + r.update_ms);
        out.device_ms += r.simulate_ms + r.update_ms;
        out.wall_ms += r.wall_ms;
        out.voxels_changed += r.voxels_changed;
        out.full_regenerations += r.full_regeneration ? 1 : 0;
        out.per_step.push_back({{"step", r.step},
                                {"simulate_ms", r.simulate_ms},
                                {"update_ms", r.update_ms},
                                {"wall_ms", r.wall_ms},
                                {"voxels_changed", r.voxels_changed},
                                {"voxels_recomputed", r.voxels_recomputed},
                                {"full_regeneration", r.full_regeneration}});
    }
    out.simulate = summarize(simulate_ms);
    out.update = summarize(update_ms);
    out.step = summarize(step_ms);
    return out;
}

}  // namespace voxfield::cli
