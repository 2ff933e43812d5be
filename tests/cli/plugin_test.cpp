// OpenVDB is a plugin loaded on first use (voxfield/core/plugin.hpp): a command that reads and
// writes no .vdb never loads it, which the dynamic loader's own log (LD_DEBUG=files: every
// object it opens) shows; one that writes a .vdb loads it; a plugin that is missing, or is not
// OpenVDB's, is one line and exit 1 with no output written.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "../scoped_env.hpp"
#include "cli_test_util.hpp"

namespace voxfield::test {
namespace {

const fs::path kVox = fs::path(VOXFIELD_DATA_DIR) / "vox" / "obj_house4.vox";

class PluginTest : public TempDirsTest {
  protected:
    PluginTest() : TempDirsTest("voxfield_plugin") {}
    RunResult generate(const std::string& output) {
        return run({"generate", kVox.string(), "-o", (dir_ / output).string(), "--device", "cpu",
                    "--max-distance", "6"});
    }
};

TEST_F(PluginTest, OpenVdbIsLoadedOnlyForVdbFiles) {
    const ScopedEnv log("LD_DEBUG", "files");
    const RunResult npy = generate("field.npy");
    ASSERT_EQ(npy.code, 0) << describe(npy);
    EXPECT_NE(npy.err.find("libOpenCL"), std::string::npos) << "no loader log";
    EXPECT_EQ(npy.err.find("libopenvdb"), std::string::npos) << "OpenVDB loaded for a .npy";
    EXPECT_EQ(npy.err.find("libvoxfield_vdb"), std::string::npos);
    const RunResult vdb = generate("field.vdb");
    ASSERT_EQ(vdb.code, 0) << describe(vdb);
    EXPECT_NE(vdb.err.find("libvoxfield_vdb.so"), std::string::npos);
    EXPECT_NE(vdb.err.find("libopenvdb"), std::string::npos);
    EXPECT_TRUE(fs::exists(dir_ / "field.vdb"));
}

TEST_F(PluginTest, AMissingOrWrongPluginIsOneLineAndNoOutput) {
    const fs::path missing = dir_ / "none" / "libvoxfield_vdb.so";
    {
        const ScopedEnv env("VOXFIELD_VDB_PLUGIN", missing.string());
        const RunResult r = generate("field.vdb");
        EXPECT_EQ(r.code, 1) << describe(r);
        EXPECT_EQ(split_lines(r.err).size(), 1u) << r.err;
        EXPECT_NE(r.err.find(missing.string() + ": not there"), std::string::npos) << r.err;
        EXPECT_NE(r.err.find("set VOXFIELD_VDB_PLUGIN to its path"), std::string::npos) << r.err;
    }
    // The peer's plugin, beside the binary as every plugin is: another entry.
    const fs::path peer =
        kExe.parent_path().parent_path() / "lib" / "voxfield" / "libvoxfield_openvdb_peer.so";
    ASSERT_TRUE(fs::exists(peer)) << peer;
    {
        const ScopedEnv env("VOXFIELD_VDB_PLUGIN", peer.string());
        const RunResult r = generate("field.vdb");
        EXPECT_EQ(r.code, 1) << describe(r);
        EXPECT_EQ(split_lines(r.err).size(), 1u) << r.err;
        EXPECT_NE(r.err.find("no entry voxfield_vdb_plugin"), std::string::npos) << r.err;
    }
    EXPECT_TRUE(list_dir(dir_).count("field.vdb") == 0) << "output written without the plugin";
    // A command without a .vdb does not need the plugin at all.
    const ScopedEnv env("VOXFIELD_VDB_PLUGIN", missing.string());
    const RunResult npy = generate("field.npy");
    EXPECT_EQ(npy.code, 0) << describe(npy);
}

}  // namespace
}  // namespace voxfield::test
