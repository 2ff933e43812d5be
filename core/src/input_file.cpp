#include "input_file.hpp"

#include <cerrno>
#include <string>
#include <system_error>

#include "voxfield/core/error.hpp"

namespace voxfield::detail {

namespace fs = std::filesystem;

std::ifstream open_input(const fs::path& path, std::uint64_t& size) {
    std::error_code ec;
    const auto st = fs::status(path, ec);
    if (!fs::exists(st)) {
        throw InputError("'" + path.string() + "': no such file");
    }
    if (fs::is_directory(st)) {
        throw InputError("'" + path.string() + "': is a directory, not a file");
    }
    std::ifstream in(path, std::ios::binary);
    if (!in) {
        throw InputError("'" + path.string() + "': cannot open for reading (" +
                         std::generic_category().message(errno) + ")");
    }
    in.seekg(0, std::ios::end);
    const auto end = in.tellg();
    in.seekg(0, std::ios::beg);
    if (end < 0 || !in) {
        throw InputError("'" + path.string() + "': cannot read (not a regular file?)");
    }
    size = static_cast<std::uint64_t>(end);
    return in;
}

}  // namespace voxfield::detail
