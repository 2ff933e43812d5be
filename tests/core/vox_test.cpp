#include <gtest/gtest.h>

#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <iostream>
#include <iterator>
#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "test_util.hpp"
#include "voxfield/core/sparse.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield {
namespace {

namespace fs = std::filesystem;
using test::expect_input_error;
using test::put_u32;
using test::read_bytes;
using test::TempDir;
using test::write_bytes;

const fs::path kData = fs::path(VOXFIELD_DATA_DIR) / "vox";

// Expected values computed independently by a Python script that walks the .vox chunks:
// vox SIZE, XYZI voxel count, sum of colour indices, sum of world linear indices after the
// (x, y, z) -> (x, z, y) mapping, and the first XYZI voxel with its RGBA colour.
struct Expected {
    const char* file;
    Dims vox_size;
    std::size_t voxels;
    std::uint64_t sum_colour;
    std::uint64_t sum_index;
    std::uint32_t fx, fy, fz;
    std::uint8_t fc;
    Rgba colour;
};

const Expected kModels[] = {
    {"chr_army1.vox", {8, 7, 12}, 341, 51121, 126290, 6, 2, 7, 96, {152, 100, 0, 255}},
    {"veh_car1.vox", {15, 32, 11}, 2849, 600097, 7447673, 11, 7, 4, 253, {68, 68, 68, 255}},
    {"obj_house4.vox",
     {64, 64, 64},
     180202,
     44224572,
     27233069058ull,
     61,
     39,
     0,
     249,
     {168, 168, 168, 255}},
    {"scene_store8.vox",
     {124, 124, 68},
     441118,
     108395751,
     228989741366ull,
     85,
     14,
     20,
     249,
     {168, 168, 168, 255}},
};

TEST(Vox, ReadsShippedModels) {
    for (const Expected& e : kModels) {
        SCOPED_TRACE(e.file);
        const VoxModel m = read_vox(kData / e.file);
        EXPECT_EQ(m.world.dims(), (Dims{e.vox_size.x, e.vox_size.z, e.vox_size.y}));
        EXPECT_EQ(m.world.solid_count(), e.voxels);
        std::uint64_t sum_colour = 0, sum_index = 0;
        for (std::size_t i = 0; i < m.world.size(); ++i) {
            if (m.world.voxels()[i] != 0) {
                sum_colour += m.world.voxels()[i];
                sum_index += i;
            }
        }
        EXPECT_EQ(sum_colour, e.sum_colour);
        EXPECT_EQ(sum_index, e.sum_index);
        EXPECT_EQ(m.world.at(e.fx, e.fz, e.fy), e.fc);
        EXPECT_EQ(m.palette[e.fc], e.colour);
        // load_world gives the same (case-insensitive extension handled below).
        const VoxModel l = load_world(kData / e.file);
        EXPECT_EQ(l.world.voxels(), m.world.voxels());
    }
}

// Builds a .vox file from chunks.
struct VoxBuilder {
    std::vector<std::uint8_t> children;
    void chunk(const std::string& id, const std::vector<std::uint8_t>& content,
               const std::vector<std::uint8_t>& kids = {}) {
        children.insert(children.end(), id.begin(), id.end());
        put_u32(children, static_cast<std::uint32_t>(content.size()));
        put_u32(children, static_cast<std::uint32_t>(kids.size()));
        children.insert(children.end(), content.begin(), content.end());
        children.insert(children.end(), kids.begin(), kids.end());
    }
    void size(std::uint32_t x, std::uint32_t y, std::uint32_t z) {
        std::vector<std::uint8_t> c;
        put_u32(c, x);
        put_u32(c, y);
        put_u32(c, z);
        chunk("SIZE", c);
    }
    void xyzi(const std::vector<std::array<std::uint8_t, 4>>& voxels) {
        std::vector<std::uint8_t> c;
        put_u32(c, static_cast<std::uint32_t>(voxels.size()));
        for (const auto& v : voxels) {
            c.insert(c.end(), v.begin(), v.end());
        }
        chunk("XYZI", c);
    }
    std::vector<std::uint8_t> bytes() const {
        std::vector<std::uint8_t> b = {'V', 'O', 'X', ' '};
        put_u32(b, 150);
        b.insert(b.end(), {'M', 'A', 'I', 'N'});
        put_u32(b, 0);
        put_u32(b, static_cast<std::uint32_t>(children.size()));
        b.insert(b.end(), children.begin(), children.end());
        return b;
    }
};

TEST(Vox, PaletteMappingAndAxes) {
    TempDir dir;
    VoxBuilder vb;
    std::vector<std::uint8_t> pack;
    put_u32(pack, 1);
    vb.chunk("PACK", pack);
    vb.size(4, 3, 2);  // x 4, y 3 (depth), z 2 (up)
    vb.xyzi({{{3, 2, 1, 1}}, {{0, 1, 0, 200}}, {{1, 0, 1, 255}}});
    vb.chunk("rOBJ", std::vector<std::uint8_t>(28, 0xAB));
    vb.chunk("MATL", std::vector<std::uint8_t>(13, 0));
    vb.chunk("IMAP", std::vector<std::uint8_t>(5, 1), std::vector<std::uint8_t>(12, 0));
    std::vector<std::uint8_t> rgba;
    for (int i = 0; i < 256; ++i) {
        rgba.insert(rgba.end(), {static_cast<std::uint8_t>(i), static_cast<std::uint8_t>(255 - i),
                                 static_cast<std::uint8_t>(i / 2), 200});
    }
    vb.chunk("RGBA", rgba);
    vb.chunk("NOTE", {1, 2, 3});
    write_bytes(dir / "p.vox", vb.bytes());
    const VoxModel m = read_vox(dir / "p.vox");
    EXPECT_EQ(m.world.dims(), (Dims{4, 2, 3}));
    EXPECT_EQ(m.world.solid_count(), 3u);
    EXPECT_EQ(m.world.at(3, 1, 2), 1);    // vox (3,2,1)
    EXPECT_EQ(m.world.at(0, 0, 1), 200);  // vox (0,1,0)
    EXPECT_EQ(m.world.at(1, 1, 0), 255);  // vox (1,0,1)
    // Palette index i comes from RGBA entry i-1.
    EXPECT_EQ(m.palette[1], (Rgba{0, 255, 0, 200}));
    EXPECT_EQ(m.palette[200], (Rgba{199, 56, 99, 200}));
    EXPECT_EQ(m.palette[255], (Rgba{254, 1, 127, 200}));
    EXPECT_EQ(m.palette[0].a, 0);
    // load_world dispatches on a case-insensitive extension.
    fs::copy_file(dir / "p.vox", dir / "P.VoX");
    EXPECT_EQ(load_world(dir / "P.VoX").world.voxels(), m.world.voxels());
}

TEST(Vox, MissingRgbaUsesDefaultAndFirstModelOnly) {
    TempDir dir;
    VoxBuilder vb;
    vb.size(2, 2, 2);
    vb.xyzi({{{1, 1, 1, 5}}});
    vb.size(9, 9, 9);
    vb.xyzi({{{8, 8, 8, 7}}, {{0, 0, 0, 7}}});
    write_bytes(dir / "d.vox", vb.bytes());
    const VoxModel m = read_vox(dir / "d.vox");
    EXPECT_EQ(m.world.dims(), (Dims{2, 2, 2}));
    EXPECT_EQ(m.world.solid_count(), 1u);
    EXPECT_EQ(m.world.at(1, 1, 1), 5);
    for (int i = 0; i < 256; ++i) {
        EXPECT_EQ(m.palette[static_cast<std::uint8_t>(i)], Palette()[static_cast<std::uint8_t>(i)]);
    }
}

TEST(Vox, StructuralErrors) {
    TempDir dir;
    auto check = [&](const std::string& name, const std::vector<std::uint8_t>& bytes,
                     const std::vector<std::string>& parts) {
        SCOPED_TRACE(name);
        write_bytes(dir / name, bytes);
        std::vector<std::string> all = parts;
        all.push_back(name);
        expect_input_error([&] { read_vox(dir / name); }, all);
    };
    {
        VoxBuilder vb;
        vb.size(2, 2, 2);
        vb.xyzi({{{2, 0, 0, 1}}});
        check("outside.vox", vb.bytes(), {"(2, 0, 0)", "outside SIZE 2x2x2"});
    }
    {
        VoxBuilder vb;
        vb.size(2, 2, 2);
        vb.xyzi({{{1, 0, 0, 0}}});
        check("colour0.vox", vb.bytes(), {"colour index 0"});
    }
    {
        VoxBuilder vb;
        vb.xyzi({{{1, 0, 0, 1}}});
        vb.size(2, 2, 2);
        check("order.vox", vb.bytes(), {"'XYZI'", "before any 'SIZE'"});
    }
    {
        VoxBuilder vb;
        vb.size(2, 2, 2);
        check("noxyzi.vox", vb.bytes(), {"no 'XYZI'"});
    }
    {
        VoxBuilder vb;
        vb.size(2, 2, 2);
        vb.size(2, 2, 2);
        vb.xyzi({});
        check("twosize.vox", vb.bytes(), {"no 'XYZI'", "'SIZE' chunk at offset 20"});
    }
    {
        VoxBuilder vb;
        vb.size(2, 2, 2);
        vb.xyzi({{{1, 0, 0, 1}}});
        auto b = vb.bytes();
        b[4] = 149;  // version 149
        check("old.vox", b, {"version 149", "older than 150"});
    }
    {
        VoxBuilder vb;
        vb.chunk("RGBA", std::vector<std::uint8_t>(1024, 0));
        check("nosize.vox", vb.bytes(), {"no 'SIZE'"});
    }
    {
        VoxBuilder vb;
        vb.size(0, 2, 2);
        vb.xyzi({});
        check("size0.vox", vb.bytes(), {"'SIZE'", "1..256"});
    }
    {
        VoxBuilder vb;
        vb.size(2, 2, 2);
        vb.chunk("RGBA", std::vector<std::uint8_t>(100, 0));
        vb.xyzi({});
        check("rgba.vox", vb.bytes(), {"'RGBA'", "100 content bytes", "needs 1024"});
    }
    {
        VoxBuilder vb;
        vb.size(2, 2, 2);
        std::vector<std::uint8_t> c;
        put_u32(c, 1000);  // claims 1000 voxels, has 1
        c.insert(c.end(), {0, 0, 0, 1});
        vb.chunk("XYZI", c);
        check("count.vox", vb.bytes(), {"1000 voxels", "4004 bytes", "content is 8 bytes"});
    }
    {
        auto b = VoxBuilder{}.bytes();
        b[0] = 'B';
        check("magic.vox", b, {"not a MagicaVoxel file", "'BOX '"});
    }
    {
        auto b = VoxBuilder{}.bytes();
        b[8] = 'X';
        check("main.vox", b, {"'XAIN'", "expected 'MAIN'"});
    }
    check("short.vox", {'V', 'O', 'X'}, {"truncated"});
    check("empty.vox", {}, {"truncated"});
}

TEST(Vox, BogusChunkSizes) {
    TempDir dir;
    const auto good = read_bytes(kData / "chr_army1.vox");
    ASSERT_EQ(good.size(), 2460u);
    // MAIN at 8, SIZE at 20 (content 12), XYZI at 44.
    ASSERT_EQ(std::string(good.begin() + 44, good.begin() + 48), "XYZI");
    struct Patch {
        std::size_t offset;
        std::uint32_t value;
        std::vector<std::string> parts;
    };
    const std::vector<Patch> patches = {
        {12, 0xFFFFFFFFu, {"truncated", "'MAIN'"}},  // MAIN content size
        {16, 0x7FFFFFFFu, {"truncated", "'MAIN'"}},  // MAIN children size
        {24, 0xFFFFFFF0u, {"truncated", "'SIZE'"}},  // SIZE content size
        {28, 5000, {"truncated", "'SIZE'"}},         // SIZE children size
        {48, 4000, {"chunk 'XYZI' needs 4000 bytes at offset 56"}},
        {56, 0x40000000u, {"declares 1073741824 voxels"}},  // XYZI voxel count
        {32, 300, {"1..256"}},                              // SIZE x
    };
    for (const Patch& p : patches) {
        auto b = good;
        for (int k = 0; k < 4; ++k) {
            b[p.offset + static_cast<std::size_t>(k)] =
                static_cast<std::uint8_t>(p.value >> (8 * k));
        }
        const std::string name = "patch" + std::to_string(p.offset) + ".vox";
        write_bytes(dir / name, b);
        SCOPED_TRACE(name);
        expect_input_error([&] { read_vox(dir / name); }, p.parts);
    }
}

TEST(Vox, TruncatedFilesNeverCrash) {
    TempDir dir;
    for (const char* file : {"chr_army1.vox", "veh_car1.vox"}) {
        const auto good = read_bytes(kData / file);
        std::vector<std::size_t> cuts = {0,
                                         1,
                                         4,
                                         7,
                                         8,
                                         12,
                                         19,
                                         20,
                                         31,
                                         43,
                                         44,
                                         55,
                                         56,
                                         57,
                                         100,
                                         good.size() / 2,
                                         good.size() - 1024,
                                         good.size() - 1};
        for (std::size_t cut : cuts) {
            auto b = std::vector<std::uint8_t>(good.begin(), good.begin() + static_cast<long>(cut));
            write_bytes(dir / "cut.vox", b);
            try {
                read_vox(dir / "cut.vox");
                ADD_FAILURE() << file << " cut at " << cut << " was accepted";
            } catch (const InputError& e) {
                EXPECT_NE(std::string(e.what()).find("cut.vox"), std::string::npos) << e.what();
            }
        }
    }
    // Random byte corruption: either a clean InputError or a valid model, never a crash.
    const auto good = read_bytes(kData / "veh_car1.vox");
    std::uint64_t state = 12345;
    int rejected = 0;
    for (int trial = 0; trial < 300; ++trial) {
        auto b = good;
        for (int k = 0; k < 4; ++k) {
            state = state * 6364136223846793005ull + 1442695040888963407ull;
            const std::size_t at = (state >> 33) % 80;  // headers and the first voxels
            b[at] = static_cast<std::uint8_t>(state >> 20);
        }
        write_bytes(dir / "flip.vox", b);
        try {
            const VoxModel m = read_vox(dir / "flip.vox");
            EXPECT_GT(m.world.size(), 0u);
        } catch (const InputError&) {
            ++rejected;
        }
    }
    EXPECT_GT(rejected, 0);
}

TEST(Vox, LoadWorldErrors) {
    TempDir dir;
    const fs::path missing = dir / "none.vox";
    expect_input_error([&] { load_world(missing); },
                       {test::cat({"'", missing.string(), "': no such file"})});
    expect_input_error([&] { read_vox(missing); }, {"no such file"});
    test::write_text(dir / "model.obj", "v 1 2 3\n");
    expect_input_error([&] { load_world(dir / "model.obj"); },
                       {"model.obj", "'.obj'", ".vox, .npy"});
    test::write_text(dir / "noext", "x");
    expect_input_error([&] { load_world(dir / "noext"); }, {"noext", ".vox, .npy"});
    fs::create_directory(dir / "folder.vox");
    expect_input_error([&] { load_world(dir / "folder.vox"); }, {"folder.vox", "directory"});
    if (::geteuid() != 0) {
        test::write_text(dir / "locked.vox", "VOX ");
        fs::permissions(dir / "locked.vox", fs::perms::none);
        expect_input_error([&] { load_world(dir / "locked.vox"); }, {"locked.vox", "cannot open"});
    }
}

TEST(Vox, WriteRoundTrips) {
    TempDir dir;
    // A non-cubic world with every palette index, written and read back unchanged.
    World w(Dims{7, 5, 3});
    Palette pal = Palette::dissertation();
    pal[255] = Rgba{1, 2, 3, 4};
    for (std::size_t i = 0; i < w.size(); ++i) {
        w.voxels()[i] = static_cast<std::uint8_t>(i % 3 == 0 ? 0 : (i * 37) % 256);
    }
    w.set(6, 4, 2, 255);
    w.set(0, 0, 0, 1);
    const fs::path p = dir / "world.vox";
    write_vox(p, w, pal);
    const VoxModel m = read_vox(p);
    EXPECT_EQ(m.world.dims(), w.dims());
    EXPECT_EQ(m.world.voxels(), w.voxels());
    for (int i = 1; i < 256; ++i) {
        EXPECT_EQ(m.palette[static_cast<std::uint8_t>(i)], pal[static_cast<std::uint8_t>(i)]) << i;
    }
    // MagicaVoxel is z-up: SIZE holds (X, Z, Y) and XYZI (x, z, y, index).
    const std::vector<std::uint8_t> b = read_bytes(p);
    ASSERT_GE(b.size(), 56u);
    EXPECT_EQ(std::string(b.begin(), b.begin() + 4), "VOX ");
    EXPECT_EQ(std::string(b.begin() + 20, b.begin() + 24), "SIZE");
    EXPECT_EQ(b[32], 7);
    EXPECT_EQ(b[36], 3);
    EXPECT_EQ(b[40], 5);
    // A shipped model survives a round trip, and so does an empty world.
    const VoxModel house = read_vox(kData / "obj_house4.vox");
    write_vox(dir / "house.vox", house.world, house.palette);
    const VoxModel again = read_vox(dir / "house.vox");
    EXPECT_EQ(again.world.dims(), house.world.dims());
    EXPECT_EQ(again.world.voxels(), house.world.voxels());
    write_vox(dir / "empty.vox", World(Dims{2, 3, 4}), pal);
    EXPECT_EQ(read_vox(dir / "empty.vox").world.solid_count(), 0u);
}

TEST(Vox, WriteErrors) {
    TempDir dir;
    expect_input_error(
        [&] {
            write_vox(dir / "big.vox", World(Dims{257, 1, 1}), Palette());
        },
        {"big.vox", "257x1x1", "256"});
    expect_input_error(
        [&] {
            write_vox(dir / "missing" / "w.vox", World(Dims{1, 1, 1}), Palette());
        },
        {"w.vox", "does not exist"});
    EXPECT_TRUE(fs::is_empty(dir.path()));
}

// ---- Scene graphs (nTRN / nGRP / nSHP / LAYR) -------------------------------------------

using Dict = std::vector<std::pair<std::string, std::string>>;

void put_text(std::vector<std::uint8_t>& b, const std::string& s) {
    put_u32(b, static_cast<std::uint32_t>(s.size()));
    b.insert(b.end(), s.begin(), s.end());
}

void put_dict(std::vector<std::uint8_t>& b, const Dict& d) {
    put_u32(b, static_cast<std::uint32_t>(d.size()));
    for (const auto& [k, v] : d) {
        put_text(b, k);
        put_text(b, v);
    }
}

// A signed permutation matrix, rows; the test's own description of a rotation.
using Mat = std::array<int, 9>;
using Vec = std::array<std::int64_t, 3>;

const Mat kIdentity = {1, 0, 0, 0, 1, 0, 0, 0, 1};

// MagicaVoxel's packed byte for `m` (the inverse of what the reader decodes).
int pack_rotation(const Mat& m) {
    int bits = 0;
    for (int row = 0; row < 3; ++row) {
        for (int col = 0; col < 3; ++col) {
            const int v = m[static_cast<std::size_t>(3 * row + col)];
            if (v != 0) {
                if (row < 2) {
                    bits |= col << (2 * row);
                }
                if (v < 0) {
                    bits |= 1 << (4 + row);
                }
            }
        }
    }
    return bits;
}

// All 48 signed permutations (24 rotations and 24 reflections).
std::vector<Mat> all_rotations() {
    std::vector<Mat> out;
    const int perms[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
    for (const auto& p : perms) {
        for (int s = 0; s < 8; ++s) {
            Mat m{};
            for (int row = 0; row < 3; ++row) {
                m[static_cast<std::size_t>(3 * row + p[row])] = (s >> row) & 1 ? -1 : 1;
            }
            out.push_back(m);
        }
    }
    return out;
}

Mat mul(const Mat& a, const Mat& b) {
    Mat c{};
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) {
            for (int k = 0; k < 3; ++k) {
                c[static_cast<std::size_t>(3 * i + j)] +=
                    a[static_cast<std::size_t>(3 * i + k)] * b[static_cast<std::size_t>(3 * k + j)];
            }
        }
    }
    return c;
}

