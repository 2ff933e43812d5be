#include <gtest/gtest.h>

#include <sstream>
#include <string>
#include <vector>

#include "test_util.hpp"
#include "voxfield/core/edits.hpp"
#include "voxfield/core/error.hpp"

namespace voxfield {
namespace {

using test::expect_input_error;

std::vector<Edit> parse(const std::string& text, const std::string& name = "edits.txt") {
    std::istringstream in(text);
    return parse_edits(in, name);
}

// Parsing `text` must fail with a message that starts with exactly `prefix` and contains
// every one of `parts`.
void expect_parse_error(const std::string& text, const std::string& prefix,
                        const std::vector<std::string>& parts) {
    try {
        parse(text);
        ADD_FAILURE() << "expected InputError for:\n" << text;
    } catch (const InputError& e) {
        const std::string msg = e.what();
        EXPECT_EQ(msg.rfind(prefix, 0), 0u)
            << "message '" << msg << "' lacks prefix '" << prefix << "'";
        for (const auto& part : parts) {
            EXPECT_NE(msg.find(part), std::string::npos)
                << "message '" << msg << "' lacks '" << part << "'";
        }
        EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    }
}

TEST(Edits, ParsesEveryOpAndShape) {
    const auto edits = parse(
        "place sphere 1 2 3 4\n"
        "erase cube -5 0 7 0\n"
        "paint sphere 10 20 30 2 17\n"
        "place cube 0 0 0 1 255\n");
    ASSERT_EQ(edits.size(), 4u);
    EXPECT_EQ(edits[0].brush, (Brush{BrushOp::place, BrushShape::sphere, {1, 2, 3}, 4, 1}));
    EXPECT_EQ(edits[1].brush, (Brush{BrushOp::erase, BrushShape::cube, {-5, 0, 7}, 0, 1}));
    EXPECT_EQ(edits[2].brush, (Brush{BrushOp::paint, BrushShape::sphere, {10, 20, 30}, 2, 17}));
    EXPECT_EQ(edits[3].brush, (Brush{BrushOp::place, BrushShape::cube, {0, 0, 0}, 1, 255}));
    for (std::size_t i = 0; i < 4; ++i) {
        EXPECT_EQ(edits[i].line, i + 1);
    }
    EXPECT_EQ(edits[2].text, "paint sphere 10 20 30 2 17");
}

TEST(Edits, DefaultMaterialIsOne) {
    const auto edits = parse("paint cube 1 1 1 1\nplace sphere 1 1 1 1\n");
    ASSERT_EQ(edits.size(), 2u);
    EXPECT_EQ(edits[0].brush.material, 1);
    EXPECT_EQ(edits[1].brush.material, 1);
}

TEST(Edits, CommentsBlankLinesAndLineNumbers) {
    const auto edits = parse(
        "# a replay file\n"
        "\n"
        "   \t \n"
        "place sphere 1 2 3 4   # trailing comment\n"
        "#erase cube 1 1 1 1\n"
        "\tpaint\tcube\t5  6 7\t8 3#no space before the comment\n"
        "   # indented comment\n"
        "erase sphere 0 0 0 1");  // no final newline
    ASSERT_EQ(edits.size(), 3u);
    EXPECT_EQ(edits[0].line, 4u);
    EXPECT_EQ(edits[0].text, "place sphere 1 2 3 4");
    EXPECT_EQ(edits[0].brush, (Brush{BrushOp::place, BrushShape::sphere, {1, 2, 3}, 4, 1}));
    EXPECT_EQ(edits[1].line, 6u);
    EXPECT_EQ(edits[1].text, "paint\tcube\t5  6 7\t8 3");
    EXPECT_EQ(edits[1].brush, (Brush{BrushOp::paint, BrushShape::cube, {5, 6, 7}, 8, 3}));
    EXPECT_EQ(edits[2].line, 8u);
    EXPECT_EQ(edits[2].brush.op, BrushOp::erase);
}

TEST(Edits, EmptyAndCommentOnlyFilesGiveNoEdits) {
    EXPECT_TRUE(parse("").empty());
    EXPECT_TRUE(parse("\n\n# nothing\n  # here\r\n").empty());
}

TEST(Edits, CrlfLineEndings) {
    const auto edits = parse("# header\r\nplace cube 1 2 3 4 5\r\n\r\nerase sphere 0 0 0 2\r\n");
    ASSERT_EQ(edits.size(), 2u);
    EXPECT_EQ(edits[0].line, 2u);
    EXPECT_EQ(edits[0].brush, (Brush{BrushOp::place, BrushShape::cube, {1, 2, 3}, 4, 5}));
    EXPECT_EQ(edits[0].text, "place cube 1 2 3 4 5");
    EXPECT_EQ(edits[1].line, 4u);
    EXPECT_EQ(edits[1].brush.radius, 2);
    // An error on a CRLF line still names the right line, and the '\r' is not in the field.
    expect_parse_error("place cube 1 2 3 4\r\nplace cube 1 2 3 4 0\r\n",
                       "edits.txt:2: ", {"MATERIAL '0'", "1..255"});
}

TEST(Edits, Int32LimitsAndSigns) {
    const auto edits = parse(
        "place cube -2147483648 2147483647 +5 2147483647\n"
        "erase sphere -0 +0 0 +0\n");
    ASSERT_EQ(edits.size(), 2u);
    EXPECT_EQ(edits[0].brush.centre, (Int3{-2147483648LL, 2147483647LL, 5}));
    EXPECT_EQ(edits[0].brush.radius, 2147483647);
    EXPECT_EQ(edits[1].brush.centre, (Int3{0, 0, 0}));
    EXPECT_EQ(edits[1].brush.radius, 0);
    EXPECT_EQ(parse("place cube 1 1 1 1 007\n")[0].brush.material, 7);
}

TEST(Edits, UnknownOperation) {
    expect_parse_error("place cube 1 1 1 1\nfill cube 1 1 1 1\n",
                       "edits.txt:2: ", {"unknown operation 'fill'", "place, erase or paint"});
    expect_parse_error("Place cube 1 1 1 1\n",
                       "edits.txt:1: ", {"'Place'", "place, erase or paint"});
    expect_parse_error("\n\n1 2 3\n", "edits.txt:3: ", {"unknown operation '1'"});
}

TEST(Edits, UnknownShape) {
    expect_parse_error("place ball 1 1 1 1\n",
                       "edits.txt:1: ", {"unknown shape 'ball'", "sphere or cube"});
    expect_parse_error("# x\nerase Cube 1 1 1 1\n", "edits.txt:2: ", {"'Cube'", "sphere or cube"});
    expect_parse_error("paint 1 1 1 1 1\n", "edits.txt:1: ", {"unknown shape '1'"});
}

TEST(Edits, MissingFields) {
    expect_parse_error(
        "place\n", "edits.txt:1: ", {"missing shape", "'place sphere|cube X Y Z R [MATERIAL]'"});
    expect_parse_error("erase  # comment\n",
                       "edits.txt:1: ", {"missing shape", "'erase sphere|cube X Y Z R'"});
    expect_parse_error("place sphere\n", "edits.txt:1: ",
                       {"missing X, Y, Z, R", "'place sphere X Y Z R [MATERIAL]'"});
    expect_parse_error("place cube 1 2\n", "edits.txt:1: ", {"missing Z, R"});
    expect_parse_error("\n\n\n\nerase cube 1 2 3\n",
                       "edits.txt:5: ", {"missing R", "'erase cube X Y Z R'"});
    expect_parse_error("paint sphere 1 2 3 # 4\n", "edits.txt:1: ", {"missing R"});
}

TEST(Edits, ExtraFields) {
    expect_parse_error("place sphere 1 2 3 4 5 6\n",
                       "edits.txt:1: ", {"extra field '6'", "'place sphere X Y Z R [MATERIAL]'"});
    expect_parse_error("paint cube 1 2 3 4 5 junk more\n", "edits.txt:1: ", {"extra field 'junk'"});
}

TEST(Edits, MaterialOnlyForPlaceAndPaint) {
    expect_parse_error("erase sphere 1 2 3 4 5\n", "edits.txt:1: ",
                       {"erase takes no MATERIAL", "'5'", "'erase sphere X Y Z R'"});
    expect_parse_error("erase cube 1 2 3 4 5 6\n", "edits.txt:1: ", {"erase takes no MATERIAL"});
}

TEST(Edits, MaterialRange) {
    for (const std::string bad : {"0", "256", "-1", "1000", "99999999999999999999999"}) {
        expect_parse_error("place cube 1 2 3 4 " + bad + "\n",
                           "edits.txt:1: ", {"MATERIAL '" + bad + "' is out of range", "1..255"});
        expect_parse_error("\npaint sphere 1 2 3 4 " + bad + "\n",
                           "edits.txt:2: ", {"MATERIAL", "out of range", "1..255"});
    }
    expect_parse_error("place cube 1 2 3 4 red\n",
                       "edits.txt:1: ", {"MATERIAL 'red' is not a whole number", "1..255"});
}

TEST(Edits, NonNumericValues) {
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"place cube x 2 3 4", "X 'x'"},       {"place cube 1 2.5 3 4", "Y '2.5'"},
        {"place cube 1 2 3e2 4", "Z '3e2'"},   {"place cube 1 2 3 four", "radius R 'four'"},
        {"place cube 0x10 2 3 4", "X '0x10'"}, {"place cube - 2 3 4", "X '-'"},
        {"place cube +-1 2 3 4", "X '+-1'"},   {"place cube 1 2 3 --4", "radius R '--4'"},
        {"place cube 1, 2 3 4", "X '1,'"},     {"place cube 1 2 3 4 5a", "MATERIAL '5a'"},
    };
    for (const auto& [line, part] : cases) {
        expect_parse_error("# c\n" + line + "\n", "edits.txt:2: ",
                           {part, "is not a whole number", "expected an integer in"});
    }
    // Control bytes are shown escaped so the message stays on one printable line.
    expect_parse_error(std::string("place cube 1\x01 2 3 4\n"), "edits.txt:1: ", {"'1\\x01'"});
}

