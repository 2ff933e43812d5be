// MagicaVoxel .vox reader and writer (format: ephtracy/voxel-model,
// MagicaVoxel-file-format-vox.txt and MagicaVoxel-file-format-vox-extension.txt; the placement
// of scene-graph instances follows the rules the open-source ogt_vox reader documents).
#include "voxfield/core/vox.hpp"

#include "input_file.hpp"
#include "output_file.hpp"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "voxfield/core/error.hpp"

namespace voxfield {

namespace {

namespace fs = std::filesystem;

constexpr std::uint32_t kMinVersion = 150;

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

// A chunk id for messages (printable).
std::string id_text(const std::vector<std::uint8_t>& b, std::size_t off) {
    return printable(std::string_view(reinterpret_cast<const char*>(b.data() + off), 4));
}

struct Chunk {
    std::string id;
    std::size_t offset = 0;   // of the chunk header
    std::size_t content = 0;  // offset of the content
    std::uint64_t content_size = 0;
    std::uint64_t children_size = 0;
};

// x -> rotation * x + translation, rotation a signed permutation (rows).
struct Affine {
    std::array<std::int32_t, 9> r{1, 0, 0, 0, 1, 0, 0, 0, 1};
    std::array<std::int64_t, 3> t{0, 0, 0};

    // This transform applied after `inner`.
    Affine then_outer_of(const Affine& inner) const {
        Affine out;
        for (int i = 0; i < 3; ++i) {
            std::int64_t sum = t[static_cast<std::size_t>(i)];
            for (int j = 0; j < 3; ++j) {
                std::int32_t s = 0;
                for (int k = 0; k < 3; ++k) {
                    s += r[static_cast<std::size_t>(3 * i + k)] *
                         inner.r[static_cast<std::size_t>(3 * k + j)];
                }
                out.r[static_cast<std::size_t>(3 * i + j)] = s;
                sum += std::int64_t{r[static_cast<std::size_t>(3 * i + j)]} *
                       inner.t[static_cast<std::size_t>(j)];
            }
            out.t[static_cast<std::size_t>(i)] = sum;
        }
        return out;
    }
};

enum class NodeKind { kTransform, kGroup, kShape };

const char* kind_id(NodeKind k) {
    return k == NodeKind::kTransform ? "nTRN" : k == NodeKind::kGroup ? "nGRP" : "nSHP";
}

struct Node {
    NodeKind kind = NodeKind::kTransform;
    std::size_t offset = 0;  // of its chunk
    bool hidden = false;
    std::int32_t layer = -1;              // nTRN
    Affine local;                         // nTRN, first frame
    std::vector<std::uint32_t> children;  // nTRN: one; nGRP: any; nSHP: none
    std::uint32_t model = 0;              // nSHP, first model
};

// Per axis: where model coordinate v (0..size-1) lands under an instance, as lo..hi.
struct Extent {
    std::int64_t lo = 0, hi = 0;
};

std::array<std::int64_t, 3> pivot_of(const Dims& size) {
    return {size.x / 2, size.y / 2, size.z / 2};
}

std::array<Extent, 3> extent_of(const VoxInstance& in, const Dims& size) {
    const std::array<std::int64_t, 3> n = {size.x, size.y, size.z};
    const auto p = pivot_of(size);
    std::array<Extent, 3> e;
    for (std::size_t i = 0; i < 3; ++i) {
        for (std::size_t j = 0; j < 3; ++j) {
            const std::int32_t s = in.rotation[3 * i + j];
            if (s != 0) {
                const std::int64_t flip = s < 0 ? 1 : 0;
                const std::int64_t a = s * (0 - p[j]) + in.translation[i] - flip;
                const std::int64_t b = s * (n[j] - 1 - p[j]) + in.translation[i] - flip;
                e[i] = {std::min(a, b), std::max(a, b)};
            }
        }
    }
    return e;
}

class Reader;

class VoxParser {
  public:
    VoxParser(std::string file, const std::vector<std::uint8_t>& bytes)
        : file_(std::move(file)), b_(bytes) {}

