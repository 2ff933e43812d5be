// `.sdf.json` (DESIGN §3) parsed, validated and compiled to the postfix tape of sdf_layout.hpp.
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <fstream>
#include <limits>
#include <numbers>
#include <sstream>
#include <string>

#include "input_file.hpp"
#include "voxfield/core/error.hpp"
#include "voxfield/core/sdf.hpp"

namespace voxfield::sdf {
namespace {

using nlohmann::json;

// Most nodes a part may have (its tape has about as many instructions).
constexpr std::size_t kMaxNodes = 65536;

class Compiler {
  public:
    explicit Compiler(std::string name) : name_(std::move(name)) {}

    [[noreturn]] void fail(const std::string& where, const std::string& what) const {
        throw InputError(name_ + ": " + where + ": " + what);
    }

    const json& field(const json& obj, const std::string& where, const char* key) const {
        const auto it = obj.find(key);
        if (it == obj.end()) {
            fail(where, std::string("missing field '") + key + "'");
        }
        return *it;
    }

    double number(const json& v, const std::string& where) const {
        if (!v.is_number()) {
            fail(where, "expected a number, got " + type_of(v));
        }
        const double d = v.get<double>();
        if (!std::isfinite(d) || std::abs(d) > 1e30) {
            fail(where, "number out of range");
        }
        return d;
    }

    double positive(const json& v, const std::string& where) const {
        const double d = number(v, where);
        if (!(d > 0)) {
            fail(where, "must be positive, got " + v.dump());
        }
        return d;
    }

    std::array<double, 3> vec3(const json& v, const std::string& where) const {
        if (!v.is_array() || v.size() != 3) {
            fail(where, "expected an array of 3 numbers, got " + brief(v));
        }
        return {number(v[0], where + "[0]"), number(v[1], where + "[1]"),
                number(v[2], where + "[2]")};
    }

    std::array<double, 3> positive3(const json& v, const std::string& where) const {
        const auto a = vec3(v, where);
        for (double d : a) {
            if (!(d > 0)) {
                fail(where, "every component must be positive, got " + v.dump());
            }
        }
        return a;
    }

    // The field `key` of `obj` (at `where`) read as above, its errors at `where`.key.
    double number_at(const json& obj, const std::string& where, const char* key) const {
        return number(field(obj, where, key), where + "." + key);
    }
    double positive_at(const json& obj, const std::string& where, const char* key) const {
        return positive(field(obj, where, key), where + "." + key);
    }
    std::array<double, 3> vec3_at(const json& obj, const std::string& where,
                                  const char* key) const {
        return vec3(field(obj, where, key), where + "." + key);
    }
    std::array<double, 3> positive3_at(const json& obj, const std::string& where,
                                       const char* key) const {
        return positive3(field(obj, where, key), where + "." + key);
    }

    // Checks that `obj` (a node's body) has only the keys in `allowed`.
    void only_keys(const json& obj, const std::string& where,
                   std::initializer_list<const char*> allowed) const {
        if (!obj.is_object()) {
            fail(where, "expected an object, got " + type_of(obj));
        }
        for (const auto& item : obj.items()) {
            if (std::none_of(allowed.begin(), allowed.end(),
                             [&](const char* k) { return item.key() == k; })) {
                fail(where, "unknown field '" + item.key() + "'");
            }
        }
    }

    static std::string type_of(const json& v) {
        if (v.is_number()) {
            return "a number";
        }
        if (v.is_string()) {
            return "a string";
        }
        if (v.is_boolean()) {
            return "a boolean";
        }
        if (v.is_null()) {
            return "null";
        }
        return v.is_array() ? "an array" : "an object";
    }

    static std::string brief(const json& v) {
        std::string s = v.dump();
        return s.size() > 40 ? s.substr(0, 37) + "..." : s;
    }