Vec apply(const Mat& m, const std::array<double, 3>& v, std::array<double, 3>& out) {
    for (int i = 0; i < 3; ++i) {
        out[static_cast<std::size_t>(i)] = 0;
        for (int k = 0; k < 3; ++k) {
            out[static_cast<std::size_t>(i)] +=
                m[static_cast<std::size_t>(3 * i + k)] * v[static_cast<std::size_t>(k)];
        }
    }
    return {};
}

struct TestModel {
    std::array<std::uint32_t, 3> size;
    std::vector<std::array<std::uint8_t, 4>> voxels;
};

// Builds a .vox scene from the test's own tree and keeps, for every shape it adds, the
// instance's accumulated transform as the test computes it (for the expectation).
struct SceneBuilder {
    std::vector<TestModel> models;
    VoxBuilder vb;
    std::vector<std::uint8_t> graph;  // node and layer chunks, appended after the models
    std::uint32_t next_id = 0;
    struct Placed {
        std::uint32_t model;
        Mat r;
        std::array<double, 3> t;
    };
    std::vector<Placed> visible;  // in depth-first order
    std::size_t hidden = 0;

    void node_chunk(const std::string& id, const std::vector<std::uint8_t>& content) {
        graph.insert(graph.end(), id.begin(), id.end());
        put_u32(graph, static_cast<std::uint32_t>(content.size()));
        put_u32(graph, 0);
        graph.insert(graph.end(), content.begin(), content.end());
    }
    void transform(std::uint32_t id, std::uint32_t child, const Mat& r, const Vec& t,
                   std::int32_t layer = -1, bool hidden_node = false) {
        std::vector<std::uint8_t> c;
        put_u32(c, id);
        put_dict(c, hidden_node ? Dict{{"_name", "n"}, {"_hidden", "1"}} : Dict{{"_name", "n"}});
        put_u32(c, child);
        put_u32(c, 0xFFFFFFFFu);
        put_u32(c, static_cast<std::uint32_t>(layer));
        put_u32(c, 1);
        Dict frame;
        if (r != kIdentity) {
            frame.emplace_back("_r", std::to_string(pack_rotation(r)));
        }
        frame.emplace_back(
            "_t", std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]));
        put_dict(c, frame);
        node_chunk("nTRN", c);
    }
    void group(std::uint32_t id, const std::vector<std::uint32_t>& kids) {
        std::vector<std::uint8_t> c;
        put_u32(c, id);
        put_dict(c, {});
        put_u32(c, static_cast<std::uint32_t>(kids.size()));
        for (std::uint32_t k : kids) {
            put_u32(c, k);
        }
        node_chunk("nGRP", c);
    }
    void shape(std::uint32_t id, std::uint32_t model) {
        std::vector<std::uint8_t> c;
        put_u32(c, id);
        put_dict(c, {});
        put_u32(c, 1);
        put_u32(c, model);
        put_dict(c, {});
        node_chunk("nSHP", c);
    }
    void layer(std::int32_t id, bool hidden_layer) {
        std::vector<std::uint8_t> c;
        put_u32(c, static_cast<std::uint32_t>(id));
        put_dict(c, hidden_layer ? Dict{{"_name", "L"}, {"_hidden", "1"}} : Dict{{"_name", "L"}});
        put_u32(c, 0xFFFFFFFFu);
        node_chunk("LAYR", c);
    }

    // A transform node over a shape node; `r`, `t` local; the parent's accumulated pr, pt.
    void instance(std::uint32_t model, const Mat& pr, const std::array<double, 3>& pt, const Mat& r,
                  const Vec& t, bool is_hidden, std::uint32_t& tid, std::int32_t layer_id = -1,
                  bool hidden_node = false) {
        tid = next_id++;
        const std::uint32_t sid = next_id++;
        transform(tid, sid, r, t, layer_id, hidden_node);
        shape(sid, model);
        if (is_hidden) {
            ++hidden;
            return;
        }
        std::array<double, 3> rt{};
        apply(pr, {static_cast<double>(t[0]), static_cast<double>(t[1]), static_cast<double>(t[2])},
              rt);
        visible.push_back({model, mul(pr, r), {pt[0] + rt[0], pt[1] + rt[1], pt[2] + rt[2]}});
    }

    std::vector<std::uint8_t> bytes() {
        VoxBuilder out;
        for (const TestModel& m : models) {
            out.size(m.size[0], m.size[1], m.size[2]);
            out.xyzi(m.voxels);
        }
        out.children.insert(out.children.end(), graph.begin(), graph.end());
        return out.bytes();
    }

    // The expectation: every visible instance's model box corners and voxel centres moved by
    // x -> R (x - pivot) + T in doubles; origin at the minimum corner; vox -> world axes.
    World expected() const {
        std::array<double, 3> lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
        for (const Placed& p : visible) {
            const TestModel& m = models[p.model];
            for (int corner = 0; corner < 8; ++corner) {
                std::array<double, 3> c{}, w{};
                for (int a = 0; a < 3; ++a) {
                    const double piv = std::floor(m.size[static_cast<std::size_t>(a)] / 2.0);
                    c[static_cast<std::size_t>(a)] =
                        ((corner >> a) & 1 ? m.size[static_cast<std::size_t>(a)] : 0) - piv;
                }
                apply(p.r, c, w);
                for (std::size_t a = 0; a < 3; ++a) {
                    lo[a] = std::min(lo[a], w[a] + p.t[a]);
                    hi[a] = std::max(hi[a], w[a] + p.t[a]);
                }
            }
        }
        World w(Dims{static_cast<std::uint32_t>(hi[0] - lo[0]),
                     static_cast<std::uint32_t>(hi[2] - lo[2]),
                     static_cast<std::uint32_t>(hi[1] - lo[1])});
        for (const Placed& p : visible) {
            const TestModel& m = models[p.model];
            for (const auto& v : m.voxels) {
                std::array<double, 3> c{}, r{};
                for (std::size_t a = 0; a < 3; ++a) {
                    c[a] = v[a] + 0.5 - std::floor(m.size[a] / 2.0);
                }
                apply(p.r, c, r);
                std::array<std::uint32_t, 3> cell{};
                for (std::size_t a = 0; a < 3; ++a) {
                    cell[a] = static_cast<std::uint32_t>(std::floor(r[a] + p.t[a] - lo[a]));
                }
                w.set(cell[0], cell[2], cell[1], v[3]);
            }
        }
        return w;
    }
};

