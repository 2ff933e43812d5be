// Metric names, spacing parsing and the metric itself (DESIGN §3).
#include "voxfield/core/metric.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "voxfield/core/error.hpp"

namespace voxfield {

const std::vector<std::string>& metric_names() {
    static const std::vector<std::string> names = {"manhattan", "chebyshev", "euclidean"};
    return names;
}

Metric parse_metric(const std::string& name) {
    if (name == "manhattan") {
        return Metric::manhattan;
    }
    if (name == "chebyshev") {
        return Metric::chebyshev;
    }
    if (name == "euclidean") {
        return Metric::euclidean;
    }
    throw InputError("unknown metric '" + name + "' (valid: manhattan, chebyshev, euclidean)");
}

std::string to_string(Metric m) {
    switch (m) {
        case Metric::manhattan:
            return "manhattan";
        case Metric::chebyshev:
            return "chebyshev";
        case Metric::euclidean:
            return "euclidean";
    }
    throw std::invalid_argument("to_string: invalid Metric value");
}

std::string Spacing::to_string() const {
    std::ostringstream s;
    s << x << ',' << y << ',' << z;
    return s.str();
}

Spacing parse_spacing(const std::string& text) {
    const auto values = std::count(text.begin(), text.end(), ',') + 1;
    if (values != 3) {
        throw InputError("spacing '" + text + "': expected three values X,Y,Z, got " +
                         std::to_string(values));
    }
    double v[3] = {0, 0, 0};
    std::size_t start = 0;
    for (int axis = 0; axis < 3; ++axis) {
        const std::size_t end = axis < 2 ? text.find(',', start) : text.size();
        if (end == std::string::npos) {
            throw InputError("spacing '" + text + "': expected three values X,Y,Z");
        }
        const std::string part = text.substr(start, end - start);
        char* stop = nullptr;
        const double value = part.empty() ? 0 : std::strtod(part.c_str(), &stop);
        if (part.empty() || stop != part.c_str() + part.size()) {
            throw InputError("spacing '" + text + "': '" + part + "' is not a number");
        }
        if (!std::isfinite(value) || value <= 0) {
            throw InputError("spacing '" + text + "': every value must be positive and finite, " +
                             "got " + part);
        }
        v[axis] = value;
        start = end + 1;
    }
    return {v[0], v[1], v[2]};
}

namespace {

std::string number(double v) {
    std::ostringstream s;
    s << v;
    return s.str();
}

}  // namespace

void check_spacing_range(const Spacing& s, Metric m, Dims world) {
    const std::string text = "spacing " + s.to_string();
    for (const double v : {s.x, s.y, s.z}) {
        if (!std::isfinite(v) || v <= 0) {
            throw InputError(text + ": every value must be positive and finite, got " + number(v));
        }
        if (v > std::numeric_limits<float>::max() || v < std::numeric_limits<float>::min()) {
            throw InputError(text + ": " + number(v) +
                             " is outside the float range the kernels compute in (" +
                             number(std::numeric_limits<float>::min()) + " to " +
                             number(std::numeric_limits<float>::max()) + ")");
        }
    }
    if (s.unit()) {
        return;  // integer scans
    }
    // The world's diameter in the metric (one more voxel per axis for a signed field's
    // padding), against the smallest spacing: the float scans of exact_separable.cl compare
    // partial distances of that size and turn their ratio to the spacing into a voxel
    // position (an int); a step of the smallest spacing is resolved up to 2^24 of them.
    const double ax = s.x * (static_cast<double>(world.x) + 1);
    const double ay = s.y * (static_cast<double>(world.y) + 1);
    const double az = s.z * (static_cast<double>(world.z) + 1);
    const double diameter = m == Metric::manhattan   ? ax + ay + az
                            : m == Metric::chebyshev ? std::max({ax, ay, az})
                                                     : std::sqrt(ax * ax + ay * ay + az * az);
    const double partial = m == Metric::euclidean ? diameter * diameter : diameter;
    if (partial > std::numeric_limits<float>::max()) {
        throw InputError(text + ": distances across this " + world.to_string() + " world reach " +
                         number(diameter) + (m == Metric::euclidean ? "^2" : "") +
                         ", beyond the float range the kernels compute in (" +
                         number(std::numeric_limits<float>::max()) + "); use smaller spacings");
    }
    const double smallest = std::min({s.x, s.y, s.z});
    if (diameter / smallest > kSpacingStepsLimit) {
        throw InputError(text + ": distances across this " + world.to_string() + " world reach " +
                         number(diameter) + ", " + number(diameter / smallest) +
                         " times the smallest spacing " + number(smallest) +
                         "; the kernels' float scans resolve at most " +
                         number(kSpacingStepsLimit) +
                         " (2^24) steps of the smallest spacing: bring the spacings closer "
                         "together or use a smaller world");
    }
}

double metric_distance(Metric m, const Spacing& s, long dx, long dy, long dz) {
    const double ax = s.x * static_cast<double>(std::labs(dx));
    const double ay = s.y * static_cast<double>(std::labs(dy));
    const double az = s.z * static_cast<double>(std::labs(dz));
    switch (m) {
        case Metric::manhattan:
            return ax + ay + az;
        case Metric::chebyshev:
            return std::max({ax, ay, az});
        case Metric::euclidean:
            return std::sqrt(ax * ax + ay * ay + az * az);
    }
    throw std::invalid_argument("metric_distance: invalid Metric value");
}

}  // namespace voxfield