    // Compiles NODE at `where`, `depth` nodes deep (1: the shape), whose primitives default to
    // `material`.
    void node(const json& n, const std::string& where, std::size_t depth, std::uint32_t material) {
        if (depth > VF_SDF_MAX_DEPTH) {
            fail(where,
                 "tree too deep (more than " + std::to_string(VF_SDF_MAX_DEPTH) + " nested nodes)");
        }
        if (++nodes_ > kMaxNodes) {
            fail(where, "too many nodes (more than " + std::to_string(kMaxNodes) + ")");
        }
        depth_ = std::max(depth_, depth);
        if (!n.is_object()) {
            fail(where, "expected a node (an object), got " + type_of(n));
        }
        std::string kind;
        for (const auto& item : n.items()) {
            if (item.key() == "material") {
                const json& m = item.value();
                if (!m.is_number_integer() || m.get<std::int64_t>() < 1 ||
                    m.get<std::int64_t>() > 255) {
                    fail(where + ".material", "must be an integer in 1..255, got " + brief(m));
                }
                material = static_cast<std::uint32_t>(m.get<std::int64_t>());
            } else if (!kind.empty()) {
                fail(where,
                     "a node has one kind, got both '" + kind + "' and '" + item.key() + "'");
            } else {
                kind = item.key();
            }
        }
        if (kind.empty()) {
            fail(where,
                 "a node needs a kind (sphere, box, round_box, cylinder, torus, capsule, "
                 "plane, union, intersection, difference, smooth_union, "
                 "smooth_difference, transform, shell)");
        }
        const json& b = n.at(kind);
        const std::string at = where + "." + kind;
        if (kind == "sphere") {
            only_keys(b, at, {"center", "radius"});
            const auto c = vec3_at(b, at, "center");
            const double r = positive_at(b, at, "radius");
            emit(VF_SDF_SPHERE, material, {c[0], c[1], c[2], r});
        } else if (kind == "box") {
            only_keys(b, at, {"center", "half_size"});
            const auto c = vec3_at(b, at, "center");
            const auto s = positive3_at(b, at, "half_size");
            emit(VF_SDF_BOX, material, {c[0], c[1], c[2], s[0], s[1], s[2]});
        } else if (kind == "round_box") {
            only_keys(b, at, {"center", "half_size", "radius"});
            const auto c = vec3_at(b, at, "center");
            const auto s = positive3_at(b, at, "half_size");
            const double r = positive_at(b, at, "radius");
            if (r > std::min({s[0], s[1], s[2]})) {
                fail(at + ".radius", "must not exceed the smallest half_size");
            }
            emit(VF_SDF_ROUND_BOX, material, {c[0], c[1], c[2], s[0], s[1], s[2], r});
        } else if (kind == "cylinder") {
            only_keys(b, at, {"center", "radius", "half_height"});
            const auto c = vec3_at(b, at, "center");
            const double r = positive_at(b, at, "radius");
            const double hh = positive_at(b, at, "half_height");
            emit(VF_SDF_CYLINDER, material, {c[0], c[1], c[2], r, hh});
        } else if (kind == "torus") {
            only_keys(b, at, {"center", "major", "minor"});
            const auto c = vec3_at(b, at, "center");
            const double big = positive_at(b, at, "major");
            const double small = positive_at(b, at, "minor");
            emit(VF_SDF_TORUS, material, {c[0], c[1], c[2], big, small});
        } else if (kind == "capsule") {
            only_keys(b, at, {"a", "b", "radius"});
            const auto a = vec3_at(b, at, "a");
            const auto e = vec3_at(b, at, "b");
            const double r = positive_at(b, at, "radius");
            emit(VF_SDF_CAPSULE, material, {a[0], a[1], a[2], e[0], e[1], e[2], r});
        } else if (kind == "plane") {
            only_keys(b, at, {"normal", "offset"});
            const auto nv = vec3_at(b, at, "normal");
            const double len = std::sqrt(nv[0] * nv[0] + nv[1] * nv[1] + nv[2] * nv[2]);
            if (!(len > 0)) {
                fail(at + ".normal", "must not be zero");
            }
            const double off = number_at(b, at, "offset");
            emit(VF_SDF_PLANE, material, {nv[0] / len, nv[1] / len, nv[2] / len, off});
        } else if (kind == "union" || kind == "intersection") {
            list(b, at, 1, depth, material, kind == "union" ? VF_SDF_MIN : VF_SDF_MAX, {});
        } else if (kind == "difference") {
            if (!b.is_array() || b.size() != 2) {
                fail(at, "expected an array of two nodes [A, B], got " + brief(b));
            }
            list(b, at, 2, depth, material, VF_SDF_DIFF, {});
        } else if (kind == "smooth_union" || kind == "smooth_difference") {
            only_keys(b, at, {"k", "of"});
            const double k = positive_at(b, at, "k");
            const json& of = field(b, at, "of");
            if (kind == "smooth_difference" && (!of.is_array() || of.size() != 2)) {
                fail(at + ".of", "expected an array of two nodes [A, B], got " + brief(of));
            }
            list(of, at + ".of", kind == "smooth_union" ? 1 : 2, depth, material,
                 kind == "smooth_union" ? VF_SDF_SMOOTH_MIN : VF_SDF_SMOOTH_DIFF, {k});
        } else if (kind == "transform") {
            transform(b, at, depth, material);
        } else if (kind == "shell") {
            only_keys(b, at, {"thickness", "of"});
            const double t = positive_at(b, at, "thickness");
            node(field(b, at, "of"), at + ".of", depth + 1, material);
            emit(VF_SDF_SHELL, 0, {t});
        } else {
            fail(where, "unknown node '" + kind + "'");
        }
    }