// An asymmetric model: every voxel has its own colour, so any misplaced voxel shows.
TestModel asymmetric_model(std::uint32_t sx, std::uint32_t sy, std::uint32_t sz,
                           std::uint8_t colour_base, std::uint64_t seed) {
    TestModel m{{sx, sy, sz}, {}};
    std::mt19937_64 rng(seed);
    for (std::uint32_t z = 0; z < sz; ++z) {
        for (std::uint32_t y = 0; y < sy; ++y) {
            for (std::uint32_t x = 0; x < sx; ++x) {
                if (rng() % 3 != 0 || (x == 0 && y == 0 && z == 0)) {
                    const auto c =
                        static_cast<std::uint8_t>(1 + (colour_base + x + 7 * y + 31 * z) % 255);
                    m.voxels.push_back({static_cast<std::uint8_t>(x), static_cast<std::uint8_t>(y),
                                        static_cast<std::uint8_t>(z), c});
                }
            }
        }
    }
    return m;
}

void expect_same_world(const World& got, const World& want) {
    ASSERT_EQ(got.dims(), want.dims());
    std::size_t diff = 0;
    for (std::size_t i = 0; i < got.size(); ++i) {
        diff += got.voxels()[i] != want.voxels()[i];
    }
    EXPECT_EQ(diff, 0u) << "of " << got.size() << " voxels";
}

