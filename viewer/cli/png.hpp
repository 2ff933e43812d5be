#pragma once
// PNG output of `render` and `view` (stb_image_write).
#include <filesystem>

#include "voxfield/vk/raymarcher.hpp"

namespace voxfield::cli {

// Writes `image` (RGBA8) to `path` atomically: never a partial file.
void write_png(const std::filesystem::path& path, const vk::Image& image);

}  // namespace voxfield::cli