    // An n-ary operator: children folded left by the binary `op`.
    void list(const json& arr, const std::string& at, std::size_t min_size, std::size_t depth,
              std::uint32_t material, std::uint32_t op, std::initializer_list<double> params) {
        if (!arr.is_array() || arr.size() < min_size) {
            fail(at, "expected an array of at least " + std::to_string(min_size) +
                         " node(s), got " + brief(arr));
        }
        const auto a_start = static_cast<double>(tape_.code.size());
        for (std::size_t i = 0; i < arr.size(); ++i) {
            const auto b_start = static_cast<double>(tape_.code.size());
            node(arr[i], at + "[" + std::to_string(i) + "]", depth + 1, material);
            if (i > 0) {
                // p[0] = k (smooth operators), p[1] / p[2] = where A's / B's code starts.
                emit(op, 0, {params.size() != 0 ? *params.begin() : 0.0, a_start, b_start});
            }
        }
    }

    void transform(const json& b, const std::string& at, std::size_t depth,
                   std::uint32_t material) {
        only_keys(b, at, {"translate", "rotate_deg", "scale", "of"});
        std::array<double, 3> t{0, 0, 0}, r{0, 0, 0};
        double s = 1;
        if (b.contains("translate")) {
            t = vec3(b["translate"], at + ".translate");
        }
        if (b.contains("rotate_deg")) {
            r = vec3(b["rotate_deg"], at + ".rotate_deg");
        }
        if (b.contains("scale")) {
            s = positive(b["scale"], at + ".scale");
        }
        // R = Rz Ry Rx (x first); the child is evaluated at R^T (p - t) / s.
        const double deg = std::numbers::pi / 180;
        const double cx = std::cos(r[0] * deg), sx = std::sin(r[0] * deg);
        const double cy = std::cos(r[1] * deg), sy = std::sin(r[1] * deg);
        const double cz = std::cos(r[2] * deg), sz = std::sin(r[2] * deg);
        const double rx[3][3] = {{1, 0, 0}, {0, cx, -sx}, {0, sx, cx}};
        const double ry[3][3] = {{cy, 0, sy}, {0, 1, 0}, {-sy, 0, cy}};
        const double rz[3][3] = {{cz, -sz, 0}, {sz, cz, 0}, {0, 0, 1}};
        double zy[3][3]{}, rot[3][3]{};
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                for (int k = 0; k < 3; ++k) {
                    zy[i][j] += rz[i][k] * ry[k][j];
                }
            }
        }
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                for (int k = 0; k < 3; ++k) {
                    rot[i][j] += zy[i][k] * rx[k][j];
                }
            }
        }
        std::vector<double> p;
        for (int i = 0; i < 3; ++i) {
            for (int j = 0; j < 3; ++j) {
                p.push_back(rot[j][i] / s);  // (R^T / s)[i][j]
            }
        }
        p.insert(p.end(), t.begin(), t.end());
        emit_point(+1);
        emit(VF_SDF_PUSH_POINT, 0, p);
        node(field(b, at, "of"), at + ".of", depth + 1, material);
        emit(VF_SDF_POP_POINT, 0, {s});
        emit_point(-1);
    }

    void emit(std::uint32_t op, std::uint32_t material, const std::vector<double>& params) {
        Instr in;
        in.op = op;
        in.material = material;
        for (std::size_t i = 0; i < params.size(); ++i) {
            in.p[i] = static_cast<float>(params[i]);
        }
        tape_.code.push_back(in);
        if (op <= VF_SDF_PLANE) {
            ++values_;
        } else if (op >= VF_SDF_MIN && op <= VF_SDF_SMOOTH_DIFF) {
            --values_;
        }
        tape_.max_values = std::max(tape_.max_values, values_);
    }
    void emit(std::uint32_t op, std::uint32_t material, std::initializer_list<double> params) {
        emit(op, material, std::vector<double>(params));
    }
    void emit_point(int delta) {
        points_ = static_cast<std::uint32_t>(static_cast<int>(points_) + delta);
        tape_.max_points = std::max(tape_.max_points, points_);
    }

    Tape take_tape() { return std::move(tape_); }
    std::size_t nodes() const { return nodes_; }
    std::size_t depth() const { return depth_; }

  private:
    std::string name_;
    Tape tape_;
    std::uint32_t values_ = 0, points_ = 1;
    std::size_t nodes_ = 0, depth_ = 0;
};

}  // namespace

