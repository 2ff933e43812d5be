// `voxfield info`: dims, solid voxels, 64^3 tiles and 64-tree blocks against counts made here
// from the dense world, models and instances of .vox scenes, and bad input (exit 2, one line).
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "cli_test_util.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield::test {
namespace {

const fs::path kData = fs::path(VOXFIELD_DATA_DIR) / "vox";

class InfoTest : public ::testing::Test {
  protected:
    void SetUp() override { dir_ = make_temp_dir("voxfield_info"); }
    void TearDown() override { fs::remove_all(dir_); }
    nlohmann::json info_json(const fs::path& input, const std::vector<std::string>& extra = {}) {
        std::vector<std::string> args = {"info", input.string(), "--json"};
        args.insert(args.end(), extra.begin(), extra.end());
        const RunResult r = run_voxfield(args, dir_);
        EXPECT_EQ(r.code, 0) << describe(r);
        return nlohmann::json::parse(r.out);
    }
    fs::path dir_;
};

// The counts `info` reports, made here the plain way from a dense world.
struct Counts {
    std::uint64_t solid = 0, tiles = 0, blocks16 = 0, blocks4 = 0;
};

Counts count(const World& w) {
    std::set<std::uint64_t> tiles, b16, b4;
    const Dims d = w.dims();
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                if (w.at(x, y, z) != 0) {
                    const std::uint64_t t = ((z / 64) * 1000 + y / 64) * 1000 + x / 64;
                    tiles.insert(t);
                    b16.insert(t * 64 + ((z % 64) / 16 * 4 + (y % 64) / 16) * 4 + (x % 64) / 16);
                    b4.insert(t * 4096 + ((z % 64) / 4 * 16 + (y % 64) / 4) * 16 + (x % 64) / 4);
                }
            }
        }
    }
    return {w.solid_count(), tiles.size(), b16.size(), b4.size()};
}

void expect_counts(const nlohmann::json& j, const World& w) {
    const Counts c = count(w);
    const Dims d = w.dims();
    EXPECT_EQ(j["dims"], (nlohmann::json{d.x, d.y, d.z}));
    EXPECT_EQ(j["voxels"].get<std::uint64_t>(), d.count());
    EXPECT_EQ(j["solid_voxels"].get<std::uint64_t>(), c.solid);
    EXPECT_EQ(j["tiles"]["solid"].get<std::uint64_t>(), c.tiles);
    EXPECT_EQ(j["tiles"]["blocks16"].get<std::uint64_t>(), c.blocks16);
    EXPECT_EQ(j["tiles"]["blocks4"].get<std::uint64_t>(), c.blocks4);
    const std::uint64_t total =
        std::uint64_t{(d.x + 63) / 64} * ((d.y + 63) / 64) * ((d.z + 63) / 64);
    EXPECT_EQ(j["tiles"]["total"].get<std::uint64_t>(), total);
    EXPECT_GE(j["tiles"]["stored"].get<std::uint64_t>(), c.tiles);
    EXPECT_LE(j["tiles"]["stored"].get<std::uint64_t>(), total);
}

TEST_F(InfoTest, ShippedModels) {
    for (const char* file :
         {"chr_army1.vox", "veh_car1.vox", "obj_house4.vox", "scene_store8.vox"}) {
        SCOPED_TRACE(file);
        const nlohmann::json j = info_json(kData / file);
        const VoxModel m = read_vox(kData / file);
        expect_counts(j, m.world);
        EXPECT_EQ(j["kind"], "vox");
        EXPECT_EQ(j["models"], 1);
        EXPECT_EQ(j["instances"], 1);
        EXPECT_EQ(j["scene_graph"], false);
        EXPECT_EQ(j["memory"]["format"], "u16");
        EXPECT_EQ(j["memory"]["dense_bytes"].get<std::uint64_t>(), m.world.size() * 3);
    }
}

TEST_F(InfoTest, NpyAcrossTileEdgesAndFormats) {
    // 130 x 70 x 65: tiles cut by the world's edge on every axis; clustered solids.
    World w(Dims{130, 70, 65});
    std::mt19937_64 rng(5);
    for (int k = 0; k < 300; ++k) {
        const auto x = static_cast<std::uint32_t>(rng() % 130);
        const auto y = static_cast<std::uint32_t>(rng() % 70);
        const auto z = static_cast<std::uint32_t>(rng() % 65);
        w.set(x, y, z, static_cast<std::uint8_t>(1 + rng() % 255));
        if (x < 64 && y < 64 && z < 64) {
            w.set(x, y, z, 0);  // leave tile (0, 0, 0) empty
        }
    }
    write_npy(dir_ / "w.npy", NpyType::u8, w.dims(), w.voxels());
    const nlohmann::json j = info_json(dir_ / "w.npy", {"--format", "f64", "--max-distance", "3"});
    expect_counts(j, w);
    EXPECT_EQ(j["kind"], "npy");
    EXPECT_EQ(j["memory"]["dense_bytes"].get<std::uint64_t>(), w.size() * 9);
    EXPECT_EQ(j["memory"]["max_distance"].get<double>(), 3.0);
    EXPECT_FALSE(j.contains("models"));
    // Text form: the same numbers on labelled lines.
    const RunResult r = run_voxfield({"info", (dir_ / "w.npy").string()}, dir_);
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.out.find("dims: 130x70x65 (591500 voxels)"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("solid voxels: " + std::to_string(w.solid_count())), std::string::npos);
    EXPECT_NE(r.out.find("tiles of 64^3: " + std::to_string(count(w).tiles) + " of 12 hold"),
              std::string::npos)
        << r.out;
}

