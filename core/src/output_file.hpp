#pragma once
// The output writer's entry point for core's own writers (npy.cpp, vox.cpp); the rules are in
// voxfield/core/output.hpp.
#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <span>

#include "voxfield/core/output.hpp"

namespace voxfield::detail {

// write_output_file: a temporary beside a regular or new target renamed onto it, a character
// device or FIFO written directly; InputError for a refused target, OutputError on a failed
// write (the temporary removed).
void write_file_atomic(const std::filesystem::path& path,
                       std::initializer_list<std::span<const std::uint8_t>> parts);

}  // namespace voxfield::detail
