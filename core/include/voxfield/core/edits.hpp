#pragma once
// The `replay` edit file (DESIGN §4): one edit per line,
//     place|erase|paint sphere|cube X Y Z R [MATERIAL]
// X, Y, Z, R are decimal integers in int32 range (an optional sign; R >= 0); MATERIAL is
// 1..255, allowed for place and paint only, default 1. Fields are separated by spaces or
// tabs; `#` starts a comment that runs to the end of the line; blank and comment-only lines
// are skipped; CRLF line endings are accepted. Names are lower case.
#include <cstddef>
#include <filesystem>
#include <istream>
#include <string>
#include <vector>

#include "voxfield/core/brush.hpp"

namespace voxfield {

struct Edit {
    Brush brush;
    std::size_t line = 0;  // 1-based line number in the file (counting every line)
    std::string text;      // the edit's fields as written, comment and outer blanks removed
};

// Parses the whole stream before returning: either every edit in file order, or an
// InputError for the first bad line with the message "NAME:LINE: what is wrong (what is
// expected)". `name` is the file name used in messages.
std::vector<Edit> parse_edits(std::istream& in, const std::string& name);

// Opens and parses a file; messages use path.string() as the name. InputError for a missing
// or unreadable file, too.
std::vector<Edit> read_edits(const std::filesystem::path& path);

}  // namespace voxfield
