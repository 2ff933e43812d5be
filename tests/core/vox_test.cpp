#include <gtest/gtest.h>

#include <unistd.h>

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "test_util.hpp"
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
    vb.chunk("nTRN", std::vector<std::uint8_t>(28, 0xAB));
    vb.chunk("MATL", std::vector<std::uint8_t>(13, 0));
    vb.chunk("LAYR", std::vector<std::uint8_t>(5, 1), std::vector<std::uint8_t>(12, 0));
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
                       {"model.obj", "'.obj'", ".vox or .npy"});
    test::write_text(dir / "noext", "x");
    expect_input_error([&] { load_world(dir / "noext"); }, {"noext", ".vox or .npy"});
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

}  // namespace
}  // namespace voxfield
