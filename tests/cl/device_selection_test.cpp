// Device selection (ocl::select_device) walks the platforms only as far as the device asked
// for: whatever it returns must be the device, with the info, that the whole list gives for
// the same request.
#include <gtest/gtest.h>

#include <cstdlib>
#include <optional>
#include <string>
#include <vector>

#include "voxfield/cl/runtime.hpp"

namespace voxfield {
namespace {

// The device the documented rules pick from the whole list; nullopt when none is usable.
std::optional<ocl::DeviceInfo> by_the_list(const std::vector<ocl::DeviceInfo>& all,
                                           const std::vector<std::string>& types) {
    for (const std::string& type : types) {
        for (const auto& d : all) {
            if ((type.empty() || d.type == type) && d.available && d.compiler_available) {
                return d;
            }
        }
    }
    return std::nullopt;
}

void expect_same(const ocl::DeviceInfo& got, const ocl::DeviceInfo& want, const std::string& spec) {
    EXPECT_EQ(got.index, want.index) << spec;
    EXPECT_EQ(got.device(), want.device()) << spec;
    EXPECT_EQ(got.name, want.name) << spec;
    EXPECT_EQ(got.platform, want.platform) << spec;
    EXPECT_EQ(got.vendor, want.vendor) << spec;
    EXPECT_EQ(got.version, want.version) << spec;
    EXPECT_EQ(got.driver, want.driver) << spec;
    EXPECT_EQ(got.type, want.type) << spec;
    EXPECT_EQ(got.compute_units, want.compute_units) << spec;
    EXPECT_EQ(got.global_mem, want.global_mem) << spec;
    EXPECT_EQ(got.max_alloc, want.max_alloc) << spec;
    EXPECT_EQ(got.extensions, want.extensions) << spec;
    EXPECT_EQ(got.host_unified_memory, want.host_unified_memory) << spec;
}

class SelectDevice : public ::testing::Test {
  protected:
    void SetUp() override {
        if (const char* v = std::getenv("VOXFIELD_DEVICE")) {
            saved = v;
        }
        ::unsetenv("VOXFIELD_DEVICE");
        all = ocl::list_devices();
        if (all.empty()) {
            GTEST_SKIP() << "no OpenCL device";
        }
    }
    void TearDown() override {
        if (saved) {
            ::setenv("VOXFIELD_DEVICE", saved->c_str(), 1);
        }
    }
    std::vector<ocl::DeviceInfo> all;
    std::optional<std::string> saved;
};

TEST_F(SelectDevice, TypesPickWhatTheWholeListPicks) {
    const std::vector<std::pair<std::string, std::vector<std::string>>> requests = {
        {"cpu", {"cpu"}}, {"gpu", {"gpu"}}, {"", {"gpu", "cpu", ""}}};
    for (const auto& [spec, types] : requests) {
        const auto want = by_the_list(all, types);
        if (!want) {
            EXPECT_THROW(ocl::select_device(spec), ocl::DeviceSelectionError) << spec;
            continue;
        }
        expect_same(ocl::select_device(spec), *want, "'" + spec + "'");
    }
}

TEST_F(SelectDevice, IndicesPickTheirDevice) {
    for (const auto& d : all) {
        const std::string spec = std::to_string(d.index);
        if (!d.available || !d.compiler_available) {
            EXPECT_THROW(ocl::select_device(spec), ocl::DeviceSelectionError) << spec;
            continue;
        }
        expect_same(ocl::select_device(spec), d, spec);
        expect_same(ocl::select_device("000" + spec), d, "000" + spec);
    }
    for (const std::string& beyond :
         {std::to_string(all.size()), std::string("18446744073709551616"),
          std::string("99999999999999999999999")}) {
        try {
            ocl::select_device(beyond);
            ADD_FAILURE() << beyond << " selected a device";
        } catch (const ocl::DeviceSelectionError& e) {
            EXPECT_NE(std::string(e.what()).find("the indices are 0.."), std::string::npos)
                << e.what();
        }
    }
}

TEST_F(SelectDevice, TheEnvironmentIsTheDefault) {
    ::setenv("VOXFIELD_DEVICE", "cpu", 1);
    if (const auto want = by_the_list(all, {"cpu"})) {
        expect_same(ocl::select_device(""), *want, "VOXFIELD_DEVICE=cpu");
    }
    ::setenv("VOXFIELD_DEVICE", "0", 1);
    if (all[0].available && all[0].compiler_available) {
        expect_same(ocl::select_device(""), all[0], "VOXFIELD_DEVICE=0");
    }
}

}  // namespace
}  // namespace voxfield