    VoxScene parse();

    [[noreturn]] void fail(const std::string& what) const { throw InputError(file_ + ": " + what); }

  private:
    friend class Reader;

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

    VoxScene::Model read_model(const Chunk& size, const Chunk& xyzi) const;
    void read_node(const Chunk& c);
    void read_layer(const Chunk& c);
    void build_instances(VoxScene& scene) const;
    void place_scene(VoxScene& scene) const;
    std::string node_name(std::uint32_t id) const;

    std::string file_;
    const std::vector<std::uint8_t>& b_;
    std::unordered_map<std::uint32_t, Node> nodes_;
    std::unordered_set<std::int32_t> hidden_layers_;
};

// Reads the fields of one scene-graph chunk, failing with the chunk's name and offset.
class Reader {
  public:
    Reader(const VoxParser& p, const Chunk& c)
        : p_(p),
          c_(c),
          pos_(c.content),
          end_(c.content + static_cast<std::size_t>(c.content_size)) {}

    std::uint32_t u32() {
        need(4, "a 4-byte integer");
        const std::uint32_t v = u32_at(p_.b_, pos_);
        pos_ += 4;
        return v;
    }
    std::int32_t i32() { return static_cast<std::int32_t>(u32()); }
    std::string text() {
        const std::uint32_t n = u32();
        need(n, "a " + std::to_string(n) + "-byte string");
        std::string s(reinterpret_cast<const char*>(p_.b_.data() + pos_), n);
        pos_ += n;
        return s;
    }
    std::unordered_map<std::string, std::string> dict() {
        const std::uint32_t n = u32();
        if (std::uint64_t{n} * 8 > end_ - pos_) {
            fail("truncated: a dictionary of " + std::to_string(n) +
                 " entries does not fit in its " + std::to_string(end_ - pos_) +
                 " remaining bytes");
        }
        std::unordered_map<std::string, std::string> d;
        for (std::uint32_t i = 0; i < n; ++i) {
            std::string key = text();
            d[std::move(key)] = text();
        }
        return d;
    }
    // Checks that `count` items of at least `bytes` each can still follow.
    void need_items(std::uint32_t count, std::size_t bytes, const std::string& what) {
        if (std::uint64_t{count} * bytes > end_ - pos_) {
            fail("truncated: " + std::to_string(count) + " " + what + " do not fit in its " +
                 std::to_string(end_ - pos_) + " remaining bytes");
        }
    }
    [[noreturn]] void fail(const std::string& what) const {
        p_.fail("chunk '" + c_.id + "' at offset " + std::to_string(c_.offset) + ": " + what);
    }

  private:
    void need(std::uint64_t n, const std::string& what) const {
        if (n > end_ - pos_) {
            fail("truncated: " + what + " at offset " + std::to_string(pos_) + ", " +
                 std::to_string(end_ - pos_) + " content bytes left");
        }
    }

