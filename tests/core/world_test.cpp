#include <gtest/gtest.h>

#include "test_util.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield {
namespace {

using test::expect_input_error;

TEST(Dims, ParseCubeAndTriple) {
    EXPECT_EQ(parse_dims("64"), (Dims{64, 64, 64}));
    EXPECT_EQ(parse_dims("1"), (Dims{1, 1, 1}));
    EXPECT_EQ(parse_dims("3,5,7"), (Dims{3, 5, 7}));
    EXPECT_EQ(parse_dims("4294967295,1,1"), (Dims{4294967295u, 1, 1}));
}

TEST(Dims, ParseRejectsBadText) {
    for (const std::string bad : {"", "0", "3,0,2", "3,4", "1,2,3,4", "-3", "abc", "3,,4", " 3",
                                  "3.5", "4294967296", "1,2,", "x"}) {
        expect_input_error([&] { parse_dims(bad); }, {"'" + bad + "'"});
    }
}

TEST(Dims, ToStringIndexContains) {
    const Dims d{3, 4, 5};
    EXPECT_EQ(d.to_string(), "3x4x5");
    EXPECT_EQ(d.count(), 60u);
    EXPECT_EQ(d.index(0, 0, 0), 0u);
    EXPECT_EQ(d.index(1, 0, 0), 1u);
    EXPECT_EQ(d.index(0, 1, 0), 3u);
    EXPECT_EQ(d.index(0, 0, 1), 12u);
    EXPECT_EQ(d.index(2, 3, 4), 59u);
    EXPECT_TRUE(d.contains(2, 3, 4));
    EXPECT_FALSE(d.contains(3, 0, 0));
    EXPECT_FALSE(d.contains(-1, 0, 0));
    EXPECT_FALSE(d.contains(0, 0, 5));
}

TEST(World, ConstructSetAndCount) {
    World w(Dims{3, 4, 5});
    EXPECT_EQ(w.size(), 60u);
    EXPECT_EQ(w.solid_count(), 0u);
    w.set(2, 3, 4, 7);
    w.set(0, 1, 0, 1);
    EXPECT_EQ(w.at(2, 3, 4), 7);
    EXPECT_EQ(w.voxels()[59], 7);
    EXPECT_EQ(w.voxels()[3], 1);
    EXPECT_EQ(w.solid_count(), 2u);
}

TEST(World, RejectsZeroAxesAndWrongSizes) {
    expect_input_error([] { World w(Dims{0, 4, 4}); }, {"0x4x4"});
    expect_input_error([] { World w(Dims{4, 4, 0}); }, {"4x4x0"});
    expect_input_error(
        [] {
            World w(Dims{2, 2, 2}, std::vector<std::uint8_t>(7));
        },
        {"2x2x2", "8", "7"});
    expect_input_error([] { World w(Dims{4294967295u, 4294967295u, 4294967295u}); }, {"too many"});
    World ok(Dims{2, 2, 2}, std::vector<std::uint8_t>{0, 1, 0, 1, 0, 0, 0, 9});
    EXPECT_EQ(ok.solid_count(), 3u);
    EXPECT_EQ(ok.at(1, 1, 1), 9);
}

}  // namespace
}  // namespace voxfield
