#pragma once
// PNG output of `render` and `view` (stb_image_write).
#include <filesystem>
#include <string>

#include "voxfield/vk/raymarcher.hpp"

namespace voxfield::cli {

// `image` (RGBA8) as the bytes of a PNG file.
std::string encode_png(const vk::Image& image);
// Writes `image` to `path` through the output writer: never a partial file.
void write_png(const std::filesystem::path& path, const vk::Image& image);

}  // namespace voxfield::cli