// A two-instance scene: model 0 (2x2x2) at the origin and rotated 90 degrees about z at
// (10, 0, 0), as MagicaVoxel writes them (root transform, group, transform + shape each).
std::string two_instance_scene(bool cycle) {
    std::string b;
    auto u32 = [](std::string& s, std::uint32_t v) {
        for (int k = 0; k < 4; ++k) {
            s += static_cast<char>((v >> (8 * k)) & 0xFF);
        }
    };
    auto text = [&](std::string& s, const std::string& t) {
        u32(s, static_cast<std::uint32_t>(t.size()));
        s += t;
    };
    auto chunk = [&](const std::string& id, const std::string& content) {
        b += id;
        u32(b, static_cast<std::uint32_t>(content.size()));
        u32(b, 0);
        b += content;
    };
    std::string c;
    u32(c, 2);
    u32(c, 2);
    u32(c, 2);
    chunk("SIZE", c);
    c.clear();
    u32(c, 2);
    c += std::string("\0\0\0\x05\x01\x01\x01\x06", 8);
    chunk("XYZI", c);
    auto trn = [&](std::uint32_t id, std::uint32_t child, const std::string& r,
                   const std::string& t) {
        std::string n;
        u32(n, id);
        u32(n, 0);
        u32(n, child);
        u32(n, 0xFFFFFFFFu);
        u32(n, 0);
        u32(n, 1);
        u32(n, r.empty() ? 1 : 2);
        text(n, "_t");
        text(n, t);
        if (!r.empty()) {
            text(n, "_r");
            text(n, r);
        }
        chunk("nTRN", n);
    };
    trn(0, 1, "", "0 0 0");
    std::string g;
    u32(g, 1);
    u32(g, 0);
    u32(g, 2);
    u32(g, 2);
    u32(g, cycle ? 0 : 4);
    chunk("nGRP", g);
    trn(2, 3, "", "0 0 0");
    trn(4, 3, "17", "10 0 0");
    std::string s;
    u32(s, 3);
    u32(s, 0);
    u32(s, 1);
    u32(s, 0);
    u32(s, 0);
    chunk("nSHP", s);
    std::string out = "VOX ";
    u32(out, 150);
    out += "MAIN";
    u32(out, 0);
    u32(out, static_cast<std::uint32_t>(b.size()));
    return out + b;
}

TEST_F(InfoTest, SceneGraphModelsAndInstances) {
    write_file(dir_ / "scene.vox", two_instance_scene(false));
    const nlohmann::json j = info_json(dir_ / "scene.vox");
    EXPECT_EQ(j["scene_graph"], true);
    EXPECT_EQ(j["models"], 1);
    EXPECT_EQ(j["instances"], 2);
    EXPECT_EQ(j["hidden_instances"], 0);
    EXPECT_EQ(j["solid_voxels"], 4);
    // x from -1 (pivot 1) to 10 + 1 - 1: 12 wide; the rotation keeps z.
    EXPECT_EQ(j["dims"], (nlohmann::json{12, 2, 2}));
    expect_counts(j, read_vox(dir_ / "scene.vox").world);
}

TEST_F(InfoTest, BadInputIsOneLineExit2AndNoOutput) {
    write_file(dir_ / "cycle.vox", two_instance_scene(true));
    const fs::path work = make_temp_dir("voxfield_info_work");
    for (const std::vector<std::string>& args :
         {std::vector<std::string>{"info", (dir_ / "cycle.vox").string()},
          std::vector<std::string>{"generate", (dir_ / "cycle.vox").string(), "-o",
                                   (work / "f.npy").string()},
          std::vector<std::string>{"info", (dir_ / "none.vox").string()},
          std::vector<std::string>{"info", (kData / "ATTRIBUTION.md").string()},
          std::vector<std::string>{"info", (kData / "chr_army1.vox").string(), "--max-distance",
                                   "0"},
          std::vector<std::string>{"info", (kData / "chr_army1.vox").string(), "--format", "u7"}}) {
        SCOPED_TRACE(args[1]);
        const RunResult r = run_voxfield(args, dir_);
        EXPECT_EQ(r.code, 2) << describe(r);
        EXPECT_EQ(split_lines(r.err).size(), 1u) << r.err;
        EXPECT_TRUE(r.out.empty()) << r.out;
    }
    const RunResult c = run_voxfield({"info", (dir_ / "cycle.vox").string()}, dir_);
    EXPECT_NE(c.err.find("node cycle: 0 -> 1 -> 0"), std::string::npos) << c.err;
    EXPECT_TRUE(list_dir(work).empty());
    fs::remove_all(work);
}

TEST_F(InfoTest, Help) {
    const RunResult r = run_voxfield({"info", "--help"}, dir_);
    EXPECT_EQ(r.code, 0);
    for (const char* part : {"--json", "--grid", "--format", "--max-distance", ".vdb"}) {
        EXPECT_NE(r.out.find(part), std::string::npos) << part;
    }
    const RunResult top = run_voxfield({"--help"}, dir_);
    EXPECT_NE(top.out.find("info"), std::string::npos);
}

}  // namespace
}  // namespace voxfield::test
