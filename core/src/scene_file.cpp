// Mixed scenes: .vox models and .sdf.json parts in one world (scene_file.hpp).
#include "voxfield/core/scene_file.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <sstream>

#include "input_file.hpp"
#include "voxfield/core/error.hpp"

namespace voxfield::scene {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

// Nodes above a part's shape in a scene: the union of all parts, its translation, its clip.
constexpr std::size_t kWrapDepth = 3;

std::string brief(const json& v) {
    std::string s = v.dump();
    return s.size() > 40 ? s.substr(0, 37) + "..." : s;
}

// Every "material" key of a node tree removed (only nodes carry one: a part's own parser
// rejects it anywhere else).
void strip_materials(json& node) {
    if (node.is_object()) {
        node.erase("material");
        for (auto& [key, value] : node.items()) {
            strip_materials(value);
        }
    } else if (node.is_array()) {
        for (json& v : node) {
            strip_materials(v);
        }
    }
}

struct Reader {
    std::string name;  // the scene file, for messages
    fs::path folder;

    [[noreturn]] void fail(const std::string& where, const std::string& what) const {
        throw InputError(name + ": " + where + ": " + what);
    }

    void only_keys(const json& obj, const std::string& where,
                   std::initializer_list<const char*> keys) const {
        for (const auto& item : obj.items()) {
            if (std::find_if(keys.begin(), keys.end(),
                             [&](const char* k) { return item.key() == k; }) == keys.end()) {
                std::string list;
                for (const char* k : keys) {
                    list += (list.empty() ? "" : ", ") + std::string(k);
                }
                fail(where, "unknown field '" + item.key() + "' (expected " + list + ")");
            }
        }
    }

    std::array<double, 3> translate(const json& item, const std::string& where) const {
        std::array<double, 3> t{0, 0, 0};
        if (!item.contains("translate")) {
            return t;
        }
        const json& v = item["translate"];
        if (!v.is_array() || v.size() != 3) {
            fail(where + ".translate", "expected [x, y, z], got " + brief(v));
        }
        for (int a = 0; a < 3; ++a) {
            if (!v[a].is_number() || !std::isfinite(v[a].get<double>())) {
                fail(where + ".translate", "expected [x, y, z], got " + brief(v));
            }
            t[a] = v[a].get<double>();
        }
        return t;
    }

    fs::path item_path(const json& v, const std::string& where) const {
        if (!v.is_string() || v.get<std::string>().empty()) {
            fail(where, "expected a file name, got " + brief(v));
        }
        const fs::path p(v.get<std::string>());
        return p.is_absolute() ? p : folder / p;
    }
};

// An item file's reader failing: its message, prefixed by the item.
template <class F>
auto read_item(const std::string& scene, const std::string& where, F&& read) {
    try {
        return read();
    } catch (const InputError& e) {
        throw InputError(scene + ": " + where + ": " + e.what());
    }
}

}  // namespace

