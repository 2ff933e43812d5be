// Summary statistics: mean, median, sample std and a normal-approximation 95% CI.
#include "voxfield/core/stats.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace voxfield {

Summary summarize(std::span<const double> samples) {
    Summary s;
    s.n = samples.size();
    if (s.n == 0) {
        return s;
    }
    std::vector<double> v(samples.begin(), samples.end());
    std::sort(v.begin(), v.end());
    const double n = static_cast<double>(s.n);
    double sum = 0;
    for (double x : v) {
        sum += x;
    }
    s.mean = sum / n;
    s.min = v.front();
    s.max = v.back();
    const std::size_t mid = s.n / 2;
    s.median = (s.n % 2 == 1) ? v[mid] : (v[mid - 1] + v[mid]) / 2.0;
    if (s.n > 1) {
        double ss = 0;
        for (double x : v) {
            ss += (x - s.mean) * (x - s.mean);
        }
        s.std = std::sqrt(ss / (n - 1.0));
    }
    const double half = 1.96 * s.std / std::sqrt(n);
    // Non-negative samples (durations, counts) have a non-negative mean: the interval is
    // clipped at zero rather than reaching below what the quantity can be.
    s.ci95_lo = s.min >= 0 ? std::max(0.0, s.mean - half) : s.mean - half;
    s.ci95_hi = s.mean + half;
    return s;
}

}  // namespace voxfield