TEST(VoxScene, EveryRotationByteIncludingReflections) {
    TempDir dir;
    SceneBuilder sb;
    sb.models.push_back(asymmetric_model(3, 4, 5, 0, 1));  // odd and even sizes
    sb.models.push_back(asymmetric_model(2, 6, 1, 90, 2));
    const std::vector<Mat> rots = all_rotations();
    std::vector<std::uint32_t> kids;
    for (std::size_t i = 0; i < rots.size(); ++i) {
        std::uint32_t tid = 0;
        // Spread along x and y so no two instances overlap; z varies too.
        const Vec t = {static_cast<std::int64_t>(i % 8) * 9 - 20,
                       static_cast<std::int64_t>(i / 8) * 9 + 3, static_cast<std::int64_t>(i % 3)};
        sb.next_id = std::max<std::uint32_t>(sb.next_id, 2);
        sb.instance(static_cast<std::uint32_t>(i % 2), kIdentity, {0, 0, 0}, rots[i], t, false,
                    tid);
        kids.push_back(tid);
    }
    sb.transform(0, 1, kIdentity, {0, 0, 0});
    sb.group(1, kids);
    write_bytes(dir / "rot.vox", sb.bytes());
    const VoxScene scene = read_vox_scene(dir / "rot.vox");
    EXPECT_TRUE(scene.has_scene_graph);
    EXPECT_EQ(scene.models.size(), 2u);
    EXPECT_EQ(scene.instances.size(), 48u);
    const VoxModel m = read_vox(dir / "rot.vox");
    expect_same_world(m.world, sb.expected());
    // Every rotation byte decodes to the matrix it was packed from.
    for (std::size_t i = 0; i < rots.size(); ++i) {
        for (std::size_t k = 0; k < 9; ++k) {
            EXPECT_EQ(scene.instances[i].rotation[k], rots[i][k]) << "rotation " << i;
        }
    }
}

