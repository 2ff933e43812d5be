// Metric names, spacing parsing and the metric itself (DESIGN §3).
#include "voxfield/core/metric.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdlib>
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