Part parse_part(const std::string& text, const std::string& name) {
    json doc;
    try {
        doc = json::parse(text);
    } catch (const json::parse_error& e) {
        std::string what = e.what();
        const auto colon = what.find("parse error");
        throw InputError(name + ": not valid JSON (" +
                         (colon == std::string::npos ? what : what.substr(colon)) + ")");
    }
    Compiler c(name);
    c.only_keys(doc, "top level", {"version", "voxel_size", "bounds", "shape"});
    const json& version = c.field(doc, "top level", "version");
    if (!version.is_number_integer() || version.get<std::int64_t>() != 1) {
        c.fail("version", "unsupported version " + Compiler::brief(version) + " (expected 1)");
    }
    Part part;
    part.voxel_size = c.number(c.field(doc, "top level", "voxel_size"), "voxel_size");
    if (!(part.voxel_size > 0)) {
        c.fail("voxel_size", "must be positive, got " + doc["voxel_size"].dump());
    }
    const json& bounds = c.field(doc, "top level", "bounds");
    if (!bounds.is_array() || bounds.size() != 2) {
        c.fail("bounds", "expected [[x0, y0, z0], [x1, y1, z1]], got " + Compiler::brief(bounds));
    }
    part.lo = c.vec3(bounds[0], "bounds[0]");
    part.hi = c.vec3(bounds[1], "bounds[1]");
    std::uint32_t n[3];
    for (int a = 0; a < 3; ++a) {
        if (!(part.hi[a] > part.lo[a])) {
            c.fail("bounds", std::string("empty bounds: ") + "xyz"[a] + " from " +
                                 std::to_string(part.lo[a]) + " to " + std::to_string(part.hi[a]));
        }
        const double cells = std::ceil((part.hi[a] - part.lo[a]) / part.voxel_size);
        if (cells > double(1u << 24)) {
            c.fail("bounds", std::string("the grid has ") + std::to_string(cells) +
                                 " voxels along " + "xyz"[a] + " (at most 2^24)");
        }
        n[a] = static_cast<std::uint32_t>(cells);
    }
    part.dims = Dims{n[0], n[1], n[2]};
    c.node(c.field(doc, "top level", "shape"), "shape", 1, 1);
    part.tape = c.take_tape();
    part.nodes = c.nodes();
    part.depth = c.depth();
    return part;
}

Part load_part(const std::filesystem::path& path) {
    std::uint64_t size = 0;
    std::ifstream in = detail::open_input(path, size);
    std::ostringstream text;
    text << in.rdbuf();
    return parse_part(text.str(), path.string());
}

bool is_sdf_path(const std::filesystem::path& path) {
    std::string name = path.filename().string();
    std::transform(name.begin(), name.end(), name.begin(),
                   [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
    return name.size() > 9 && name.ends_with(".sdf.json");
}

float Part::corner_x(std::uint32_t i) const {
    return static_cast<float>(lo[0]) + static_cast<float>(i) * static_cast<float>(voxel_size);
}
float Part::corner_y(std::uint32_t j) const {
    return static_cast<float>(lo[1]) + static_cast<float>(j) * static_cast<float>(voxel_size);
}
float Part::corner_z(std::uint32_t k) const {
    return static_cast<float>(lo[2]) + static_cast<float>(k) * static_cast<float>(voxel_size);
}
Vec3 Part::corner(std::uint32_t i, std::uint32_t j, std::uint32_t k) const {
    return {corner_x(i), corner_y(j), corner_z(k)};
}
Vec3 Part::centre(std::uint32_t i, std::uint32_t j, std::uint32_t k) const {
    const float h = static_cast<float>(voxel_size);
    return {static_cast<float>(lo[0]) + (static_cast<float>(i) + 0.5f) * h,
            static_cast<float>(lo[1]) + (static_cast<float>(j) + 0.5f) * h,
            static_cast<float>(lo[2]) + (static_cast<float>(k) + 0.5f) * h};
}
Box Part::box(std::uint32_t i0, std::uint32_t j0, std::uint32_t k0, std::uint32_t i1,
              std::uint32_t j1, std::uint32_t k1) const {
    return {
        {corner_x(i0), corner_x(i1)}, {corner_y(j0), corner_y(j1)}, {corner_z(k0), corner_z(k1)}};
}

}  // namespace voxfield::sdf