TEST(VoxScene, NestedGroupsTranslatedAndRotated) {
    TempDir dir;
    SceneBuilder sb;
    sb.models.push_back(asymmetric_model(5, 3, 4, 10, 3));
    sb.models.push_back(asymmetric_model(4, 4, 2, 50, 4));
    const std::vector<Mat> rots = all_rotations();
    // root 0 -> group 1 -> [T 2 (rot a, t) -> group 3 -> [T (rot b) -> shape, T -> shape],
    //                       T (plain) -> shape]
    sb.next_id = 4;
    const Mat ra = rots[13], rb = rots[38];
    const Vec ta = {-7, 11, 5};
    std::uint32_t i0 = 0, i1 = 0, i2 = 0;
    sb.instance(0, ra, {-7, 11, 5}, rb, {3, -2, 6}, false, i0);
    sb.instance(1, ra, {-7, 11, 5}, kIdentity, {-4, 0, 1}, false, i1);
    sb.instance(1, kIdentity, {0, 0, 0}, rots[5], {20, 20, -3}, false, i2);
    sb.transform(0, 1, kIdentity, {0, 0, 0});
    sb.group(1, {2, i2});
    sb.transform(2, 3, ra, ta);
    sb.group(3, {i0, i1});
    write_bytes(dir / "nest.vox", sb.bytes());
    const VoxScene scene = read_vox_scene(dir / "nest.vox");
    ASSERT_EQ(scene.instances.size(), 3u);
    EXPECT_EQ(scene.instances[0].model, 0u);  // depth-first order
    EXPECT_EQ(scene.instances[2].model, 1u);
    expect_same_world(read_vox(dir / "nest.vox").world, sb.expected());
}

