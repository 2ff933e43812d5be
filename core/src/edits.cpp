// The `replay` edit file (DESIGN §4): place|erase|paint sphere|cube X Y Z R [MATERIAL].
#include "voxfield/core/edits.hpp"

#include <charconv>
#include <cstdint>
#include <fstream>
#include <limits>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include "input_file.hpp"
#include "voxfield/core/error.hpp"

namespace voxfield {

namespace {

constexpr std::string_view kBlanks = " \t\r\v\f";

// A field quoted for a message: at most 32 characters, control bytes as \xNN.
std::string quote(std::string_view field) {
    constexpr std::size_t kMax = 32;
    std::string s = "'";
    for (std::size_t i = 0; i < field.size() && i < kMax; ++i) {
        const auto c = static_cast<unsigned char>(field[i]);
        if (c < 0x20 || c >= 0x7f) {
            static constexpr char kHex[] = "0123456789abcdef";
            s += "\\x";
            s += kHex[c >> 4];
            s += kHex[c & 15];
        } else {
            s += static_cast<char>(c);
        }
    }
    if (field.size() > kMax) {
        s += "...";
    }
    s += "'";
    return s;
}

std::vector<std::string_view> split_fields(std::string_view text) {
    std::vector<std::string_view> fields;
    std::size_t pos = text.find_first_not_of(kBlanks);
    while (pos != std::string_view::npos) {
        const std::size_t end = text.find_first_of(kBlanks, pos);
        fields.push_back(text.substr(pos, end == std::string_view::npos ? end : end - pos));
        pos = end == std::string_view::npos ? end : text.find_first_not_of(kBlanks, end);
    }
    return fields;
}

class LineParser {
  public:
    LineParser(const std::string& name, std::size_t line) : name_(name), line_(line) {}

    Brush parse(const std::vector<std::string_view>& f) {
        Brush b;
        if (f[0] == "place") {
            b.op = BrushOp::place;
        } else if (f[0] == "erase") {
            b.op = BrushOp::erase;
        } else if (f[0] == "paint") {
            b.op = BrushOp::paint;
        } else {
            fail("unknown operation " + quote(f[0]) +
                 " (expected place, erase or paint, then sphere|cube X Y Z R [MATERIAL])");
        }
        const std::string op = to_string(b.op);
        if (f.size() < 2) {
            fail("missing shape after '" + op + "' (expected " + usage(op, "sphere|cube") + ")");
        }
        if (f[1] == "sphere") {
            b.shape = BrushShape::sphere;
        } else if (f[1] == "cube") {
            b.shape = BrushShape::cube;
        } else {
            fail("unknown shape " + quote(f[1]) + " (expected sphere or cube)");
        }
        const std::string expected = "expected " + usage(op, to_string(b.shape));
        if (f.size() < 6) {
            static constexpr const char* kNames[] = {"X", "Y", "Z", "R"};
            std::string missing;
            for (std::size_t i = f.size(); i < 6; ++i) {
                missing += missing.empty() ? "" : ", ";
                missing += kNames[i - 2];
            }
            fail("missing " + missing + " (" + expected + ")");
        }
        if (b.op == BrushOp::erase && f.size() >= 7) {
            fail("erase takes no MATERIAL, got " + quote(f[6]) + " (" + expected + ")");
        }
        if (f.size() > 7) {
            fail("extra field " + quote(f[7]) + " after MATERIAL (" + expected + ")");
        }
        b.centre.x = integer(f[2], "X", std::numeric_limits<std::int32_t>::min());
        b.centre.y = integer(f[3], "Y", std::numeric_limits<std::int32_t>::min());
        b.centre.z = integer(f[4], "Z", std::numeric_limits<std::int32_t>::min());
        b.radius = integer(f[5], "radius R", 0);
        if (f.size() == 7) {
            b.material = static_cast<std::uint8_t>(integer(f[6], "MATERIAL", 1, 255));
        }
        return b;
    }

  private:
    static std::string usage(const std::string& op, const std::string& shape) {
        return "'" + op + " " + shape + " X Y Z R" + (op == "erase" ? "" : " [MATERIAL]") + "'";
    }

    // A decimal integer in lo..hi (lo <= 0 or lo == 1): an optional + or - sign, then digits.
    std::int64_t integer(std::string_view text, const std::string& what, std::int64_t lo,
                         std::int64_t hi = std::numeric_limits<std::int32_t>::max()) const {
        const std::string expected =
            "(expected an integer in " + std::to_string(lo) + ".." + std::to_string(hi) + ")";
        std::string_view digits = text;
        const bool negative = !digits.empty() && digits.front() == '-';
        if (!digits.empty() && (digits.front() == '+' || digits.front() == '-')) {
            digits.remove_prefix(1);
        }
        if (digits.empty() || digits.find_first_not_of("0123456789") != std::string_view::npos) {
            fail(what + " " + quote(text) + " is not a whole number " + expected);
        }
        std::uint64_t magnitude = 0;
        const auto r = std::from_chars(digits.data(), digits.data() + digits.size(), magnitude);
        const bool overflow = r.ec == std::errc::result_out_of_range;
        if (negative && lo == 0 && (overflow || magnitude != 0)) {
            fail(what + " " + quote(text) + " is negative " + expected);
        }
        const std::uint64_t limit =
            negative ? (lo < 0 ? std::uint64_t{0} - static_cast<std::uint64_t>(lo) : 0)
                     : static_cast<std::uint64_t>(hi);
        if (overflow || magnitude > limit) {
            fail(what + " " + quote(text) + " is out of range " + expected);
        }
        const std::int64_t value =
            negative ? -static_cast<std::int64_t>(magnitude) : static_cast<std::int64_t>(magnitude);
        if (value < lo) {
            fail(what + " " + quote(text) + " is out of range " + expected);
        }
        return value;
    }

    [[noreturn]] void fail(const std::string& what) const {
        throw InputError(name_ + ":" + std::to_string(line_) + ": " + what);
    }

    const std::string& name_;
    std::size_t line_;
};

}  // namespace

std::vector<Edit> parse_edits(std::istream& in, const std::string& name) {
    std::vector<Edit> edits;
    std::string line;
    std::size_t number = 0;
    while (std::getline(in, line)) {
        ++number;
        std::string_view text = line;
        text = text.substr(0, text.find('#'));
        const std::vector<std::string_view> fields = split_fields(text);
        if (fields.empty()) {
            continue;
        }
        Edit e;
        e.brush = LineParser(name, number).parse(fields);
        e.line = number;
        const auto first = static_cast<std::size_t>(fields.front().data() - text.data());
        const auto last =
            static_cast<std::size_t>(fields.back().data() - text.data()) + fields.back().size();
        e.text = std::string(text.substr(first, last - first));
        edits.push_back(std::move(e));
    }
    if (in.bad()) {
        throw InputError(name + ":" + std::to_string(number + 1) + ": read error");
    }
    return edits;
}

std::vector<Edit> read_edits(const std::filesystem::path& path) {
    std::uint64_t size = 0;
    std::ifstream in = detail::open_input(path, size);
    return parse_edits(in, path.string());
}

}  // namespace voxfield
