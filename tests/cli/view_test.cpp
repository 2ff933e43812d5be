// `voxfield view` end to end: the no-display path, the headless benchmark, and a smoke test
// of the window under Xvfb + lavapipe (skipped, with CTest's skip, only without xvfb-run).
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <regex>
#include <string>
#include <utility>
#include <vector>

#include "cli_test_util.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/world.hpp"

#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_STATIC
#include <stb/stb_image.h>

namespace voxfield::test {
namespace {

// The pixels of the PNG at `path` that are not black; 0 (with a failure) when it cannot be read
// or is not width x height.
std::size_t non_black_pixels(const fs::path& path, int width, int height) {
    int iw = 0, ih = 0, channels = 0;
    unsigned char* px = stbi_load(path.c_str(), &iw, &ih, &channels, 4);
    if (px == nullptr || iw != width || ih != height) {
        ADD_FAILURE() << path << ": not a " << width << "x" << height << " PNG (" << iw << "x" << ih
                      << ")";
        stbi_image_free(px);
        return 0;
    }
    std::size_t n = 0;
    for (int i = 0; i < iw * ih; ++i) {
        n += (px[4 * i] != 0 || px[4 * i + 1] != 0 || px[4 * i + 2] != 0) ? 1 : 0;
    }
    stbi_image_free(px);
    return n;
}

class ViewTest : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = make_temp_dir("voxfield_view_test");
        io_ = make_temp_dir("voxfield_view_io");
        for (const char* v : {"DISPLAY", "WAYLAND_DISPLAY"}) {
            const char* old = std::getenv(v);
            saved_.push_back(old ? std::optional<std::string>(old) : std::nullopt);
        }
        ::unsetenv("DISPLAY");
        ::unsetenv("WAYLAND_DISPLAY");
        ::setenv("VOXFIELD_DEVICE", "cpu", 1);
        // `--validate` for every run: the Vulkan validation layer's messages (synchronisation
        // validation included) are printed and any makes the viewer exit 1.
        ::setenv("VOXFIELD_VALIDATE", "1", 1);
    }
    void TearDown() override {
        const char* names[] = {"DISPLAY", "WAYLAND_DISPLAY"};
        for (std::size_t i = 0; i < 2; ++i) {
            if (saved_[i]) {
                ::setenv(names[i], saved_[i]->c_str(), 1);
            }
        }
        fs::remove_all(dir_);
        fs::remove_all(io_);
    }
    void check_shot_and_field(const fs::path& world, const fs::path& edits,
                              const std::string& format, const fs::path& shot,
                              const fs::path& field);
    fs::path dir_, io_;
    std::vector<std::optional<std::string>> saved_;
};

TEST_F(ViewTest, NoDisplaySaysSoInOneLineAndSuggestsRender) {
    const RunResult r = run_voxfield({"view", "--world", "16"}, io_);
    EXPECT_EQ(r.code, 2) << describe(r);
    const auto lines = split_lines(r.err);
    ASSERT_EQ(lines.size(), 1u) << describe(r);
    EXPECT_NE(lines[0].find("no display"), std::string::npos) << lines[0];
    EXPECT_NE(lines[0].find("voxfield render"), std::string::npos) << lines[0];
    EXPECT_TRUE(r.out.empty()) << describe(r);
}

TEST_F(ViewTest, UnreachableDisplayIsNoDisplayToo) {
    ::setenv("DISPLAY", ":4711", 1);  // no X server there
    const RunResult r = run_voxfield({"view", "--world", "16"}, io_);
    ::unsetenv("DISPLAY");
    EXPECT_EQ(r.code, 2) << describe(r);
    const auto lines = split_lines(r.err);
    ASSERT_EQ(lines.size(), 1u) << describe(r);
    EXPECT_NE(lines[0].find("no display"), std::string::npos) << lines[0];
    EXPECT_NE(lines[0].find("voxfield render"), std::string::npos) << lines[0];
}