TEST(Edits, ValuesOutOfInt32Range) {
    expect_parse_error("place cube 2147483648 0 0 1\n", "edits.txt:1: ",
                       {"X '2147483648' is out of range", "-2147483648..2147483647"});
    expect_parse_error("place cube 0 -2147483649 0 1\n",
                       "edits.txt:1: ", {"Y '-2147483649' is out of range"});
    expect_parse_error("place cube 0 0 99999999999999999999999999 1\n",
                       "edits.txt:1: ", {"Z '99999999999999999999999999' is out of range"});
    expect_parse_error("place cube 0 0 0 2147483648\n",
                       "edits.txt:1: ", {"radius R '2147483648' is out of range", "0..2147483647"});
}

TEST(Edits, NegativeRadius) {
    expect_parse_error("place sphere 1 2 3 -1\n",
                       "edits.txt:1: ", {"radius R '-1' is negative", "0..2147483647"});
    expect_parse_error("\nerase cube 1 2 3 -99999999999999999999\n",
                       "edits.txt:2: ", {"radius R", "is negative"});
}

TEST(Edits, FirstBadLineWinsAndNothingIsReturned) {
    // Good lines before and after do not matter: the whole file is rejected.
    expect_parse_error("place cube 1 1 1 1\nplace cube 1 1 1\nfill cube\n",
                       "edits.txt:2: ", {"missing R"});
}

