// `voxfield render` end to end: bad input is refused (exit 2, one stderr line, no file), and a
// small render writes a PNG atomically and reports the sharing path and GPU time.
#include <cstdlib>
#include <string>
#include <vector>

#include "../cli/cli_test_util.hpp"

namespace voxfield::test {
namespace {

const fs::path kModel = fs::path(VOXFIELD_DATA_DIR) / "vox" / "chr_army1.vox";

class RenderCli : public TempDirsTest {
  protected:
    RenderCli() : TempDirsTest("voxfield_render") {}
    void SetUp() override {
        TempDirsTest::SetUp();
        ::setenv("VOXFIELD_VALIDATE", "1", 1);  // `--validate`: any message exits 1
    }
};

TEST_F(RenderCli, BadInputExitsTwoWithOneLineAndNoFile) {
    write_file(dir_ / "world.txt", "not a world");
    const std::string out = (dir_ / "out.png").string();
    const std::vector<std::vector<std::string>> cases = {
        {kModel.string(), "-o", out, "--width", "0"},
        {kModel.string(), "-o", out, "--field", "u16"},
        {kModel.string(), "-o", out, "--width", "16385"},
        {kModel.string(), "-o", out, "--height", "0"},
        {kModel.string(), "-o", out, "--width", "-3"},
        {kModel.string(), "-o", out, "--fov", "0"},
        {kModel.string(), "-o", out, "--fov", "180"},
        {kModel.string(), "-o", out, "--fov", "-10"},
        {kModel.string(), "-o", out, "--camera", "1,2,3", "--target", "1,2,3"},
        {kModel.string(), "-o", out, "--camera", "1,2"},
        {kModel.string(), "-o", out, "--target", "a,b,c"},
        {kModel.string(), "-o", out, "--camera", "1,2,3,4"},
        {kModel.string(), "-o", out, "--sky", "12345"},
        {kModel.string(), "-o", out, "--sky", "zzzzzz"},
        {kModel.string(), "-o", out, "--shading", "phong"},
        {kModel.string(), "-o", out, "--metric", "taxicab"},
        {kModel.string(), "-o", (dir_ / "out.jpg").string()},
        {kModel.string(), "-o", (dir_ / "missing" / "out.png").string()},
        {(dir_ / "absent.vox").string(), "-o", out},
        {(dir_ / "world.txt").string(), "-o", out},
        {kModel.string()},
    };
    for (const auto& args : cases) {
        std::vector<std::string> full = {"render"};
        full.insert(full.end(), args.begin(), args.end());
        const RunResult r = run_voxfield(full, io_);
        std::string cmd;
        for (const auto& a : args) {
            cmd += a + " ";
        }
        EXPECT_EQ(r.code, 2) << cmd << describe(r);
        EXPECT_EQ(split_lines(r.err).size(), 1u) << cmd << describe(r);
        EXPECT_EQ(list_dir(dir_), std::set<std::string>{"world.txt"}) << cmd;
    }
}

// No Vulkan device serves the request (a device index that does not exist, from the
// environment as from a machine without a driver): the same "no driver" situation as OpenCL's
// DeviceSelectionError, so the same exit code 2, one line and no file.
TEST_F(RenderCli, NoUsableVulkanDeviceExitsTwo) {
    const std::string out = (dir_ / "out.png").string();
    for (const char* spec : {"99", "tpu"}) {
        ::setenv("VOXFIELD_VK_DEVICE", spec, 1);
        const RunResult r = run_voxfield({"render", kModel.string(), "-o", out}, io_);
        ::unsetenv("VOXFIELD_VK_DEVICE");
        EXPECT_EQ(r.code, 2) << spec << describe(r);
        EXPECT_EQ(split_lines(r.err).size(), 1u) << spec << describe(r);
        EXPECT_NE(r.err.find("Vulkan"), std::string::npos) << describe(r);
        EXPECT_TRUE(list_dir(dir_).empty()) << spec;
    }
}

TEST_F(RenderCli, WritesPngAndReports) {
    const fs::path out = dir_ / "army.png";
    const RunResult r = run_voxfield({"render", kModel.string(), "-o", out.string(), "--width",
                                      "64", "--height", "48", "--shading", "lit", "--stats"},
                                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(list_dir(dir_), std::set<std::string>{"army.png"});
    const auto bytes = read_bytes(out);
    ASSERT_GT(bytes.size(), 8u);
    EXPECT_EQ(std::string(bytes.begin() + 1, bytes.begin() + 4), "PNG");
    // compact by default; PoCL + lavapipe share one host allocation (DESIGN §2 path 2).
    EXPECT_NE(r.out.find("compact"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("sharing: path 2"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("ray march"), std::string::npos) << r.out;
    EXPECT_TRUE(r.err.empty()) << r.err;
}

TEST_F(RenderCli, BothFieldFormatsGiveTheSameImage) {
    const fs::path a = dir_ / "compact.png", b = dir_ / "packed.png";
    const RunResult rc = run_voxfield({"render", kModel.string(), "-o", a.string(), "--width", "64",
                                       "--height", "48", "--field", "compact"},
                                      io_);
    ASSERT_EQ(rc.code, 0) << describe(rc);
    const RunResult rp = run_voxfield({"render", kModel.string(), "-o", b.string(), "--width", "64",
                                       "--height", "48", "--field", "packed32"},
                                      io_);
    ASSERT_EQ(rp.code, 0) << describe(rp);
    EXPECT_NE(rp.out.find("sharing: path 3"), std::string::npos) << rp.out;
    EXPECT_EQ(read_bytes(a), read_bytes(b));
}

// The field of every metric, in both formats, gives the same image: the metric decides how far
// rays walk between fetches, never which voxel they hit. Flat shading: lit shading's ambient
// occlusion reads the field's distances, which differ by metric where the nearest solid lies
// off the normal.
TEST_F(RenderCli, EveryMetricGivesTheSameImage) {
    const fs::path reference = dir_ / "manhattan-compact.png";
    for (const std::string metric : {"manhattan", "chebyshev", "euclidean"}) {
        for (const std::string field : {"compact", "packed32"}) {
            const fs::path out = dir_ / (metric + "-" + field + ".png");
            const RunResult r =
                run_voxfield({"render", kModel.string(), "-o", out.string(), "--width", "64",
                              "--height", "48", "--metric", metric, "--field", field, "--stats"},
                             io_);
            ASSERT_EQ(r.code, 0) << describe(r);
            EXPECT_NE(r.out.find("exact " + metric + " field"), std::string::npos) << r.out;
            EXPECT_NE(r.out.find("field fetches"), std::string::npos) << r.out;
            EXPECT_EQ(read_bytes(out), read_bytes(reference)) << metric << " " << field;
        }
    }
}

// A field with voxel spacing, turned into voxel steps by its largest spacing, draws the same
// image as the unit field: the steps are lower bounds, so no solid is skipped, and the DDA
// decides the hit voxel. packed32 cannot take a spacing (its field is copied as it is).
TEST_F(RenderCli, SpacingGivesTheSameImage) {
    const fs::path unit = dir_ / "unit.png";
    RunResult r = run_voxfield(
        {"render", kModel.string(), "-o", unit.string(), "--width", "64", "--height", "48"}, io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    for (const std::string metric : {"manhattan", "chebyshev", "euclidean"}) {
        for (const std::string spacing : {"2,1,0.5", "0.3,0.3,0.3"}) {
            const fs::path out = dir_ / (metric + "-spaced.png");
            r = run_voxfield({"render", kModel.string(), "-o", out.string(), "--width", "64",
                              "--height", "48", "--metric", metric, "--spacing", spacing},
                             io_);
            ASSERT_EQ(r.code, 0) << describe(r);
            EXPECT_EQ(read_bytes(out), read_bytes(unit)) << metric << " spacing " << spacing;
        }
    }
    r = run_voxfield({"render", kModel.string(), "-o", (dir_ / "p.png").string(), "--field",
                      "packed32", "--spacing", "2,1,1"},
                     io_);
    EXPECT_EQ(r.code, 2) << describe(r);
    EXPECT_FALSE(fs::exists(dir_ / "p.png"));
}

// A part (.sdf.json) is traced on the trilinear surface of its discretisation: the report says
// so, every metric and field format gives the same image (the walk decides where a ray meets a
// crossed voxel, never whether), and `view` shows the same frame.
TEST_F(RenderCli, PartsAreTracedOnTheirSurface) {
    const fs::path part = fs::path(VOXFIELD_DATA_DIR) / "parts" / "gear_ring.sdf.json";
    const fs::path reference = dir_ / "part.png";
    RunResult r = run_voxfield(
        {"render", part.string(), "-o", reference.string(), "--width", "64", "--height", "48"},
        io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.out.find("implicit: "), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("crossed voxels traced on the trilinear interpolant"), std::string::npos)
        << r.out;
    for (const std::string metric : {"chebyshev", "euclidean"}) {
        for (const std::string field : {"compact", "packed32"}) {
            const fs::path out = dir_ / (metric + "-" + field + ".png");
            r = run_voxfield({"render", part.string(), "-o", out.string(), "--width", "64",
                              "--height", "48", "--metric", metric, "--field", field},
                             io_);
            ASSERT_EQ(r.code, 0) << describe(r);
            EXPECT_EQ(read_bytes(out), read_bytes(reference)) << metric << " " << field;
        }
    }
    // view's headless frame (no display): the same default camera and the same surface.
    const fs::path shown = dir_ / "view.png";
    const char* display = std::getenv("DISPLAY");
    const std::string saved = display ? display : "";
    ::unsetenv("DISPLAY");
    r = run_voxfield({"view", part.string(), "--shading", "flat", "--width", "64", "--height", "48",
                      "--fallback-png", shown.string()},
                     io_);
    if (!saved.empty()) {
        ::setenv("DISPLAY", saved.c_str(), 1);
    }
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(read_bytes(shown), read_bytes(reference));
}

// A malformed part: one line, exit 2, no image.
TEST_F(RenderCli, BadPartExitsTwo) {
    write_file(dir_ / "bad.sdf.json",
               R"({"version": 1, "voxel_size": 0.5, "bounds": [[0, 0, 0], [4, 4, 4]],
                   "shape": {"teapot": {}}})");
    const fs::path out = dir_ / "bad.png";
    const RunResult r =
        run_voxfield({"render", (dir_ / "bad.sdf.json").string(), "-o", out.string()}, io_);
    EXPECT_EQ(r.code, 2) << describe(r);
    EXPECT_EQ(split_lines(r.err).size(), 1u) << describe(r);
    EXPECT_FALSE(fs::exists(out));
}

// A mixed scene (.scene.json): parts traced on their surface beside .vox models' cubes (`view`
// shows the same frame), and `generate` reads the same world; a malformed scene is one line,
// exit 2, no image.
TEST_F(RenderCli, MixedScenesRenderAndGenerate) {
    const fs::path scene = fs::path(VOXFIELD_DATA_DIR) / "scenes" / "workshop.scene.json";
    const fs::path out = dir_ / "scene.png";
    RunResult r = run_voxfield(
        {"render", scene.string(), "-o", out.string(), "--width", "64", "--height", "48"}, io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_TRUE(fs::exists(out));
    EXPECT_NE(r.out.find("implicit: "), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("128x88x196"), std::string::npos) << r.out;
    // view's headless frame: the same default camera and the same surfaces.
    const fs::path shown = dir_ / "view.png";
    const char* display = std::getenv("DISPLAY");
    const std::string saved = display ? display : "";
    ::unsetenv("DISPLAY");
    r = run_voxfield({"view", scene.string(), "--shading", "flat", "--width", "64", "--height",
                      "48", "--fallback-png", shown.string()},
                     io_);
    if (!saved.empty()) {
        ::setenv("DISPLAY", saved.c_str(), 1);
    }
    ASSERT_EQ(r.code, 0) << describe(r);
    const fs::path flat = dir_ / "flat.png";
    r = run_voxfield({"render", scene.string(), "-o", flat.string(), "--width", "64", "--height",
                      "48", "--shading", "flat"},
                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(read_bytes(shown), read_bytes(flat));
    const fs::path field = dir_ / "scene.npy";
    r = run_voxfield({"generate", scene.string(), "-o", field.string()}, io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_TRUE(fs::exists(field));

    write_file(dir_ / "bad.scene.json",
               R"({"version": 1, "voxel_size": 0.5, "items": [{"vox": "nowhere.vox"}]})");
    const fs::path bad = dir_ / "bad.png";
    r = run_voxfield({"render", (dir_ / "bad.scene.json").string(), "-o", bad.string()}, io_);
    EXPECT_EQ(r.code, 2) << describe(r);
    EXPECT_EQ(split_lines(r.err).size(), 1u) << describe(r);
    EXPECT_NE(r.err.find("items[0]"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(bad));
}

TEST_F(RenderCli, HelpListsEveryOption) {
    const RunResult r = run_voxfield({"render", "--help"}, io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    for (const char* opt : {"--width", "--height", "--camera", "--target", "--fov", "--shading",
                            "--sky", "--device", "--stats", "--output", "--field", "--metric"}) {
        EXPECT_NE(r.out.find(opt), std::string::npos) << opt;
    }
}

}  // namespace
}  // namespace voxfield::test