    const VoxParser& p_;
    const Chunk& c_;
    std::size_t pos_;
    std::size_t end_;
};

// MagicaVoxel's packed rotation: bits 0-1 the column of row 0's non-zero entry, bits 2-3 that
// of row 1, row 2 takes the remaining column; bits 4, 5, 6 negate rows 0, 1, 2.
std::array<std::int32_t, 9> decode_rotation(const std::string& text, Reader& rd) {
    std::uint32_t v = 0;
    bool ok = !text.empty() && text.size() <= 3;
    for (char ch : text) {
        ok = ok && ch >= '0' && ch <= '9';
        v = v * 10 + static_cast<std::uint32_t>(ch - '0');
    }
    const std::uint32_t c0 = v & 3, c1 = (v >> 2) & 3;
    if (!ok || v > 127 || c0 > 2 || c1 > 2 || c0 == c1) {
        rd.fail("invalid rotation '_r' = '" + printable(text) +
                "' (a packed rotation byte 0..127 whose rows "
                "name two different columns 0..2)");
    }
    const std::uint32_t c2 = 3 - c0 - c1;
    std::array<std::int32_t, 9> r{};
    r[c0] = (v & 16) ? -1 : 1;
    r[3 + c1] = (v & 32) ? -1 : 1;
    r[6 + c2] = (v & 64) ? -1 : 1;
    return r;
}

std::array<std::int64_t, 3> decode_translation(const std::string& text, Reader& rd) {
    std::array<std::int64_t, 3> t{};
    std::size_t pos = 0;
    bool ok = true;
    for (std::size_t k = 0; k < 3 && ok; ++k) {
        while (pos < text.size() && text[pos] == ' ') {
            ++pos;
        }
        const bool neg = pos < text.size() && text[pos] == '-';
        pos += neg ? 1 : 0;
        const std::size_t start = pos;
        std::int64_t v = 0;
        while (pos < text.size() && text[pos] >= '0' && text[pos] <= '9' && pos - start < 10) {
            v = v * 10 + (text[pos] - '0');
            ++pos;
        }
        ok = pos > start && (pos == text.size() || text[pos] == ' ');
        v = neg ? -v : v;
        ok = ok && v >= std::numeric_limits<std::int32_t>::min() &&
             v <= std::numeric_limits<std::int32_t>::max();
        t[k] = v;
    }
    while (pos < text.size() && text[pos] == ' ') {
        ++pos;
    }
    if (!ok || pos != text.size()) {
        rd.fail("invalid translation '_t' = '" + printable(text) + "' (three 32-bit integers)");
    }
    return t;
}

bool is_hidden(const std::unordered_map<std::string, std::string>& d) {
    const auto it = d.find("_hidden");
    return it != d.end() && it->second == "1";
}

void VoxParser::read_node(const Chunk& c) {
    Reader rd(*this, c);
    const std::uint32_t id = rd.u32();
    Node node;
    node.offset = c.offset;
    node.hidden = is_hidden(rd.dict());
    if (c.id == "nTRN") {
        node.kind = NodeKind::kTransform;
        node.children.push_back(rd.u32());
        rd.u32();  // reserved
        node.layer = rd.i32();
        const std::uint32_t frames = rd.u32();
        rd.need_items(frames, 4, "frames");
        for (std::uint32_t f = 0; f < frames; ++f) {
            const auto d = rd.dict();
            if (f == 0) {
                if (const auto r = d.find("_r"); r != d.end()) {
                    node.local.r = decode_rotation(r->second, rd);
                }
                if (const auto t = d.find("_t"); t != d.end()) {
                    node.local.t = decode_translation(t->second, rd);
                }
            }
        }
    } else if (c.id == "nGRP") {
        node.kind = NodeKind::kGroup;
        const std::uint32_t n = rd.u32();
        rd.need_items(n, 4, "children");
        for (std::uint32_t i = 0; i < n; ++i) {
            node.children.push_back(rd.u32());
        }
    } else {
        node.kind = NodeKind::kShape;
        const std::uint32_t n = rd.u32();
        if (n == 0) {
            rd.fail("shape node " + std::to_string(id) + " names no model");
        }
        rd.need_items(n, 8, "models");
        for (std::uint32_t i = 0; i < n; ++i) {
            const std::uint32_t m = rd.u32();
            rd.dict();
            if (i == 0) {
                node.model = m;
            }
        }
    }
    if (const auto it = nodes_.find(id); it != nodes_.end()) {
        rd.fail("node id " + std::to_string(id) + " is already used by the '" +
                kind_id(it->second.kind) + "' chunk at offset " +
                std::to_string(it->second.offset));
    }
    nodes_.emplace(id, std::move(node));
}

void VoxParser::read_layer(const Chunk& c) {
    Reader rd(*this, c);
    const std::int32_t id = rd.i32();
    if (is_hidden(rd.dict())) {
        hidden_layers_.insert(id);
    }
}

std::string VoxParser::node_name(std::uint32_t id) const {
    const Node& n = nodes_.at(id);
    return std::string("node ") + std::to_string(id) + " ('" + kind_id(n.kind) + "' at offset " +
           std::to_string(n.offset) + ")";
}

// Depth-first from node 0 with an explicit stack (no recursion depth limit): accumulates the
// transforms, skips hidden subtrees (still checked), refuses cycles and missing nodes. A node
// may have several parents (MagicaVoxel shares a shape node between the transforms that place
// copies of a model); each path is an instance, up to kMaxVisits nodes entered in all.
void VoxParser::build_instances(VoxScene& scene) const {
    if (nodes_.find(0) == nodes_.end()) {
        fail("the scene graph has no root node 0");
    }
    constexpr std::size_t kMaxVisits = std::size_t{1} << 22;
    struct Frame {
        std::uint32_t id;
        std::size_t next = 0;
        Affine m;
        bool hidden = false;
    };
    std::unordered_set<std::uint32_t> on_path;
    std::vector<Frame> stack;
    std::size_t visits = 0;
    auto enter = [&](std::uint32_t id, const Frame* from) {
        const auto it = nodes_.find(id);
        if (it == nodes_.end()) {
            fail(node_name(from->id) + " names child node " + std::to_string(id) +
                 ", which is not in the file");
        }
        if (on_path.count(id) != 0) {
            std::string cycle = std::to_string(id);
            for (std::size_t k = stack.size(); k-- > 0 && stack[k].id != id;) {
                cycle = std::to_string(stack[k].id) + " -> " + cycle;
            }
            fail("the scene graph has a node cycle: " + std::to_string(id) + " -> " + cycle);
        }
        if (++visits > kMaxVisits) {
            fail("the scene graph expands to more than " + std::to_string(kMaxVisits) +
                 " nodes (shared subtrees)");
        }
        on_path.insert(id);
        const Node& n = it->second;
        Frame f{id, 0, from ? from->m : Affine{}, from ? from->hidden : false};
        f.hidden = f.hidden || n.hidden ||
                   (n.kind == NodeKind::kTransform && hidden_layers_.count(n.layer) != 0);
        if (n.kind == NodeKind::kTransform) {
            f.m = f.m.then_outer_of(n.local);
        } else if (n.kind == NodeKind::kShape) {
            if (n.model >= scene.models.size()) {
                fail(node_name(id) + " names model " + std::to_string(n.model) +
                     " but the file has " + std::to_string(scene.models.size()));
            }
            if (f.hidden) {
                ++scene.hidden_instances;
            } else {
                scene.instances.push_back(VoxInstance{n.model, f.m.r, f.m.t});
            }
        }
        stack.push_back(f);
    };
    enter(0, nullptr);
    while (!stack.empty()) {
        Frame& top = stack.back();
        const Node& n = nodes_.at(top.id);
        if (top.next < n.children.size()) {
            const std::uint32_t child = n.children[top.next++];
            const Frame from = top;
            enter(child, &from);
        } else {
            on_path.erase(top.id);
            stack.pop_back();
        }
    }
    if (scene.instances.empty()) {
        fail("the scene graph has no visible model instance (" +
             std::to_string(scene.hidden_instances) + " hidden)");
    }
}

// The world box: the union of every visible instance's model box, in vox space.
void VoxParser::place_scene(VoxScene& scene) const {
    std::array<Extent, 3> box;
    bool first = true;
    for (const VoxInstance& in : scene.instances) {
        const auto e = extent_of(in, scene.models[in.model].size);
        for (std::size_t i = 0; i < 3; ++i) {
            box[i].lo = first ? e[i].lo : std::min(box[i].lo, e[i].lo);
            box[i].hi = first ? e[i].hi : std::max(box[i].hi, e[i].hi);
        }
        first = false;
    }
    std::array<std::int64_t, 3> n{};
    for (std::size_t i = 0; i < 3; ++i) {
        n[i] = box[i].hi - box[i].lo + 1;
        scene.origin[i] = box[i].lo;
    }
    // vox (x, y, z) -> world (x, z, y)
    if (n[0] > kVoxMaxSceneAxis || n[1] > kVoxMaxSceneAxis || n[2] > kVoxMaxSceneAxis) {
        fail("the scene is " + std::to_string(n[0]) + "x" + std::to_string(n[2]) + "x" +
             std::to_string(n[1]) + " voxels, over the limit of " +
             std::to_string(kVoxMaxSceneAxis) + " per axis");
    }
    scene.dims = Dims{static_cast<std::uint32_t>(n[0]), static_cast<std::uint32_t>(n[2]),
                      static_cast<std::uint32_t>(n[1])};
}

VoxScene::Model VoxParser::read_model(const Chunk& size, const Chunk& xyzi) const {
    need_content(size, 12);
    const std::uint32_t sx = u32_at(b_, size.content);
    const std::uint32_t sy = u32_at(b_, size.content + 4);
    const std::uint32_t sz = u32_at(b_, size.content + 8);
    for (std::uint32_t s : {sx, sy, sz}) {
        if (s < 1 || s > 256) {
            fail("chunk 'SIZE' at offset " + std::to_string(size.offset) + " gives " +
                 std::to_string(static_cast<std::int32_t>(sx)) + "x" +
                 std::to_string(static_cast<std::int32_t>(sy)) + "x" +
                 std::to_string(static_cast<std::int32_t>(sz)) + " (each axis must be 1..256)");
        }
    }
    VoxScene::Model m;
    m.size = {sx, sy, sz};
    need_content(xyzi, 4);
    const std::uint32_t n = u32_at(b_, xyzi.content);
    const std::uint64_t need = 4 + std::uint64_t{n} * 4;
    if (need > xyzi.content_size) {
        fail("chunk 'XYZI' at offset " + std::to_string(xyzi.offset) + " declares " +
             std::to_string(n) + " voxels (" + std::to_string(need) +
             " bytes) but its content is " + std::to_string(xyzi.content_size) + " bytes");
    }
    m.xyzi.resize(n);
    for (std::uint32_t i = 0; i < n; ++i) {
        const std::size_t o = xyzi.content + 4 + 4 * std::size_t{i};
        const std::uint8_t x = b_[o], y = b_[o + 1], z = b_[o + 2], ci = b_[o + 3];
        if (x >= sx || y >= sy || z >= sz) {
            fail("voxel " + std::to_string(i) + " at (" + std::to_string(x) + ", " +
                 std::to_string(y) + ", " + std::to_string(z) + ") is outside SIZE " +
                 m.size.to_string());
        }
        if (ci == 0) {
            fail("voxel " + std::to_string(i) + " at (" + std::to_string(x) + ", " +
                 std::to_string(y) + ", " + std::to_string(z) +
                 ") has colour index 0 (valid: 1..255)");
        }
        m.xyzi[i] = {x, y, z, ci};
    }
    return m;
}

VoxScene VoxParser::parse() {
    if (b_.size() < 8) {
        fail("truncated: " + std::to_string(b_.size()) +
             " bytes, shorter than the 8-byte 'VOX ' header");
    }
    if (std::memcmp(b_.data(), "VOX ", 4) != 0) {
        fail("not a MagicaVoxel file (magic is '" + id_text(b_, 0) + "', expected 'VOX ')");
    }
    const std::uint32_t version = u32_at(b_, 4);
    if (version < kMinVersion) {
        fail("version " + std::to_string(version) + " is older than " +
             std::to_string(kMinVersion) + ", the oldest this reader supports");
    }
    const Chunk main = chunk_at(8, b_.size());
    if (main.id != "MAIN") {
        fail("first chunk is '" + main.id + "' at offset 8, expected 'MAIN'");
    }
    std::size_t pos = main.content + static_cast<std::size_t>(main.content_size);
    const std::size_t end = pos + static_cast<std::size_t>(main.children_size);

    VoxScene scene;
    bool have_rgba = false, pending_size = false;
    Chunk size;
    while (pos < end) {
        const Chunk c = chunk_at(pos, end);
        if (c.id == "SIZE") {
            if (pending_size) {
                fail("no 'XYZI' chunk after the 'SIZE' chunk at offset " +
                     std::to_string(size.offset));
            }
            size = c;
            pending_size = true;
        } else if (c.id == "XYZI") {
            if (!pending_size) {
                fail("chunk 'XYZI' at offset " + std::to_string(c.offset) +
                     " comes before any 'SIZE' chunk");
            }
            scene.models.push_back(read_model(size, c));
            pending_size = false;
        } else if (c.id == "RGBA" && !have_rgba) {
            need_content(c, 256 * 4);
            for (std::size_t i = 0; i < 255; ++i) {
                const std::size_t o = c.content + 4 * i;
                scene.palette[static_cast<std::uint8_t>(i + 1)] =
                    Rgba{b_[o], b_[o + 1], b_[o + 2], b_[o + 3]};
            }
            have_rgba = true;
        } else if (c.id == "nTRN" || c.id == "nGRP" || c.id == "nSHP") {
            read_node(c);
            scene.has_scene_graph = true;
        } else if (c.id == "LAYR") {
            read_layer(c);
        }
        // PACK, MATL, MATT, rOBJ, rCAM, NOTE, IMAP, META and unknown chunks are skipped.
        pos = c.content + static_cast<std::size_t>(c.content_size + c.children_size);
    }
    if (pending_size) {
        fail("no 'XYZI' chunk after the 'SIZE' chunk at offset " + std::to_string(size.offset));
    }
    if (scene.models.empty()) {
        fail("no 'SIZE' chunk in 'MAIN'");
    }
    if (scene.has_scene_graph) {
        build_instances(scene);
    } else {
        // The first model where it stands: cell = v.
        const auto p = pivot_of(scene.models[0].size);
        scene.instances.push_back(VoxInstance{0, {1, 0, 0, 0, 1, 0, 0, 0, 1}, {p[0], p[1], p[2]}});
    }
    place_scene(scene);
    return scene;
}

}  // namespace

void VoxScene::place(
    const std::function<void(std::uint32_t, std::uint32_t, std::uint32_t, std::uint8_t)>& f) const {
    for (const VoxInstance& in : instances) {
        const Model& m = models[in.model];
        const auto p = pivot_of(m.size);
        // Per vox axis i: the model axis it takes, its sign, and the constant part.
        std::array<std::size_t, 3> axis{};
        std::array<std::int64_t, 3> sign{}, offset{};
        for (std::size_t i = 0; i < 3; ++i) {
            for (std::size_t j = 0; j < 3; ++j) {
                const std::int32_t s = in.rotation[3 * i + j];
                if (s != 0) {
                    axis[i] = j;
                    sign[i] = s;
                    offset[i] = -s * p[j] + in.translation[i] - (s < 0 ? 1 : 0) - origin[i];
                }
            }
        }
        for (const auto& v : m.xyzi) {
            std::array<std::uint32_t, 3> c{};
            for (std::size_t i = 0; i < 3; ++i) {
                c[i] = static_cast<std::uint32_t>(sign[i] * v[axis[i]] + offset[i]);
            }
            f(c[0], c[2], c[1], v[3]);  // vox (x, y, z) -> world (x, z, y)
        }
    }
}

VoxScene read_vox_scene(const std::filesystem::path& path) {
    const std::vector<std::uint8_t> bytes = read_file(path);
    return VoxParser(path.string(), bytes).parse();
}

VoxModel read_vox(const std::filesystem::path& path) {
    const VoxScene scene = read_vox_scene(path);
    constexpr std::size_t kDenseLimit = std::size_t{1} << 31;
    if (scene.dims.count() > kDenseLimit) {
        throw InputError(path.string() + ": the scene is " + scene.dims.to_string() + " (" +
                         std::to_string(scene.dims.count()) +
                         " voxels), more than a dense world holds (2^31 voxels)");
    }
    World world(scene.dims);
    scene.place([&](std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint8_t c) {
        world.set(x, y, z, c);
    });
    return VoxModel{std::move(world), scene.palette};
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

}  // namespace voxfield
