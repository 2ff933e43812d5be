// MagicaVoxel .vox reader (format: ephtracy/voxel-model, MagicaVoxel-file-format-vox.txt).
#include "voxfield/core/vox.hpp"

#include "input_file.hpp"
#include "output_file.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include "voxfield/core/error.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/sdf.hpp"

namespace voxfield {

namespace {

namespace fs = std::filesystem;

std::vector<std::uint8_t> read_file(const fs::path& path) {
    std::uint64_t size = 0;
    std::ifstream in = detail::open_input(path, size);
    std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
    in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
    if (static_cast<std::size_t>(in.gcount()) != bytes.size()) {
        throw InputError("'" + path.string() + "': read error");
    }
    return bytes;
}

std::uint32_t u32_at(const std::vector<std::uint8_t>& b, std::size_t off) {
    return static_cast<std::uint32_t>(b[off]) | (static_cast<std::uint32_t>(b[off + 1]) << 8) |
           (static_cast<std::uint32_t>(b[off + 2]) << 16) |
           (static_cast<std::uint32_t>(b[off + 3]) << 24);
}

// A chunk id for messages: printable characters as-is, anything else as \xNN.
std::string id_text(const std::vector<std::uint8_t>& b, std::size_t off) {
    std::string s;
    for (std::size_t k = 0; k < 4; ++k) {
        const unsigned char c = b[off + k];
        if (c >= 0x20 && c < 0x7f && c != '\'' && c != '\\') {
            s += static_cast<char>(c);
        } else {
            const char* hex = "0123456789abcdef";
            s += "\\x";
            s += hex[c >> 4];
            s += hex[c & 15];
        }
    }
    return s;
}

struct Chunk {
    std::string id;
    std::size_t offset = 0;   // of the chunk header
    std::size_t content = 0;  // offset of the content
    std::uint64_t content_size = 0;
    std::uint64_t children_size = 0;
};

class VoxParser {
  public:
    VoxParser(std::string file, const std::vector<std::uint8_t>& bytes)
        : file_(std::move(file)), b_(bytes) {}

    VoxModel parse() {
        if (b_.size() < 8) {
            fail("truncated: " + std::to_string(b_.size()) +
                 " bytes, shorter than the 8-byte 'VOX ' header");
        }
        if (std::memcmp(b_.data(), "VOX ", 4) != 0) {
            fail("not a MagicaVoxel file (magic is '" + id_text(b_, 0) + "', expected 'VOX ')");
        }
        const Chunk main = chunk_at(8, b_.size());
        if (main.id != "MAIN") {
            fail("first chunk is '" + main.id + "' at offset 8, expected 'MAIN'");
        }
        std::size_t pos = main.content + static_cast<std::size_t>(main.content_size);
        const std::size_t end = pos + static_cast<std::size_t>(main.children_size);

        bool have_size = false, have_xyzi = false, have_rgba = false;
        Dims vox_dims;
        Chunk xyzi;
        Palette palette;
        while (pos < end) {
            const Chunk c = chunk_at(pos, end);
            if (c.id == "SIZE" && !have_size) {
                need_content(c, 12);
                const std::uint32_t sx = u32_at(b_, c.content);
                const std::uint32_t sy = u32_at(b_, c.content + 4);
                const std::uint32_t sz = u32_at(b_, c.content + 8);
                for (std::uint32_t s : {sx, sy, sz}) {
                    if (s < 1 || s > 256) {
                        fail("chunk 'SIZE' at offset " + std::to_string(c.offset) + " gives " +
                             std::to_string(static_cast<std::int32_t>(sx)) + "x" +
                             std::to_string(static_cast<std::int32_t>(sy)) + "x" +
                             std::to_string(static_cast<std::int32_t>(sz)) +
                             " (each axis must be 1..256)");
                    }
                }
                vox_dims = {sx, sy, sz};
                have_size = true;
            } else if (c.id == "XYZI" && !have_xyzi) {
                if (!have_size) {
                    fail("chunk 'XYZI' at offset " + std::to_string(c.offset) +
                         " comes before any 'SIZE' chunk");
                }
                xyzi = c;
                have_xyzi = true;
            } else if (c.id == "RGBA" && !have_rgba) {
                need_content(c, 256 * 4);
                for (std::size_t i = 0; i < 255; ++i) {
                    const std::size_t o = c.content + 4 * i;
                    palette[static_cast<std::uint8_t>(i + 1)] =
                        Rgba{b_[o], b_[o + 1], b_[o + 2], b_[o + 3]};
                }
                have_rgba = true;
            }
            // PACK, later models, nTRN, nGRP, nSHP, MATL, MATT, LAYR, rOBJ, rCAM, NOTE, IMAP
            // and unknown chunks are skipped.
            pos = c.content + static_cast<std::size_t>(c.content_size + c.children_size);
        }
        if (!have_size) {
            fail("no 'SIZE' chunk in 'MAIN'");
        }
        if (!have_xyzi) {
            fail("no 'XYZI' chunk after the first 'SIZE'");
        }

        // vox (x, y, z) with z up -> world (x, z, y) with y up.
        World world(Dims{vox_dims.x, vox_dims.z, vox_dims.y});
        need_content(xyzi, 4);
        const std::uint32_t n = u32_at(b_, xyzi.content);
        const std::uint64_t need = 4 + std::uint64_t{n} * 4;
        if (need > xyzi.content_size) {
            fail("chunk 'XYZI' at offset " + std::to_string(xyzi.offset) + " declares " +
                 std::to_string(n) + " voxels (" + std::to_string(need) +
                 " bytes) but its content is " + std::to_string(xyzi.content_size) + " bytes");
        }
        for (std::uint32_t i = 0; i < n; ++i) {
            const std::size_t o = xyzi.content + 4 + 4 * std::size_t{i};
            const std::uint8_t x = b_[o], y = b_[o + 1], z = b_[o + 2], ci = b_[o + 3];
            if (x >= vox_dims.x || y >= vox_dims.y || z >= vox_dims.z) {
                fail("voxel " + std::to_string(i) + " at (" + std::to_string(x) + ", " +
                     std::to_string(y) + ", " + std::to_string(z) + ") is outside SIZE " +
                     vox_dims.to_string());
            }
            if (ci == 0) {
                fail("voxel " + std::to_string(i) + " at (" + std::to_string(x) + ", " +
                     std::to_string(y) + ", " + std::to_string(z) +
                     ") has colour index 0 (valid: 1..255)");
            }
            world.set(x, z, y, ci);
        }
        return VoxModel{std::move(world), palette};
    }