TEST_F(ViewTest, FallbackPngRendersOneFrameHeadless) {
    const fs::path shot = dir_ / "fallback.png";
    const RunResult r =
        run_voxfield({"view", "--world", "24", "--scene", "terrain", "--shading", "flat", "--width",
                      "80", "--height", "60", "--fallback-png", shot.string()},
                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.out.find("no display"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("screenshot " + shot.string()), std::string::npos) << r.out;
    // Flat shading, black sky: lit pixels are voxels.
    EXPECT_GT(non_black_pixels(shot, 80, 60), 80u * 60 / 20) << "the fallback image is all sky";
}

TEST_F(ViewTest, FirstFrameEqualsRender) {
    // The viewer's pipeline (IncrementalField, the render field written in place) and
    // `render`'s (the exact generator) show a model identically from the same default camera.
    const fs::path model = fs::path(VOXFIELD_DATA_DIR) / "vox" / "chr_army1.vox";
    const fs::path viewed = dir_ / "viewed.png", rendered = dir_ / "rendered.png";
    RunResult r = run_voxfield({"view", model.string(), "--width", "120", "--height", "90",
                                "--fallback-png", viewed.string()},
                               io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    r = run_voxfield({"render", model.string(), "-o", rendered.string(), "--width", "120",
                      "--height", "90", "--shading", "lit"},
                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(read_text(viewed), read_text(rendered)) << "the PNGs differ";
}

TEST_F(ViewTest, BadUsageIsCheckedFirst) {
    RunResult r = run_voxfield({"view", "--world", "16", "--dims", "4,4,4"}, io_);
    EXPECT_EQ(r.code, 2) << describe(r);
    EXPECT_NE(r.err.find("not both"), std::string::npos) << describe(r);
    r = run_voxfield({"view", "--algorithm", "nope"}, io_);
    EXPECT_EQ(r.code, 2) << describe(r);
    r = run_voxfield({"view", "--edits", (dir_ / "missing.txt").string()}, io_);
    EXPECT_EQ(r.code, 2) << describe(r);
    // A scaled field is drawn through voxel steps (its distances divided by the largest
    // spacing, rounded down): the same first frame as the unit field's.
    const fs::path spaced = dir_ / "s.png", unit = dir_ / "u.png";
    for (const auto& [png, spacing] : {std::pair{spaced, "2,1,0.5"}, std::pair{unit, "1,1,1"}}) {
        r = run_voxfield({"view", "--world", "16", "--spacing", spacing, "--shading", "flat",
                          "--width", "48", "--height", "32", "--fallback-png", png.string()},
                         io_);
        EXPECT_EQ(r.code, 0) << describe(r);
    }
    EXPECT_EQ(read_text(spaced), read_text(unit));
}

TEST_F(ViewTest, HeadlessBenchmarkIsReproducibleAndRecorded) {
    const fs::path json = dir_ / "b.json", csv = dir_ / "b.csv";
    const RunResult r =
        run_voxfield({"view", "--world", "32", "--benchmark", "--seed", "7", "--interval-ms", "50",
                      "--duration-s", "1", "--width", "96", "--height", "64", "--json",
                      json.string(), "--csv", csv.string()},
                     io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.out.find("headless"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("95% CI"), std::string::npos) << r.out;
    const auto j = nlohmann::json::parse(read_text(json));
    EXPECT_EQ(j["seed"], 7);
    EXPECT_EQ(j["present"], "headless");
    const auto& frames = j["frames"];
    ASSERT_GT(frames.size(), 2u);
    std::size_t edits = 0;
    for (const auto& f : frames) {
        EXPECT_GE(f["frame_ms"].get<double>(), f["update_ms"].get<double>());
        edits += f["edit"].get<bool>() ? 1 : 0;
    }
    EXPECT_GE(edits, 1u);
    EXPECT_EQ(j["summary"]["field_update"]["n"], edits);
    EXPECT_EQ(j["summary"]["frame"]["n"], frames.size());
    EXPECT_EQ(split_lines(read_text(csv)).size(), frames.size() + 1);
}

TEST_F(ViewTest, BenchmarkEditsLeaveTheFieldAFreshGenerationWouldGive) {
    // The viewer's loop (random spheres through IncrementalField, the render field written in
    // place) ends with the field `generate` computes from the final world.
    for (const std::vector<std::string>& algorithm :
         {std::vector<std::string>{"--algorithm", "exact"},
          std::vector<std::string>{"--algorithm", "lod", "--chunk", "8"}}) {
        SCOPED_TRACE(algorithm[1]);
        const fs::path world = dir_ / "w.npy", field = dir_ / "f.npy", fresh = dir_ / "g.npy";
        std::vector<std::string> args = {"view",
                                         "--world",
                                         "32",
                                         "--benchmark",
                                         "--seed",
                                         "3",
                                         "--interval-ms",
                                         "10",
                                         "--duration-s",
                                         "1.5",
                                         "--width",
                                         "32",
                                         "--height",
                                         "24",
                                         "--world-output",
                                         world.string(),
                                         "--field-output",
                                         field.string()};
        args.insert(args.end(), algorithm.begin(), algorithm.end());
        RunResult r = run_voxfield(args, io_);
        ASSERT_EQ(r.code, 0) << describe(r);
        std::smatch m;
        ASSERT_TRUE(std::regex_search(r.out, m, std::regex(" (\\d+) edits,"))) << r.out;
        EXPECT_GE(std::stoi(m[1]), 1) << r.out;
        std::vector<std::string> gen = {"generate", world.string(), "-o", fresh.string()};
        gen.insert(gen.end(), algorithm.begin(), algorithm.end());
        r = run_voxfield(gen, io_);
        ASSERT_EQ(r.code, 0) << describe(r);
        const auto got = read_npy(field), want = read_npy(fresh);
        EXPECT_EQ(got.dims, want.dims);
        EXPECT_TRUE(got.data == want.data) << "the viewer's field differs from a fresh one";
    }
}

TEST_F(ViewTest, SimulateStepsTheSandEveryFrameAndKeepsTheFieldExact) {
    // `--simulate` on the sand scene, no edits (an interval past the run): every frame steps
    // the automaton; the final world conserves sand and water, and the final field is the one
    // `generate` computes from it.
    const fs::path json = dir_ / "s.json", world = dir_ / "w.npy", field = dir_ / "f.npy",
                   fresh = dir_ / "g.npy";
    RunResult r = run_voxfield({"view",
                                "--world",
                                "32",
                                "--scene",
                                "sand",
                                "--simulate",
                                "--benchmark",
                                "--seed",
                                "5",
                                "--interval-ms",
                                "100000",
                                "--duration-s",
                                "1",
                                "--width",
                                "48",
                                "--height",
                                "32",
                                "--json",
                                json.string(),
                                "--world-output",
                                world.string(),
                                "--field-output",
                                field.string()},
                               io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.out.find("sand simulation (device)"), std::string::npos) << r.out;
    const auto j = nlohmann::json::parse(read_text(json));
    EXPECT_TRUE(j["simulate"].get<bool>());
    const auto& frames = j["frames"];
    ASSERT_GT(frames.size(), 2u);
    std::size_t moved = 0;
    for (const auto& f : frames) {
        ASSERT_FALSE(f["simulate_ms"].is_null());
        moved += f["sand_voxels_changed"].get<std::size_t>();
    }
    EXPECT_GT(moved, 0u);
    EXPECT_EQ(j["summary"]["simulate"]["n"], frames.size());
    const World start = make_scene("sand", Dims{32, 32, 32}, 6683787);
    const NpyArray end = read_npy(world);
    for (const std::uint8_t material : {std::uint8_t{2}, std::uint8_t{3}}) {
        EXPECT_EQ(std::count(end.data.begin(), end.data.end(), material),
                  std::count(start.voxels().begin(), start.voxels().end(), material))
            << "material " << int{material};
    }
    r = run_voxfield({"generate", world.string(), "-o", fresh.string()}, io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_TRUE(read_npy(field).data == read_npy(fresh).data)
        << "the viewer's field differs from a fresh one";
}

bool have_xvfb() {
    return std::system("command -v xvfb-run >/dev/null 2>&1") == 0;
}

// Runs `voxfield ARGS` under a fresh Xvfb server; returns the exit code, output in `log`.
int run_under_xvfb(const std::vector<std::string>& args, const fs::path& log,
                   const std::string& screen = "640x480x24") {
    std::string cmd = "xvfb-run -a -s '-screen 0 " + screen + "' '" + kExe.string() + "'";
    for (const auto& a : args) {
        cmd += " '" + a + "'";
    }
    cmd += " >'" + log.string() + "' 2>&1";
    const int status = std::system(cmd.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : 128;
}

TEST_F(ViewTest, SmokeUnderXvfbShowsTheWorldAndFollowsEdits) {
    if (!have_xvfb()) {
        GTEST_SKIP() << "xvfb-run is not installed (setup.sh installs it)";
    }
    // A 40x24x40 world: a floor and a pillar, palette index 1 (white in MagicaVoxel's).
    World w(Dims{40, 24, 40});
    for (std::uint32_t z = 0; z < 40; ++z) {
        for (std::uint32_t x = 0; x < 40; ++x) {
            w.set(x, 0, z, 1);
        }
    }
    for (std::uint32_t y = 0; y < 12; ++y) {
        w.set(20, y, 20, 2);
    }
    const fs::path world = dir_ / "world.npy";
    const NpyArray a = npy_from_world(w);
    write_npy(world, a.type, a.dims, a.data);
    const fs::path edits = dir_ / "edits.txt";
    write_file(edits, "place sphere 10 6 10 4 3\nerase cube 30 0 30 3\npaint sphere 20 5 20 3 7\n");

    // The field kept on the OpenCL device in u16 (the default) and in packed32: both are
    // converted into the render field the ray marcher reads in place (sharing path 2 here).
    for (const std::string format : {"u16", "packed32"}) {
        SCOPED_TRACE(format);
        const fs::path shot = dir_ / ("shot_" + format + ".png");
        const fs::path field = dir_ / ("view_field_" + format + ".npy");
        const int code = run_under_xvfb(
            {"view", world.string(), "--frames", "6", "--edits", edits.string(), "--shading",
             "flat", "--width", "160", "--height", "120", "--format", format, "--screenshot",
             shot.string(), "--field-output", field.string()},
            io_ / "xvfb.log");
        const std::string log = read_text(io_ / "xvfb.log");
        ASSERT_EQ(code, 0) << log;
        EXPECT_NE(log.find("window:"), std::string::npos) << log;
        EXPECT_NE(log.find("sharing: path 2"), std::string::npos) << log;
        check_shot_and_field(world, edits, format, shot, field);
    }
}

TEST_F(ViewTest, WindowShowsTheRayMarchedImage) {
    if (!have_xvfb()) {
        GTEST_SKIP() << "xvfb-run is not installed (setup.sh installs it)";
    }
    // What the swapchain showed (ray-marched on the one device that also presents, which
    // lavapipe under Xvfb can: auto and gpu; or through the host) equals the ray-marched
    // image, away from the overlay (its panel is at the top left, the crosshair and brush
    // preview at the centre). Lit shading: the sky gradient and shaded voxels have R != B, so
    // a byte-order slip shows.
    for (const std::string present : {"auto", "gpu", "host"}) {
        SCOPED_TRACE(present);
        const fs::path shot = dir_ / "marched.png", window = dir_ / "window.png";
        const int code =
            run_under_xvfb({"view", "--world", "48", "--scene", "terrain", "--frames", "1",
                            "--width", "1024", "--height", "768", "--screenshot", shot.string(),
                            "--window-screenshot", window.string(), "--present", present},
                           io_ / "xvfb.log", "1024x768x24");
        const std::string log = read_text(io_ / "xvfb.log");
        ASSERT_EQ(code, 0) << log;
        EXPECT_NE(log.find(present == "host" ? "through the host" : "window:  "), std::string::npos)
            << log;
        if (present != "host") {
            EXPECT_NE(log.find("one device: frames stay on the GPU"), std::string::npos) << log;
        }
        int w1 = 0, h1 = 0, w2 = 0, h2 = 0, c = 0;
        unsigned char* a = stbi_load(shot.c_str(), &w1, &h1, &c, 4);
        unsigned char* b = stbi_load(window.c_str(), &w2, &h2, &c, 4);
        ASSERT_NE(a, nullptr);
        ASSERT_NE(b, nullptr);
        EXPECT_EQ(w1, 1024);
        EXPECT_EQ(h1, 768);
        EXPECT_EQ(w2, w1);
        EXPECT_EQ(h2, h1);
        std::size_t compared = 0, differ = 0, coloured = 0;
        // Right of the overlay (top left; even the full panel, F2, is about 640 pixels wide and
        // 440 high) and below the centre.
        for (int y = h1 * 5 / 8; y < h1 && w2 == w1 && h2 == h1; ++y) {
            for (int x = w1 * 11 / 16; x < w1; ++x) {
                const int i = 4 * (y * w1 + x);
                ++compared;
                differ += (a[i] != b[i] || a[i + 1] != b[i + 1] || a[i + 2] != b[i + 2]) ? 1 : 0;
                coloured += a[i] != a[i + 2] ? 1 : 0;
            }
        }
        stbi_image_free(a);
        stbi_image_free(b);
        EXPECT_GT(compared, 0u);
        EXPECT_EQ(differ, 0u) << "of " << compared << " pixels";
        EXPECT_GT(coloured, compared / 2)
            << "the compared region is grey: it cannot catch R/B swaps";
    }
}

TEST_F(ViewTest, OverlayShowsTheAlgorithmGiven) {
    if (!have_xvfb()) {
        GTEST_SKIP() << "xvfb-run is not installed (setup.sh installs it)";
    }
    // The overlay's algorithm list is in DESIGN §4 order, not the enum's: `--algorithm fim`
    // once showed (and "regenerate" switched to) fim-host. Every algorithm, under one server.
    const std::vector<std::string> algorithms = {
        "exact", "brute",    "brute-chunked", "fim", "fim-host",
        "jfa",   "jfa-host", "jfa-fim",       "lod", "monolithic"};
    std::string script;
    for (const std::string& a : algorithms) {
        script.append("'").append(kExe.string()).append("' view --world 16 --algorithm ");
        script.append(a).append(a == "exact" ? "" : " --chunk 8");
        script.append(" --frames 1 --width 64 --height 48 || exit 1; ");
    }
    const fs::path log = io_ / "xvfb.log";
    const std::string cmd = "xvfb-run -a -s '-screen 0 640x480x24' sh -c \"" + script + "\" >'" +
                            log.string() + "' 2>&1";
    const int status = std::system(cmd.c_str());
    const std::string out = read_text(log);
    ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << out;
    std::size_t at = 0;
    for (const std::string& a : algorithms) {
        const std::string want = "overlay: algorithm " + a + ", compact\n";
        const std::size_t found = out.find(want, at);
        EXPECT_NE(found, std::string::npos) << want << out;
        at = found == std::string::npos ? at : found + want.size();
    }
}

TEST_F(ViewTest, CompactOverlayCoversAtMost15PercentOfTheWindow) {
    if (!have_xvfb()) {
        GTEST_SKIP() << "xvfb-run is not installed (setup.sh installs it)";
    }
    // 1280x720: what the window showed differs from the ray-marched image only in the overlay
    // (the crosshair and brush preview aside, at the centre), whose bounding box must stay
    // within 15% of the window.
    const int w = 1280, h = 720;
    const fs::path shot = dir_ / "marched.png", window = dir_ / "window.png";
    const int code =
        run_under_xvfb({"view", "--world", "48", "--scene", "terrain", "--frames", "2", "--width",
                        std::to_string(w), "--height", std::to_string(h), "--screenshot",
                        shot.string(), "--window-screenshot", window.string()},
                       io_ / "xvfb.log", "1280x720x24");
    const std::string log = read_text(io_ / "xvfb.log");
    ASSERT_EQ(code, 0) << log;
    EXPECT_NE(log.find("overlay: algorithm exact, compact"), std::string::npos) << log;
    int w1 = 0, h1 = 0, w2 = 0, h2 = 0, c = 0;
    unsigned char* a = stbi_load(shot.c_str(), &w1, &h1, &c, 4);
    unsigned char* b = stbi_load(window.c_str(), &w2, &h2, &c, 4);
    ASSERT_NE(a, nullptr);
    ASSERT_NE(b, nullptr);
    ASSERT_TRUE(w1 == w && h1 == h && w2 == w && h2 == h)
        << w1 << "x" << h1 << ", " << w2 << "x" << h2;
    int x0 = w, y0 = h, x1 = -1, y1 = -1;
    for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
            if (std::abs(x - w / 2) < w / 8 && std::abs(y - h / 2) < h / 8) {
                continue;  // crosshair and brush preview
            }
            const int i = 4 * (y * w + x);
            if (a[i] != b[i] || a[i + 1] != b[i + 1] || a[i + 2] != b[i + 2]) {
                x0 = std::min(x0, x);
                y0 = std::min(y0, y);
                x1 = std::max(x1, x);
                y1 = std::max(y1, y);
            }
        }
    }
    stbi_image_free(a);
    stbi_image_free(b);
    ASSERT_GE(x1, 0) << "no overlay in the window";
    const double covered = double(x1 - x0 + 1) * double(y1 - y0 + 1) / (double(w) * h);
    EXPECT_LE(covered, 0.15) << "the overlay spans (" << x0 << ", " << y0 << ") - (" << x1 << ", "
                             << y1 << ")";
}

TEST_F(ViewTest, HelpListsValidateAndTheKeys) {
    const RunResult r = run_voxfield({"view", "--help"}, io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    for (const char* text : {"--validate", "VOXFIELD_VALIDATE", "F1", "F2", "compact overlay"}) {
        EXPECT_NE(r.out.find(text), std::string::npos) << text << '\n' << r.out;
    }
}

// The smoke test's checks for one format: the screenshot shows the world, the final field
// equals replay's for the same edits and differs from the unedited world's.
void ViewTest::check_shot_and_field(const fs::path& world, const fs::path& edits,
                                    const std::string& format, const fs::path& shot,
                                    const fs::path& field) {
    // The screenshot shows the world: flat shading, black sky, so lit pixels are voxels.
    EXPECT_GT(non_black_pixels(shot, 160, 120), 160u * 120 / 20) << "the screenshot is all sky";

    // The field after the edits equals `replay`'s and differs from the unedited world's.
    const fs::path replayed = dir_ / "replay_field.npy", before = dir_ / "before.npy";
    RunResult r = run_voxfield({"replay", edits.string(), "--input", world.string(), "--format",
                                format, "-o", replayed.string()},
                               io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    r = run_voxfield({"generate", world.string(), "--format", format, "-o", before.string()}, io_);
    ASSERT_EQ(r.code, 0) << describe(r);
    const auto got = read_npy(field), want = read_npy(replayed), old = read_npy(before);
    EXPECT_EQ(got.dims, want.dims);
    EXPECT_TRUE(got.data == want.data) << "view's field differs from replay's";
    EXPECT_FALSE(got.data == old.data) << "the edits did not change the field";
}

}  // namespace
}  // namespace voxfield::test
