// Frictions a user meets: what --help offers works, devices --json names the sharing path.
#include <nlohmann/json.hpp>

#include "cli_test_util.hpp"

namespace voxfield::test {
namespace {

class FrictionsCli : public ::testing::Test {
  protected:
    void SetUp() override { io = make_temp_dir("voxfield_frictions_io"); }
    void TearDown() override { fs::remove_all(io); }
    RunResult run(const std::vector<std::string>& args) { return run_voxfield(args, io); }
    fs::path io;
};

// The help text of `option` (its line and the wrapped lines under it).
std::string option_help(const std::string& help, const std::string& option) {
    const std::size_t at = help.find("  " + option + " ");
    if (at == std::string::npos) {
        return {};
    }
    const std::size_t end = help.find("\n  -", at + 1);
    return help.substr(at, end == std::string::npos ? std::string::npos : end - at);
}

TEST_F(FrictionsCli, DevicesJsonNamesEachDevicesSharingPath) {
    const RunResult r = run({"devices", "--json"});
    ASSERT_EQ(r.code, 0) << describe(r);
    const nlohmann::json j = nlohmann::json::parse(r.out);
    ASSERT_TRUE(j.is_array());
    ASSERT_FALSE(j.empty());
    for (const auto& d : j) {
        ASSERT_TRUE(d.contains("sharing")) << d.dump();
        EXPECT_FALSE(d["sharing"]["path"].get<std::string>().empty()) << d.dump();
        EXPECT_TRUE(d["sharing"].contains("vulkan_device")) << d.dump();
        EXPECT_TRUE(d["sharing"].contains("why_not")) << d.dump();
    }
}

TEST_F(FrictionsCli, ViewOffersOnlyTheFormatsItRenders) {
    const RunResult r = run({"view", "--help"});
    ASSERT_EQ(r.code, 0) << describe(r);
    const std::string format = option_help(r.out, "--format");
    ASSERT_FALSE(format.empty()) << r.out;
    for (const char* works : {"u8", "u16", "u32", "packed32"}) {
        EXPECT_NE(format.find(works), std::string::npos) << format;
    }
    for (const char* not_rendered : {"i8", "i16", "i32", "f32", "f64"}) {
        EXPECT_EQ(format.find(not_rendered), std::string::npos) << format;
    }
    const RunResult f = run({"view", "--world", "8", "--format", "f32"});
    EXPECT_EQ(f.code, 2) << describe(f);
}

TEST_F(FrictionsCli, SimulateHelpOffersNoAlgorithm) {
    const RunResult r = run({"simulate", "--help"});
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(r.out.find("--algorithm"), std::string::npos) << r.out;
    const RunResult g = run({"generate", "--help"});
    EXPECT_NE(option_help(g.out, "--metric").find("--algorithm exact"), std::string::npos) << g.out;
}

}  // namespace
}  // namespace voxfield::test
