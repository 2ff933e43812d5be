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

}  // namespace voxfield::cli