TEST(VoxScene, HiddenNodesAndLayersAreSkipped) {
    TempDir dir;
    SceneBuilder sb;
    sb.models.push_back(asymmetric_model(3, 3, 3, 0, 5));
    sb.next_id = 4;
    std::uint32_t a = 0, b = 0, c = 0, d = 0, e = 0;
    sb.instance(0, kIdentity, {0, 0, 0}, kIdentity, {0, 0, 0}, false, a, 0);
    sb.instance(0, kIdentity, {0, 0, 0}, kIdentity, {10, 0, 0}, true, b, 1);        // hidden layer
    sb.instance(0, kIdentity, {0, 0, 0}, kIdentity, {0, 10, 0}, true, c, 0, true);  // hidden
    sb.instance(0, kIdentity, {0, 0, 0}, kIdentity, {0, 0, 10}, false, d, 2);
    // A hidden group transform: everything below it is skipped.
    sb.instance(0, kIdentity, {30, 30, 30}, kIdentity, {0, 0, 0}, true, e);
    sb.layer(0, false);
    sb.layer(1, true);
    sb.layer(2, false);
    sb.transform(0, 1, kIdentity, {0, 0, 0});
    sb.group(1, {a, b, c, d, 2});
    sb.transform(2, 3, kIdentity, {30, 30, 30}, -1, true);
    sb.group(3, {e});
    write_bytes(dir / "hid.vox", sb.bytes());
    const VoxScene scene = read_vox_scene(dir / "hid.vox");
    EXPECT_EQ(scene.instances.size(), 2u);
    EXPECT_EQ(scene.hidden_instances, 3u);
    const World got = read_vox(dir / "hid.vox").world;
    EXPECT_EQ(got.dims(), (Dims{3, 13, 3}));  // the hidden ones do not widen the world
    expect_same_world(got, sb.expected());
}

TEST(VoxScene, OverlappingInstancesLaterWins) {
    TempDir dir;
    SceneBuilder sb;
    TestModel red{{4, 4, 4}, {}}, blue{{4, 4, 4}, {}};
    for (std::uint8_t z = 0; z < 4; ++z) {
        for (std::uint8_t y = 0; y < 4; ++y) {
            for (std::uint8_t x = 0; x < 4; ++x) {
                red.voxels.push_back({x, y, z, 7});
                if ((x + y + z) % 2 == 0) {
                    blue.voxels.push_back({x, y, z, 9});
                }
            }
        }
    }
    sb.models = {red, blue};
    sb.next_id = 2;
    std::uint32_t a = 0, b = 0, c = 0;
    sb.instance(0, kIdentity, {0, 0, 0}, kIdentity, {0, 0, 0}, false, a);
    sb.instance(1, kIdentity, {0, 0, 0}, kIdentity, {2, 1, 0}, false, b);
    sb.instance(0, kIdentity, {0, 0, 0}, all_rotations()[9], {4, 3, 1}, false, c);
    sb.transform(0, 1, kIdentity, {0, 0, 0});
    sb.group(1, {a, b, c});
    write_bytes(dir / "over.vox", sb.bytes());
    const World got = read_vox(dir / "over.vox").world;
    const World want = sb.expected();
    expect_same_world(got, want);
    // Spot checks, in the file's own words: vox (2, 1, 0) is blue's (0, 0, 0) -> 9 over red's
    // 7; vox (3, 1, 0) is blue's (1, 0, 0), empty in blue, so red stays.
    EXPECT_EQ(got.at(2, 0, 1), 9);
    EXPECT_EQ(got.at(3, 0, 1), 7);
}

// Random trees built depth-first (so the test's instance order is the reader's), random
// rotations among all 48, random translations, overlapping models.
void random_group(SceneBuilder& sb, std::mt19937_64& rng, std::uint32_t gid, const Mat& pr,
                  const std::array<double, 3>& pt, int depth) {
    const std::vector<Mat> rots = all_rotations();
    std::vector<std::uint32_t> kids;
    const int n = 1 + static_cast<int>(rng() % 4);
    for (int k = 0; k < n; ++k) {
        const Mat r = rots[rng() % rots.size()];
        const Vec t = {static_cast<std::int64_t>(rng() % 17) - 8,
                       static_cast<std::int64_t>(rng() % 17) - 8,
                       static_cast<std::int64_t>(rng() % 17) - 8};
        if (rng() % 3 == 0 && depth < 4) {
            const std::uint32_t tid = sb.next_id++, child = sb.next_id++;
            sb.transform(tid, child, r, t);
            kids.push_back(tid);
            std::array<double, 3> rt{};
            apply(pr,
                  {static_cast<double>(t[0]), static_cast<double>(t[1]), static_cast<double>(t[2])},
                  rt);
            random_group(sb, rng, child, mul(pr, r), {pt[0] + rt[0], pt[1] + rt[1], pt[2] + rt[2]},
                         depth + 1);
        } else {
            std::uint32_t tid = 0;
            sb.instance(static_cast<std::uint32_t>(rng() % sb.models.size()), pr, pt, r, t, false,
                        tid);
            kids.push_back(tid);
        }
    }
    sb.group(gid, kids);
}

