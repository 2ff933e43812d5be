#pragma once
// Shared by the kernel tests: the PoCL device and a voxel-level comparison of two fields.
#include <gtest/gtest.h>

#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "voxfield/cl/generator.hpp"

namespace voxfield::test {

// Kernel tests run on PoCL explicitly; without it they fail (CI installs it).
inline ocl::Context& pocl() {
    static std::unique_ptr<ocl::Context> ctx = [] {
        for (const auto& d : ocl::list_devices()) {
            if (d.platform.find("Portable Computing Language") != std::string::npos) {
                return std::make_unique<ocl::Context>(d);
            }
        }
        return std::unique_ptr<ocl::Context>();
    }();
    if (!ctx) {
        throw std::runtime_error("PoCL (pocl-opencl-icd) is not installed: no device to test");
    }
    return *ctx;
}

// Empty when equal, else where the first difference is and both values there.
inline std::string first_difference(const std::vector<std::uint8_t>& got,
                                    const std::vector<std::uint8_t>& want, Format f, Dims d) {
    if (got.size() != want.size()) {
        return "sizes differ: " + std::to_string(got.size()) + " vs " +
               std::to_string(want.size()) + " bytes";
    }
    if (got == want) {
        return "";
    }
    std::size_t i = 0;
    while (got[i] == want[i]) {
        ++i;
    }
    const std::size_t v = i / element_size(f);
    return "first difference at voxel (" + std::to_string(v % d.x) + "," +
           std::to_string(v / d.x % d.y) + "," + std::to_string(v / d.x / d.y) + "): got " +
           std::to_string(decode_distance(got, f, v)) + ", want " +
           std::to_string(decode_distance(want, f, v));
}

}  // namespace voxfield::test
