#pragma once
// Writing an output file atomically (internal to core/): a temporary file in the same folder,
// renamed on success, so that readers never see a partial file.
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <span>

namespace voxfield::detail {

// Writes the concatenation of `parts` to `path`. Throws InputError naming the file when its
// folder does not exist, it is a directory, or any write fails (the temporary is removed).
void write_file_atomic(const std::filesystem::path& path,
                       std::initializer_list<std::span<const std::uint8_t>> parts);

}  // namespace voxfield::detail