TEST(VoxScene, RandomTreesMatchTheIndependentPlacement) {
    TempDir dir;
    std::mt19937_64 rng(2024);
    std::size_t overlapping = 0;
    for (int trial = 0; trial < 60; ++trial) {
        SCOPED_TRACE(trial);
        SceneBuilder sb;
        const int n_models = 1 + static_cast<int>(rng() % 3);
        for (int k = 0; k < n_models; ++k) {
            sb.models.push_back(asymmetric_model(1 + static_cast<std::uint32_t>(rng() % 7),
                                                 1 + static_cast<std::uint32_t>(rng() % 7),
                                                 1 + static_cast<std::uint32_t>(rng() % 7),
                                                 static_cast<std::uint8_t>(rng()), rng()));
        }
        const std::array<double, 3> root_t = {static_cast<double>(rng() % 9) - 4, 0, 3};
        sb.transform(0, 1, kIdentity, {static_cast<std::int64_t>(root_t[0]), 0, 3});
        sb.next_id = 2;
        random_group(sb, rng, 1, kIdentity, root_t, 0);
        write_bytes(dir / "rand.vox", sb.bytes());
        const VoxScene scene = read_vox_scene(dir / "rand.vox");
        ASSERT_EQ(scene.instances.size(), sb.visible.size());
        const World want = sb.expected();
        expect_same_world(read_vox(dir / "rand.vox").world, want);
        const SparseModel sparse = load_sparse_world(dir / "rand.vox");
        expect_same_world(sparse.world.to_dense(), want);
        for (int c = 0; c < 256; ++c) {
            EXPECT_EQ(sparse.palette[static_cast<std::uint8_t>(c)],
                      scene.palette[static_cast<std::uint8_t>(c)]);
        }
        std::size_t placed = 0;
        for (const auto& p : sb.visible) {
            placed += sb.models[p.model].voxels.size();
        }
        overlapping += want.solid_count() < placed;
    }
    EXPECT_GT(overlapping, 5u);  // the overlap rule was exercised
}

// A scene too wide for a dense world: its instances 600000 voxels apart on two axes (about
// 3.6e11 voxels of extent) load sparse, tile by tile, each voxel where the scene places it.
TEST(VoxScene, WideScenesLoadSparseWithoutADenseWorld) {
    TempDir dir;
    SceneBuilder sb;
    sb.models.push_back(asymmetric_model(5, 70, 3, 10, 5));  // crosses tile edges in y
    sb.models.push_back(asymmetric_model(66, 4, 9, 99, 6));
    sb.next_id = 2;
    std::vector<std::uint32_t> kids;
    const std::vector<Mat> rots = all_rotations();
    const Vec ts[] = {{-300000, -300000, 0},
                      {300000, 300000, 5},
                      {300000, -300000, 70},
                      {-300000, 300000, 64},
                      {17, 63, 2}};
    for (std::size_t i = 0; i < std::size(ts); ++i) {
        std::uint32_t tid = 0;
        sb.instance(static_cast<std::uint32_t>(i % 2), kIdentity, {0, 0, 0}, rots[i * 7], ts[i],
                    false, tid);
        kids.push_back(tid);
    }
    sb.transform(0, 1, kIdentity, {0, 0, 0});
    sb.group(1, kids);
    write_bytes(dir / "wide.vox", sb.bytes());
    expect_input_error([&] { read_vox(dir / "wide.vox"); }, {"2^31"});
    const VoxScene scene = read_vox_scene(dir / "wide.vox");
    const SparseModel sparse = load_sparse_world(dir / "wide.vox");
    ASSERT_EQ(sparse.world.dims(), scene.dims);
    std::map<std::array<std::uint32_t, 3>, std::uint8_t> want;
    scene.place([&](std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint8_t v) {
        want[{x, y, z}] = v;
    });
    EXPECT_EQ(sparse.world.solid_count(), want.size());
    std::size_t wrong = 0;
    for (const auto& [p, v] : want) {
        wrong += sparse.world.at(p[0], p[1], p[2]) != v;
    }
    EXPECT_EQ(wrong, 0u);
    EXPECT_GT(sparse.world.tile_count(), 4u);
}

TEST(VoxScene, SharedShapeNodesAreInstancedPerPath) {
    // MagicaVoxel writes copies of a model as transforms sharing one shape node.
    TempDir dir;
    SceneBuilder sb;
    sb.models.push_back(asymmetric_model(3, 2, 4, 40, 6));
    sb.next_id = 2;
    std::uint32_t a = 0;
    sb.instance(0, kIdentity, {0, 0, 0}, all_rotations()[20], {1, 2, 3}, false, a);
    const std::uint32_t shared_shape = a + 1;
    const Mat r = all_rotations()[33];
    sb.transform(10, shared_shape, r, {9, -4, 0});
    sb.visible.push_back({0, r, {9, -4, 0}});
    sb.transform(0, 1, kIdentity, {0, 0, 0});
    sb.group(1, {a, 10});
    write_bytes(dir / "share.vox", sb.bytes());
    EXPECT_EQ(read_vox_scene(dir / "share.vox").instances.size(), 2u);
    expect_same_world(read_vox(dir / "share.vox").world, sb.expected());
}

