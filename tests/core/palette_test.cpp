#include <gtest/gtest.h>

#include <array>
#include <cstdint>

#include "voxfield/core/palette.hpp"

namespace voxfield {
namespace {

// Entries of MagicaVoxel's default_palette as the .vox spec lists them (0xAABBGGRR).
Rgba abgr(std::uint32_t v) {
    return Rgba{static_cast<std::uint8_t>(v), static_cast<std::uint8_t>(v >> 8),
                static_cast<std::uint8_t>(v >> 16), static_cast<std::uint8_t>(v >> 24)};
}

TEST(Palette, DefaultMatchesSpecTable) {
    const Palette p;
    const std::array<std::pair<int, std::uint32_t>, 28> spec = {{
        {0, 0x00000000},   {1, 0xffffffff},   {2, 0xffccffff},   {3, 0xff99ffff},
        {6, 0xff00ffff},   {7, 0xffffccff},   {8, 0xffccccff},   {15, 0xff9999ff},
        {16, 0xff6699ff},  {31, 0xffff00ff},  {36, 0xff0000ff},  {37, 0xffffffcc},
        {48, 0xff00cccc},  {100, 0xff663399}, {128, 0xffcc6666}, {200, 0xffcc6600},
        {215, 0xff330000}, {216, 0xff0000ee}, {225, 0xff000011}, {226, 0xff00ee00},
        {235, 0xff001100}, {236, 0xffee0000}, {245, 0xff110000}, {246, 0xffeeeeee},
        {247, 0xffdddddd}, {250, 0xff888888}, {254, 0xff222222}, {255, 0xff111111},
    }};
    for (const auto& [i, v] : spec) {
        EXPECT_EQ(p[static_cast<std::uint8_t>(i)], abgr(v)) << "index " << i;
    }
    EXPECT_EQ(p[1], (Rgba{255, 255, 255, 255}));  // white
    EXPECT_EQ(Palette::magicavoxel_default()[77], p[77]);
    // Every non-zero entry is opaque, and the 215 cube colours are distinct.
    for (int i = 1; i < 256; ++i) {
        EXPECT_EQ(p[static_cast<std::uint8_t>(i)].a, 255) << i;
    }
    for (int i = 1; i <= 215; ++i) {
        for (int j = i + 1; j <= 215; ++j) {
            ASSERT_FALSE(p[static_cast<std::uint8_t>(i)] == p[static_cast<std::uint8_t>(j)])
                << i << " " << j;
        }
    }
}

TEST(Palette, ToRgb332) {
    EXPECT_EQ(to_rgb332(Rgba{255, 255, 255, 255}), 0xFF);
    EXPECT_EQ(to_rgb332(Rgba{0, 0, 0, 255}), 0x00);
    EXPECT_EQ(to_rgb332(Rgba{255, 0, 0, 255}), 0xE0);
    EXPECT_EQ(to_rgb332(Rgba{0, 255, 0, 255}), 0x1C);
    EXPECT_EQ(to_rgb332(Rgba{0, 0, 255, 255}), 0x03);
    EXPECT_EQ(to_rgb332(Rgba{0x9F, 0x40, 0x80, 0}), (4 << 5) | (2 << 2) | 2);
}

TEST(Palette, DissertationColoursAreTheSeedCodes) {
    // seed-code-notes.md, "Data layout": the 3/3/2-bit values Black 0,0,0; White 7,7,3; Grey
    // 5,5,2; Red 7,0,0; Pink 7,0,2; Purple 5,0,3; Blue 0,0,3; Cyan 0,7,3; Turquoise 0,7,2;
    // Green 0,7,0; Yellow 7,7,0, written out here as RGB332 bytes and as the 8-bit colours they
    // expand to (3 bits: 0 36 73 109 146 182 219 255; 2 bits: 0 85 170 255), not taken from the
    // production table.
    struct Named {
        const char* name;
        std::uint8_t rgb332;
        Rgba rgba;
    };
    const std::array<Named, 11> want = {{{"Black", 0x00, {0, 0, 0, 255}},
                                         {"White", 0xFF, {255, 255, 255, 255}},
                                         {"Grey", 0xB6, {182, 182, 170, 255}},
                                         {"Red", 0xE0, {255, 0, 0, 255}},
                                         {"Pink", 0xE2, {255, 0, 170, 255}},
                                         {"Purple", 0xA3, {182, 0, 255, 255}},
                                         {"Blue", 0x03, {0, 0, 255, 255}},
                                         {"Cyan", 0x1F, {0, 255, 255, 255}},
                                         {"Turquoise", 0x1E, {0, 255, 170, 255}},
                                         {"Green", 0x1C, {0, 255, 0, 255}},
                                         {"Yellow", 0xFC, {255, 255, 0, 255}}}};
    const Palette p = Palette::dissertation();
    const auto table = p.rgb332_table();
    for (std::size_t k = 0; k < want.size(); ++k) {
        const auto idx = static_cast<std::uint8_t>(k + 1);
        EXPECT_EQ(p[idx], want[k].rgba) << want[k].name;
        EXPECT_EQ(table[idx], want[k].rgb332) << want[k].name;
    }
    // Beyond 11 it is MagicaVoxel's default.
    EXPECT_EQ(p[12], Palette()[12]);
    EXPECT_EQ(p[255], Palette()[255]);
}

TEST(Palette, ExpansionRoundTripsEveryRgb332Value) {
    // Every 3-bit value v expands to round(v*255/7) whose top 3 bits are v (and 2-bit likewise).
    for (int v = 0; v < 8; ++v) {
        const int e = (v * 255 + 3) / 7;
        EXPECT_EQ(e >> 5, v);
    }
    for (int v = 0; v < 4; ++v) {
        const int e = (v * 255 + 1) / 3;
        EXPECT_EQ(e >> 6, v);
    }
}

TEST(Palette, AirIsZeroInRgb332Table) {
    Palette p;
    p[0] = Rgba{255, 255, 255, 255};
    const auto t = p.rgb332_table();
    EXPECT_EQ(t[0], 0);
    EXPECT_EQ(t[1], 0xFF);
    EXPECT_EQ(Palette::dissertation().rgb332_table()[0], 0);
    for (int i = 1; i < 256; ++i) {
        EXPECT_EQ(t[static_cast<std::size_t>(i)], to_rgb332(p[static_cast<std::uint8_t>(i)]));
    }
}

}  // namespace
}  // namespace voxfield
