// Mixed scenes (.scene.json): .vox models and .sdf.json parts placed in one world. The world
// equals an independent placement (each model voxel at translate / h, each part's voxel solid
// where its own tape is < 0 at the voxel's centre less the translation, inside the part's
// bounds, a .vox voxel winning), and malformed scenes are one-line InputErrors.
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <string>
#include <vector>

#include "test_util.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/scene_file.hpp"
#include "voxfield/core/sdf.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield::scene {
namespace {

namespace fs = std::filesystem;

void write_text(const fs::path& p, const std::string& text) {
    std::ofstream(p) << text;
}

// A 3x2x4 model with two colours and a hole.
World small_model() {
    World w(Dims{3, 2, 4});
    for (std::uint32_t z = 0; z < 4; ++z) {
        for (std::uint32_t y = 0; y < 2; ++y) {
            for (std::uint32_t x = 0; x < 3; ++x) {
                w.set(x, y, z, static_cast<std::uint8_t>((x + z) % 3 == 0 ? 0 : 5 + y));
            }
        }
    }
    return w;
}

constexpr const char* kPart =
    R"({"version": 1, "voxel_size": 0.3, "bounds": [[-1, -1, -1], [1, 1, 1]],
    "shape": {"union": [{"sphere": {"center": [0, 0, 0], "radius": 0.8}, "material": 3},
                        {"plane": {"normal": [0, 1, 0], "offset": -0.5}, "material": 7}]}})";

class SceneFile : public ::testing::Test {
  protected:
    void SetUp() override {
        write_vox(dir_.path() / "model.vox", small_model(), Palette());
        write_text(dir_.path() / "part.sdf.json", kPart);
    }
    fs::path scene(const std::string& text) {
        const fs::path p = dir_.path() / "s.scene.json";
        write_text(p, text);
        return p;
    }
    test::TempDir dir_;
};

TEST_F(SceneFile, RecognisesItsName) {
    EXPECT_TRUE(is_scene_path("a/b.scene.json"));
    EXPECT_TRUE(is_scene_path("B.SCENE.JSON"));
    EXPECT_FALSE(is_scene_path(".scene.json"));
    EXPECT_FALSE(is_scene_path("b.sdf.json"));
    EXPECT_FALSE(is_scene_path("b.json"));
}

TEST_F(SceneFile, PlacesModelsAndPartsInOneGrid) {
    const double h = 0.25;
    // The model moves by [1.5, -0.25, 2.0]: whole voxels (6, -1, 8).
    const std::array<double, 3> tp{0.4, 0.1, -0.3};
    for (const bool override_material : {false, true}) {
        const Scene s = load_scene(scene(
            R"({"version": 1, "voxel_size": 0.25, "items": [
                 {"sdf": "part.sdf.json", "translate": [0.4, 0.1, -0.3])" +
            std::string(override_material ? R"(, "material": 9)" : "") + R"(},
                 {"vox": "model.vox", "translate": [1.5, -0.25, 2.0]}]})"));
        ASSERT_TRUE(s.part);
        EXPECT_EQ(s.parts, 1u);
        ASSERT_EQ(s.vox.size(), 1u);
        // The grid: the cells around the part's moved bounds and the model's box.
        const std::array<std::int64_t, 3> lo{
            static_cast<std::int64_t>(std::floor((-1 + tp[0]) / h)),
            static_cast<std::int64_t>(std::floor((-1 + tp[1]) / h)),
            static_cast<std::int64_t>(std::floor((-1 + tp[2]) / h))};
        const std::array<std::int64_t, 3> hi{
            std::max<std::int64_t>(static_cast<std::int64_t>(std::ceil((1 + tp[0]) / h)), 6 + 3),
            std::max<std::int64_t>(static_cast<std::int64_t>(std::ceil((1 + tp[1]) / h)), -1 + 2),
            std::max<std::int64_t>(static_cast<std::int64_t>(std::ceil((1 + tp[2]) / h)), 8 + 4)};
        EXPECT_EQ(s.origin, lo);
        EXPECT_EQ(s.dims, (Dims{std::uint32_t(hi[0] - lo[0]), std::uint32_t(hi[1] - lo[1]),
                                std::uint32_t(hi[2] - lo[2])}));
        const sdf::Part part = sdf::parse_part(kPart, "part");
        const World model = small_model();
        const World w = s.world("scene");
        ASSERT_EQ(w.dims(), s.dims);
        std::size_t from_part = 0, from_model = 0;
        for (std::uint32_t z = 0; z < s.dims.z; ++z) {
            for (std::uint32_t y = 0; y < s.dims.y; ++y) {
                for (std::uint32_t x = 0; x < s.dims.x; ++x) {
                    const std::int64_t cell[3] = {lo[0] + x, lo[1] + y, lo[2] + z};
                    std::uint8_t want = 0;
                    const std::int64_t m[3] = {cell[0] - 6, cell[1] + 1, cell[2] - 8};
                    if (m[0] >= 0 && m[0] < 3 && m[1] >= 0 && m[1] < 2 && m[2] >= 0 && m[2] < 4) {
                        want =
                            model.at(std::uint32_t(m[0]), std::uint32_t(m[1]), std::uint32_t(m[2]));
                        from_model += want != 0;
                    }
                    if (want == 0) {
                        // The part's own coordinates of the voxel's centre.
                        double p[3];
                        bool inside_bounds = true;
                        for (int a = 0; a < 3; ++a) {
                            p[a] = (double(cell[a]) + 0.5) * h - tp[a];
                            inside_bounds = inside_bounds && p[a] > -1 + 1e-6 && p[a] < 1 - 1e-6;
                        }
                        const sdf::ValueMaterial vm = sdf::evaluate_material(
                            part.tape, {float(p[0]), float(p[1]), float(p[2])});
                        if (inside_bounds && vm.value < 0) {
                            want = override_material ? 9 : vm.material;
                            ++from_part;
                        }
                    }
                    // The bounds' planes themselves (within 1e-6) are not tested: the scene
                    // clips by a box evaluated in float.
                    const bool on_bound = [&] {
                        for (int a = 0; a < 3; ++a) {
                            const double q = (double(cell[a]) + 0.5) * h - tp[a];
                            if (std::abs(std::abs(q) - 1) < 1e-3) {
                                return true;
                            }
                        }
                        return false;
                    }();
                    if (!on_bound) {
                        EXPECT_EQ(int(w.at(x, y, z)), int(want)) << x << "," << y << "," << z;
                    }
                }
            }
        }
        EXPECT_GT(from_part, 100u);
        EXPECT_GT(from_model, 10u);
        // load_world reads the same world.
        EXPECT_EQ(load_world(dir_.path() / "s.scene.json").world.voxels(), w.voxels());
    }
}

