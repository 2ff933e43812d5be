// PNG output (see png.hpp).
#include "png.hpp"

#include <stdexcept>
#include <string>

#include "cli_util.hpp"

#define STB_IMAGE_WRITE_IMPLEMENTATION
#define STB_IMAGE_WRITE_STATIC
#include <stb/stb_image_write.h>

namespace voxfield::cli {
namespace {

void append_bytes(void* context, void* data, int size) {
    static_cast<std::string*>(context)->append(static_cast<const char*>(data),
                                               static_cast<std::size_t>(size));
}

}  // namespace

std::string encode_png(const vk::Image& image) {
    std::string png;
    if (stbi_write_png_to_func(append_bytes, &png, static_cast<int>(image.width),
                               static_cast<int>(image.height), 4, image.rgba.data(),
                               static_cast<int>(image.width * 4)) == 0) {
        throw std::runtime_error("PNG encoding failed for " + std::to_string(image.width) + "x" +
                                 std::to_string(image.height));
    }
    return png;
}

void write_png(const std::filesystem::path& path, const vk::Image& image) {
    write_text_file(path, encode_png(image));
}

}  // namespace voxfield::cli
