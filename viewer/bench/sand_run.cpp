// The falling-sand loop of `simulate` and `bench --suite sand` (sand_run.hpp).
#include "sand_run.hpp"

#include <chrono>

namespace voxfield::cli {

std::vector<SandStepRecord> run_sand_steps(
    pipeline::Scene& scene, const SandRules& rules, std::uint64_t seed, std::uint64_t steps,
    const std::function<bool(const SandStepRecord&)>& after) {
    using Clock = std::chrono::steady_clock;
    std::vector<SandStepRecord> records;
    for (std::uint64_t step = 0; step < steps; ++step) {
        const auto t0 = Clock::now();
        const pipeline::SceneUpdate u = scene.step_sand(rules, seed, step);
        const auto t1 = Clock::now();
        records.push_back({step, u.simulate_ms, u.stats.update_ms,
                           std::chrono::duration<double, std::milli>(t1 - t0).count(),
                           static_cast<std::size_t>(u.voxels_changed), u.stats.voxels_recomputed,
                           u.stats.full_regeneration});
        if (after && !after(records.back())) {
            break;
        }
    }
    return records;
}

std::vector<SandStepRecord> run_sparse_sand_steps(
    ocl::SparseSand& sim, std::uint64_t seed, std::uint64_t steps,
    const std::function<bool(const SandStepRecord&)>& after,
    std::vector<std::pair<std::uint32_t, std::uint32_t>>* tiles) {
    using Clock = std::chrono::steady_clock;
    std::vector<SandStepRecord> records;
    for (std::uint64_t step = 0; step < steps; ++step) {
        const auto t0 = Clock::now();
        const ocl::SparseSand::Step u = sim.step(seed, step);
        const auto t1 = Clock::now();
        records.push_back({step, u.simulate_ms, u.update_ms,
                           std::chrono::duration<double, std::milli>(t1 - t0).count(),
                           static_cast<std::size_t>(u.changed),
                           static_cast<std::uint64_t>(u.update.recomputed.volume()), false});
        if (tiles != nullptr) {
            tiles->emplace_back(u.tiles_run, u.tiles_changed);
        }
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