TEST_F(SceneFile, VoxOnlyScenesHaveNoPart) {
    const Scene s =
        load_scene(scene(R"({"version": 1, "voxel_size": 2, "items": [{"vox": "model.vox"},
                 {"vox": "model.vox", "translate": [10, 0, 0]}]})"));
    EXPECT_FALSE(s.part);
    EXPECT_EQ(s.dims, (Dims{8, 2, 4}));
    const World w = s.world("scene");
    EXPECT_EQ(w.solid_count(), 2 * small_model().solid_count());
}

TEST_F(SceneFile, MalformedScenesAreOneLineErrors) {
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"{", "not valid JSON"},
        {"[]", "expected an object"},
        {R"({"voxel_size": 1, "items": [{"vox": "model.vox"}]})", "missing field 'version'"},
        {R"({"version": 2, "voxel_size": 1, "items": [{"vox": "model.vox"}]})",
         "unsupported version"},
        {R"({"version": 1, "items": [{"vox": "model.vox"}]})", "missing field 'voxel_size'"},
        {R"({"version": 1, "voxel_size": 0, "items": [{"vox": "model.vox"}]})",
         "voxel_size: must be a positive number"},
        {R"({"version": 1, "voxel_size": 1, "items": []})", "non-empty array"},
        {R"({"version": 1, "voxel_size": 1})", "missing field 'items'"},
        {R"({"version": 1, "voxel_size": 1, "items": [{"vox": "model.vox"}], "lights": 1})",
         "unknown field 'lights'"},
        {R"({"version": 1, "voxel_size": 1, "items": [{"vox": "model.vox", "sdf": "part.sdf.json"}]})",
         "items[0]: an item names one file"},
        {R"({"version": 1, "voxel_size": 1, "items": [{"translate": [0, 0, 0]}]})",
         "items[0]: an item names one file"},
        {R"({"version": 1, "voxel_size": 1, "items": [{"vox": "model.vox", "translate": [1, 2]}]})",
         "items[0].translate: expected [x, y, z]"},
        {R"({"version": 1, "voxel_size": 1, "items": [{"vox": "model.vox", "translate": [0.5, 0, 0]}]})",
         "not a multiple of voxel_size"},
        {R"({"version": 1, "voxel_size": 1, "items": [{"vox": "model.vox", "material": 2}]})",
         "unknown field 'material'"},
        {R"({"version": 1, "voxel_size": 1, "items": [{"sdf": "part.sdf.json", "material": 256}]})",
         "items[0].material: must be an integer 1..255"},
        {R"({"version": 1, "voxel_size": 1, "items": [{"sdf": "part.sdf.json", "scale": 2}]})",
         "unknown field 'scale'"},
        {R"({"version": 1, "voxel_size": 1, "items": [{"vox": "missing.vox"}]})", "items[0]: '"},
        {R"({"version": 1, "voxel_size": 1, "items": [{"sdf": 3}]})",
         "items[0].sdf: expected a file name"},
        {R"({"version": 1, "voxel_size": 1, "items": [{"vox": "model.vox"},
             {"sdf": "bad.sdf.json"}]})",
         "items[1]: "},
        {R"({"version": 1, "voxel_size": 0.001, "items": [{"vox": "model.vox"},
             {"vox": "model.vox", "translate": [2000, 2000, 2000]}]})",
         "at most 2^31"},
        {R"({"version": 1, "voxel_size": 1, "items": [{"sdf": "deep.sdf.json"}]})",
         "a scene wraps a part in 3 more"},
    };
    write_text(dir_.path() / "bad.sdf.json",
               R"({"version": 1, "voxel_size": 1, "bounds": [[0, 0, 0], [1, 1, 1]],
                   "shape": {"teapot": {}}})");
    // 30 nested shells: valid alone, too deep in a scene.
    std::string deep = R"({"sphere": {"center": [0, 0, 0], "radius": 0.5}})";
    for (int i = 0; i < 30; ++i) {
        deep = R"({"shell": {"thickness": 0.01, "of": )" + deep + "}}";
    }
    write_text(
        dir_.path() / "deep.sdf.json",
        R"({"version": 1, "voxel_size": 0.1, "bounds": [[-1, -1, -1], [1, 1, 1]], "shape": )" +
            deep + "}");
    for (const auto& [text, want] : cases) {
        const fs::path p = scene(text);
        try {
            load_scene(p);
            ADD_FAILURE() << "accepted: " << text;
        } catch (const InputError& e) {
            const std::string msg = e.what();
            EXPECT_NE(msg.find(want), std::string::npos) << msg << "\n(for " << text << ")";
            EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
            EXPECT_EQ(msg.rfind(p.string(), 0), 0u) << msg;  // names the scene first
        }
    }
}

}  // namespace
}  // namespace voxfield::scene
