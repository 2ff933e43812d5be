#pragma once
// Opening an input file with the project's messages (internal to core/).
#include <cstdint>
#include <filesystem>
#include <fstream>

namespace voxfield::detail {

// Opens `path` for binary reading and sets `size` to its length; InputError for a missing,
// directory, unreadable or unseekable path.
std::ifstream open_input(const std::filesystem::path& path, std::uint64_t& size);

}  // namespace voxfield::detail