bool is_scene_path(const fs::path& path) {
    std::string name = path.filename().string();
    std::transform(name.begin(), name.end(), name.begin(),
                   [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
    return name.size() > 11 && name.ends_with(".scene.json");
}

Scene parse_scene(const std::string& text, const fs::path& path) {
    Reader r{path.string(), path.parent_path()};
    json doc;
    try {
        doc = json::parse(text);
    } catch (const json::parse_error& e) {
        const std::string what = e.what();
        const auto at = what.find("parse error");
        throw InputError(r.name + ": not valid JSON (" +
                         (at == std::string::npos ? what : what.substr(at)) + ")");
    }
    if (!doc.is_object()) {
        r.fail("top level", "expected an object, got " + brief(doc));
    }
    r.only_keys(doc, "top level", {"version", "voxel_size", "items"});
    if (!doc.contains("version")) {
        r.fail("top level", "missing field 'version'");
    }
    if (!doc["version"].is_number_integer() || doc["version"].get<std::int64_t>() != 1) {
        r.fail("version", "unsupported version " + brief(doc["version"]) + " (expected 1)");
    }
    if (!doc.contains("voxel_size")) {
        r.fail("top level", "missing field 'voxel_size'");
    }
    const json& hv = doc["voxel_size"];
    if (!hv.is_number() || !(hv.get<double>() > 0) || !std::isfinite(hv.get<double>())) {
        r.fail("voxel_size", "must be a positive number, got " + brief(hv));
    }
    Scene s;
    s.voxel_size = hv.get<double>();
    const double h = s.voxel_size;
    if (!doc.contains("items")) {
        r.fail("top level", "missing field 'items'");
    }
    const json& items = doc["items"];
    if (!items.is_array() || items.empty()) {
        r.fail("items", "expected a non-empty array of items, got " + brief(items));
    }

    // Each item's box in scene-grid cells [lo, hi).
    struct Placed {
        std::array<std::int64_t, 3> lo, hi;
    };
    std::vector<Placed> boxes;
    std::vector<std::size_t> vox_box;  // boxes index of each vox item
    // A part's wrapper node (its material), shape, bounds' centre and half size, translation.
    struct PartItem {
        json node, shape, centre, half;
        std::array<double, 3> t;
    };
    std::vector<PartItem> parts;
    constexpr double kMaxCell = double(std::int64_t{1} << 40);
    for (std::size_t i = 0; i < items.size(); ++i) {
        const std::string where = "items[" + std::to_string(i) + "]";
        const json& item = items[i];
        if (!item.is_object()) {
            r.fail(where, "expected an object, got " + brief(item));
        }
        const bool is_vox = item.contains("vox"), is_sdf = item.contains("sdf");
        if (is_vox == is_sdf) {
            r.fail(where, "an item names one file: \"vox\" or \"sdf\"");
        }
        const std::array<double, 3> t = r.translate(item, where);
        Placed box{};
        if (is_vox) {
            r.only_keys(item, where, {"vox", "translate"});
            const fs::path file = r.item_path(item["vox"], where + ".vox");
            VoxItem v{file, read_item(r.name, where, [&] { return read_vox(file); }), {}};
            const Dims d = v.model.world.dims();
            for (int a = 0; a < 3; ++a) {
                const double cells = t[a] / h;
                if (std::abs(cells - std::round(cells)) > 1e-6 * std::max(1.0, std::abs(cells)) ||
                    std::abs(cells) > kMaxCell) {
                    r.fail(where + ".translate",
                           std::string("a .vox model moves by whole voxels: ") + "xyz"[a] + " " +
                               std::to_string(t[a]) + " is not a multiple of voxel_size " +
                               std::to_string(h));
                }
                box.lo[a] = static_cast<std::int64_t>(std::llround(cells));
                box.hi[a] =
                    box.lo[a] + static_cast<std::int64_t>(a == 0 ? d.x : (a == 1 ? d.y : d.z));
            }
            if (s.vox.empty()) {
                s.palette = v.model.palette;
            }
            vox_box.push_back(boxes.size());
            s.vox.push_back(std::move(v));
        } else {
            r.only_keys(item, where, {"sdf", "translate", "material"});
            const fs::path file = r.item_path(item["sdf"], where + ".sdf");
            const auto [part, shape] = read_item(r.name, where, [&] {
                std::uint64_t size = 0;
                std::ifstream in = detail::open_input(file, size);
                std::ostringstream part_text;
                part_text << in.rdbuf();
                sdf::Part p = sdf::parse_part(part_text.str(), file.string());
                return std::pair{std::move(p), json::parse(part_text.str())["shape"]};
            });
            if (part.depth + kWrapDepth > VF_SDF_MAX_DEPTH) {
                r.fail(where, file.string() + " is " + std::to_string(part.depth) +
                                  " nodes deep; a scene wraps a part in " +
                                  std::to_string(kWrapDepth) + " more (at most " +
                                  std::to_string(VF_SDF_MAX_DEPTH) + " in all)");
            }
            json wrapped = shape;
            json node = json::object();
            if (item.contains("material")) {
                const json& m = item["material"];
                if (!m.is_number_integer() || m.get<std::int64_t>() < 1 ||
                    m.get<std::int64_t>() > 255) {
                    r.fail(where + ".material", "must be an integer 1..255, got " + brief(m));
                }
                strip_materials(wrapped);
                node["material"] = m;
            }
            // The shape clipped to the part's own bounds, then moved.
            json centre = json::array(), half = json::array();
            for (int a = 0; a < 3; ++a) {
                centre.push_back(0.5 * (part.lo[a] + part.hi[a]));
                half.push_back(0.5 * (part.hi[a] - part.lo[a]));
                const double lo = std::floor((part.lo[a] + t[a]) / h);
                const double hi = std::ceil((part.hi[a] + t[a]) / h);
                if (std::abs(lo) > kMaxCell || std::abs(hi) > kMaxCell) {
                    r.fail(where + ".translate", "places the part too far from the origin");
                }
                box.lo[a] = static_cast<std::int64_t>(lo);
                box.hi[a] = std::max(static_cast<std::int64_t>(hi), box.lo[a] + 1);
            }
            parts.push_back({std::move(node), std::move(wrapped), centre, half, t});
        }
        boxes.push_back(box);
    }

    // The world: the grid's box around every item.
    std::array<std::int64_t, 3> lo{}, hi{};
    for (int a = 0; a < 3; ++a) {
        lo[a] = std::numeric_limits<std::int64_t>::max();
        hi[a] = std::numeric_limits<std::int64_t>::min();
        for (const Placed& b : boxes) {
            lo[a] = std::min(lo[a], b.lo[a]);
            hi[a] = std::max(hi[a], b.hi[a]);
        }
    }
    std::array<std::uint32_t, 3> n{};
    double total = 1;
    for (int a = 0; a < 3; ++a) {
        const std::int64_t extent = hi[a] - lo[a];
        if (extent > std::int64_t{1} << 24) {
            r.fail("items", std::string("the world spans ") + std::to_string(extent) +
                                " voxels along " + "xyz"[a] + " (at most 2^24)");
        }
        n[a] = static_cast<std::uint32_t>(extent);
        total *= double(extent);
        s.origin[a] = lo[a];
        s.lo[a] = double(lo[a]) * h;
    }
    if (total > double(std::uint64_t{1} << 31)) {
        r.fail("items", "the world would hold " + std::to_string(std::uint64_t(total)) +
                            " voxels (at most 2^31): a larger voxel_size or fewer, closer items");
    }
    s.dims = Dims{n[0], n[1], n[2]};
    for (std::size_t k = 0; k < s.vox.size(); ++k) {
        for (int a = 0; a < 3; ++a) {
            s.vox[k].at[a] = static_cast<std::uint32_t>(boxes[vox_box[k]].lo[a] - lo[a]);
        }
    }
    s.parts = parts.size();
    if (!parts.empty()) {
        // Each part clipped to its own bounds' box and moved: max(f, box) keeping the part's
        // materials, written as difference [f, difference [big, box]] with `big` the box
        // grown by twice the world's diagonal, so that -(max(big, -box)) = box in the world.
        double diagonal = 0;
        for (int a = 0; a < 3; ++a) {
            diagonal += double(n[a]) * h * double(n[a]) * h;
        }
        diagonal = std::sqrt(diagonal);
        json members = json::array();
        for (PartItem& item : parts) {
            json big = json::array();
            for (int a = 0; a < 3; ++a) {
                big.push_back(item.half[a].get<double>() + 2 * diagonal);
            }
            const json clip = {{"difference",
                                {{{"box", {{"center", item.centre}, {"half_size", big}}}},
                                 {{"box", {{"center", item.centre}, {"half_size", item.half}}}}}}};
            item.node["transform"] = {{"translate", {item.t[0], item.t[1], item.t[2]}},
                                      {"of", {{"difference", {item.shape, clip}}}}};
            members.push_back(std::move(item.node));
        }
        const json hi_corner = {double(hi[0]) * h, double(hi[1]) * h, double(hi[2]) * h};
        const json composed = {{"version", 1},
                               {"voxel_size", h},
                               {"bounds", {{s.lo[0], s.lo[1], s.lo[2]}, hi_corner}},
                               {"shape", {{"union", members}}}};
        sdf::Part part = sdf::parse_part(composed.dump(), r.name);
        // The grid exactly as the world's (the bounds' division may round either way).
        part.lo = s.lo;
        part.dims = s.dims;
        for (int a = 0; a < 3; ++a) {
            part.hi[a] = s.lo[a] + double(n[a]) * h;
        }
        s.part = std::move(part);
    }
    return s;
}

Scene load_scene(const fs::path& path) {
    std::uint64_t size = 0;
    std::ifstream in = detail::open_input(path, size);
    std::ostringstream text;
    text << in.rdbuf();
    return parse_scene(text.str(), path);
}

World Scene::world(const std::string& name) const {
    World w = part ? sdf::solid_world(*part, name) : World(dims);
    place_vox([&](std::uint32_t x, std::uint32_t y, std::uint32_t z, std::uint8_t v) {
        w.set(x, y, z, v);
    });
    return w;
}

}  // namespace voxfield::scene