TEST(Edits, NameIsUsedAsIs) {
    try {
        std::istringstream in("\nerase cube 1 1 1 1 1\n");
        parse_edits(in, "/tmp/some dir/strokes.txt");
        ADD_FAILURE() << "expected InputError";
    } catch (const InputError& e) {
        EXPECT_EQ(std::string(e.what()).rfind("/tmp/some dir/strokes.txt:2: ", 0), 0u) << e.what();
    }
}

TEST(Edits, ReadFromFile) {
    test::TempDir dir;
    const auto good = dir / "good.txt";
    test::write_text(good, "place sphere 4 4 4 2 3\r\n# c\nerase cube 4 4 4 1\n");
    const auto edits = read_edits(good);
    ASSERT_EQ(edits.size(), 2u);
    EXPECT_EQ(edits[0].brush, (Brush{BrushOp::place, BrushShape::sphere, {4, 4, 4}, 2, 3}));
    EXPECT_EQ(edits[1].line, 3u);

    const auto bad = dir / "bad.txt";
    test::write_text(bad, "place sphere 4 4 4 2 3\npaint cube 1 1 1 1 0\n");
    expect_input_error([&] { read_edits(bad); }, {bad.string() + ":2: ", "MATERIAL '0'"});
    try {
        read_edits(bad);
    } catch (const InputError& e) {
        EXPECT_EQ(std::string(e.what()).rfind(bad.string() + ":2: ", 0), 0u) << e.what();
    }
    expect_input_error([&] { read_edits(dir / "missing.txt"); }, {"missing.txt", "no such file"});
    expect_input_error([&] { read_edits(dir.path()); }, {"is a directory"});
}

}  // namespace
}  // namespace voxfield
