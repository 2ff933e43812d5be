#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "test_util.hpp"
#include "voxfield/core/format.hpp"

namespace voxfield {
namespace {

using test::expect_input_error;

TEST(Format, ParseAndNames) {
    for (Format f : {Format::u8, Format::u16, Format::u32, Format::packed32}) {
        EXPECT_EQ(parse_format(to_string(f)), f);
    }
    EXPECT_EQ(to_string(Format::packed32), "packed32");
    for (const std::string bad : {"", "U8", "u64", "packed", "float"}) {
        expect_input_error([&] { parse_format(bad); },
                           {"'" + bad + "'", "u8", "u16", "u32", "packed32"});
    }
    EXPECT_EQ(element_size(Format::u8), 1u);
    EXPECT_EQ(element_size(Format::u16), 2u);
    EXPECT_EQ(element_size(Format::u32), 4u);
    EXPECT_EQ(element_size(Format::packed32), 4u);
    EXPECT_EQ(max_distance(Format::u8), 255u);
    EXPECT_EQ(max_distance(Format::u16), 65535u);
    EXPECT_EQ(max_distance(Format::u32), 4294967295u);
    EXPECT_EQ(max_distance(Format::packed32), 255u);
}

// A 6x1x1 world: solid colour 2 (white, rgb332 0xFF) at x=0, colour 4 (red) at x=5.
struct Fixture {
    World world{Dims{6, 1, 1}};
    Palette palette = Palette::dissertation();
    std::vector<std::uint32_t> d{0, 254, 255, 256, kInfinite, 0};
    Fixture() {
        world.set(0, 0, 0, 2);
        world.set(5, 0, 0, 4);
    }
};

TEST(Format, EncodeU8Saturates) {
    Fixture fx;
    const auto out = encode_field(fx.d, fx.world, fx.palette, Format::u8);
    EXPECT_EQ(out, (std::vector<std::uint8_t>{0, 254, 255, 255, 255, 0}));
    for (std::size_t i = 0; i < 6; ++i) {
        EXPECT_EQ(decode_distance(out, Format::u8, i), std::min<std::uint32_t>(fx.d[i], 255));
    }
}

TEST(Format, EncodeU16SaturatesLittleEndian) {
    Fixture fx;
    fx.d = {0, 255, 256, 65535, 65536, kInfinite};
    const auto out = encode_field(fx.d, fx.world, fx.palette, Format::u16);
    EXPECT_EQ(out, (std::vector<std::uint8_t>{0, 0, 255, 0, 0, 1, 255, 255, 255, 255, 255, 255}));
    EXPECT_EQ(decode_distance(out, Format::u16, 2), 256u);
    EXPECT_EQ(decode_distance(out, Format::u16, 4), 65535u);
}

TEST(Format, EncodeU32KeepsEverything) {
    Fixture fx;
    fx.d = {0, 0x01020304u, 65536, kInfinite - 1, kInfinite, 7};
    const auto out = encode_field(fx.d, fx.world, fx.palette, Format::u32);
    ASSERT_EQ(out.size(), 24u);
    EXPECT_EQ(out[4], 0x04);
    EXPECT_EQ(out[5], 0x03);
    EXPECT_EQ(out[6], 0x02);
    EXPECT_EQ(out[7], 0x01);
    for (std::size_t i = 0; i < 6; ++i) {
        EXPECT_EQ(decode_distance(out, Format::u32, i), fx.d[i]);
    }
}

TEST(Format, EncodePacked32) {
    Fixture fx;
    const auto out = encode_field(fx.d, fx.world, fx.palette, Format::packed32);
    ASSERT_EQ(out.size(), 24u);
    auto word = [&](std::size_t i) {
        return std::uint32_t{out[4 * i]} | std::uint32_t{out[4 * i + 1]} << 8 |
               std::uint32_t{out[4 * i + 2]} << 16 | std::uint32_t{out[4 * i + 3]} << 24;
    };
    EXPECT_EQ(word(0), 0xFFu);      // d 0, white
    EXPECT_EQ(word(1), 254u << 8);  // air: colour byte 0
    EXPECT_EQ(word(2), 255u << 8);
    EXPECT_EQ(word(3), 255u << 8);            // 256 saturates, never wraps to 0
    EXPECT_EQ(word(4), 255u << 8);            // kInfinite saturates
    EXPECT_EQ(word(5), std::uint32_t{0xE0});  // red 7,0,0
    EXPECT_EQ(decode_distance(out, Format::packed32, 3), 255u);
    EXPECT_EQ(decode_distance(out, Format::packed32, 5), 0u);
    EXPECT_THROW(decode_distance(out, Format::packed32, 6), std::out_of_range);
}

TEST(Format, EncodeRejectsSizeMismatch) {
    Fixture fx;
    fx.d.pop_back();
    EXPECT_THROW(encode_field(fx.d, fx.world, fx.palette, Format::u8), std::invalid_argument);
}

}  // namespace
}  // namespace voxfield