TEST(VoxScene, CorruptGraphsAreOneLineErrors) {
    TempDir dir;
    const TestModel cube = asymmetric_model(2, 2, 2, 0, 9);
    auto check = [&](const std::string& name, SceneBuilder& sb,
                     const std::vector<std::string>& parts) {
        SCOPED_TRACE(name);
        if (sb.models.empty()) {
            sb.models.push_back(cube);
        }
        write_bytes(dir / name, sb.bytes());
        std::vector<std::string> all = parts;
        all.push_back(name);
        expect_input_error([&] { read_vox(dir / name); }, all);
    };
    {
        SceneBuilder sb;
        sb.transform(0, 1, kIdentity, {0, 0, 0});
        sb.group(1, {2});
        sb.transform(2, 1, kIdentity, {0, 0, 0});
        check("cycle.vox", sb, {"node cycle: 1 -> 2 -> 1"});
    }
    {
        SceneBuilder sb;
        sb.transform(0, 0, kIdentity, {0, 0, 0});
        check("self.vox", sb, {"node cycle: 0 -> 0"});
    }
    {
        SceneBuilder sb;
        sb.transform(0, 1, kIdentity, {0, 0, 0});
        sb.group(1, {2, 7});
        sb.transform(2, 3, kIdentity, {0, 0, 0});
        sb.shape(3, 0);
        check("missing.vox", sb, {"node 1 ('nGRP'", "child node 7", "not in the file"});
    }
    {
        SceneBuilder sb;
        // Each group lists the next one twice: 2^40 paths.
        sb.transform(0, 1, kIdentity, {0, 0, 0});
        for (std::uint32_t g = 1; g <= 40; ++g) {
            sb.group(g, {g + 1, g + 1});
        }
        sb.shape(41, 0);
        check("diamond.vox", sb, {"expands to more than 4194304 nodes"});
    }
    {
        SceneBuilder sb;
        sb.transform(0, 1, kIdentity, {0, 0, 0});
        sb.shape(1, 5);
        check("model.vox", sb, {"names model 5", "the file has 1"});
    }
    {
        SceneBuilder sb;
        sb.transform(1, 2, kIdentity, {0, 0, 0});
        sb.shape(2, 0);
        check("noroot.vox", sb, {"no root node 0"});
    }
    {
        SceneBuilder sb;
        sb.transform(0, 1, kIdentity, {0, 0, 0});
        sb.shape(1, 0);
        sb.shape(1, 0);
        check("dup.vox", sb, {"node id 1 is already used", "'nSHP'"});
    }
    {
        SceneBuilder sb;
        sb.transform(0, 1, kIdentity, {0, 0, 0}, -1, true);
        sb.shape(1, 0);
        check("allhidden.vox", sb, {"no visible model instance", "1 hidden"});
    }
    {
        SceneBuilder sb;
        sb.transform(0, 1, kIdentity, {0, 0, 0});
        sb.group(1, {2, 4});
        sb.transform(2, 3, kIdentity, {0, 0, 0});
        sb.shape(3, 0);
        sb.transform(4, 5, kIdentity, {0, 0, (1 << 20) - 1});  // vox z = world y
        sb.shape(5, 0);
        check("huge.vox", sb, {"2x1048577x2", "over the limit of 1048576 per axis"});
    }
    // Bad rotation and translation strings, written by hand.
    int case_number = 0;
    for (const auto& [r, t, part] :
         std::vector<std::array<std::string, 3>>{{"3", "0 0 0", "invalid rotation '_r' = '3'"},
                                                 {"5", "0 0 0", "invalid rotation '_r' = '5'"},
                                                 {"128", "0 0 0", "invalid rotation '_r' = '128'"},
                                                 {"x", "0 0 0", "invalid rotation"},
                                                 {"4", "1 2", "invalid translation '_t' = '1 2'"},
                                                 {"4", "1 2 3 4", "invalid translation"},
                                                 {"4", "1 2 99999999999", "invalid translation"},
                                                 {"4", "1 - 3", "invalid translation"},
                                                 // File text is quoted on one line.
                                                 {"1\n", "0 0 0", "'_r' = '1\\x0a'"},
                                                 {"4", "1\n2\n3", "'_t' = '1\\x0a2\\x0a3'"}}) {
        SceneBuilder sb;
        std::vector<std::uint8_t> c;
        put_u32(c, 0);
        put_dict(c, {});
        put_u32(c, 1);
        put_u32(c, 0xFFFFFFFFu);
        put_u32(c, 0);
        put_u32(c, 1);
        put_dict(c, {{"_r", r}, {"_t", t}});
        sb.node_chunk("nTRN", c);
        sb.shape(1, 0);
        check("rt" + std::to_string(case_number++) + ".vox", sb, {"chunk 'nTRN'", part});
    }
    // Truncated node chunks: every cut of a valid nTRN's content.
    SceneBuilder whole;
    whole.transform(0, 1, all_rotations()[7], {1, -2, 3});
    const std::vector<std::uint8_t> trn = whole.graph;
    for (std::size_t cut = 4; cut + 12 < trn.size(); cut += 3) {
        SceneBuilder sb;
        std::vector<std::uint8_t> c(trn.begin() + 12, trn.begin() + 12 + static_cast<long>(cut));
        sb.node_chunk("nTRN", c);
        sb.shape(1, 0);
        check("cut" + std::to_string(cut) + ".vox", sb, {"chunk 'nTRN' at offset", "truncated"});
    }
    {
        SceneBuilder sb;
        std::vector<std::uint8_t> c;
        put_u32(c, 1);
        put_u32(c, 0x40000000u);  // a dictionary claiming 2^30 entries
        sb.node_chunk("nGRP", c);
        check("dict.vox", sb, {"chunk 'nGRP'", "dictionary of 1073741824 entries"});
    }
}

TEST(VoxScene, ShippedModelsHaveNoSceneGraph) {
    // Every model shipped in data/vox is one model without a scene graph: its world is that
    // model, as before (the scene tests above cover graphs).
    for (const Expected& e : kModels) {
        const VoxScene s = read_vox_scene(kData / e.file);
        std::cout << e.file << ": " << s.models.size() << " model(s), "
                  << (s.has_scene_graph ? "scene graph with " : "no scene graph, ")
                  << s.instances.size() << " visible instance(s), " << s.hidden_instances
                  << " hidden; world " << s.dims.to_string() << "\n";
        EXPECT_EQ(s.models.size(), 1u) << e.file;
        EXPECT_FALSE(s.has_scene_graph) << e.file;
        EXPECT_EQ(s.instances.size(), 1u) << e.file;
        EXPECT_EQ(s.dims, (Dims{e.vox_size.x, e.vox_size.z, e.vox_size.y})) << e.file;
    }
}

}  // namespace
}  // namespace voxfield