  private:
    [[noreturn]] void fail(const std::string& what) const { throw InputError(file_ + ": " + what); }

    // Reads the chunk header at `off`; the whole chunk must end by `limit`.
    Chunk chunk_at(std::size_t off, std::size_t limit) const {
        if (off + 12 > limit) {
            const std::string where = limit == b_.size() ? "file" : "parent chunk";
            fail("truncated: chunk header needs 12 bytes at offset " + std::to_string(off) + ", " +
                 where + " has " + std::to_string(limit - off));
        }
        Chunk c;
        c.id = id_text(b_, off);
        c.offset = off;
        c.content = off + 12;
        c.content_size = u32_at(b_, off + 4);
        c.children_size = u32_at(b_, off + 8);
        const std::uint64_t need = c.content_size + c.children_size;
        const std::uint64_t have = limit - c.content;
        if (need > have) {
            const std::string where = limit == b_.size() ? "file" : "parent chunk";
            fail("truncated: chunk '" + c.id + "' needs " + std::to_string(need) +
                 " bytes at offset " + std::to_string(c.content) + ", " + where + " has " +
                 std::to_string(have));
        }
        return c;
    }

    void need_content(const Chunk& c, std::uint64_t n) const {
        if (c.content_size < n) {
            fail("chunk '" + c.id + "' at offset " + std::to_string(c.offset) + " has " +
                 std::to_string(c.content_size) + " content bytes, needs " + std::to_string(n));
        }
    }

    std::string file_;
    const std::vector<std::uint8_t>& b_;
};

}  // namespace

VoxModel read_vox(const std::filesystem::path& path) {
    const std::vector<std::uint8_t> bytes = read_file(path);
    return VoxParser(path.string(), bytes).parse();
}

void write_vox(const std::filesystem::path& path, const World& world, const Palette& palette) {
    const Dims d = world.dims();
    if (d.x > 256 || d.y > 256 || d.z > 256) {
        throw InputError("cannot write '" + path.string() + "': world " + d.to_string() +
                         " exceeds MagicaVoxel's 256 voxels per axis (save it as .npy)");
    }
    std::vector<std::uint8_t> b;
    auto put_id = [&](const char* id) { b.insert(b.end(), id, id + 4); };
    auto put_u32 = [&](std::uint32_t v) {
        for (int k = 0; k < 4; ++k) {
            b.push_back(static_cast<std::uint8_t>(v >> (8 * k)));
        }
    };
    const std::size_t solid = world.solid_count();
    const std::uint32_t xyzi_bytes = static_cast<std::uint32_t>(4 + 4 * solid);
    const std::uint32_t children = (12 + 12) + (12 + xyzi_bytes) + (12 + 256 * 4);
    b.reserve(20 + children);
    put_id("VOX ");
    put_u32(150);
    put_id("MAIN");
    put_u32(0);
    put_u32(children);
    put_id("SIZE");
    put_u32(12);
    put_u32(0);
    put_u32(d.x);  // vox x = world x
    put_u32(d.z);  // vox y = world z
    put_u32(d.y);  // vox z (up) = world y
    put_id("XYZI");
    put_u32(xyzi_bytes);
    put_u32(0);
    put_u32(static_cast<std::uint32_t>(solid));
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                const std::uint8_t v = world.at(x, y, z);
                if (v != 0) {
                    b.push_back(static_cast<std::uint8_t>(x));
                    b.push_back(static_cast<std::uint8_t>(z));
                    b.push_back(static_cast<std::uint8_t>(y));
                    b.push_back(v);
                }
            }
        }
    }
    put_id("RGBA");
    put_u32(256 * 4);
    put_u32(0);
    for (std::size_t i = 1; i <= 256; ++i) {
        const Rgba c = i < 256 ? palette[static_cast<std::uint8_t>(i)] : Rgba{0, 0, 0, 0};
        b.push_back(c.r);
        b.push_back(c.g);
        b.push_back(c.b);
        b.push_back(c.a);
    }
    detail::write_file_atomic(path, {b});
}

VoxModel load_world(const std::filesystem::path& path) {
    if (sdf::is_sdf_path(path)) {  // an implicit part: its discretised solid (sdf.hpp)
        return VoxModel{sdf::solid_world(sdf::load_part(path), path.string()), Palette()};
    }
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (ext == ".vox") {
        return read_vox(path);
    }
    if (ext == ".npy") {
        const NpyArray array = read_npy(path);
        try {
            return VoxModel{world_from_npy(array), Palette()};
        } catch (const InputError& e) {
            throw InputError(path.string() + ": " + e.what());
        }
    }
    throw InputError("'" + path.string() + "': unsupported file type " +
                     (ext.empty() ? std::string("(no extension)") : "'" + ext + "'") +
                     " (expected .vox or .npy)");
}

}  // namespace voxfield
