// NumPy .npy reader/writer (format spec: numpy.lib.format, versions 1.0, 2.0 and 3.0).
#include "voxfield/core/npy.hpp"

#include "input_file.hpp"
#include "output_file.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <bit>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "voxfield/core/error.hpp"

namespace voxfield {

static_assert(std::endian::native == std::endian::little, "voxfield assumes a little-endian host");

namespace {

namespace fs = std::filesystem;

struct TypeInfo {
    NpyType type;
    std::size_t size;
    const char* name;
    const char* descr;  // as written
    const char* kind;   // descr without the byte order
};

constexpr TypeInfo kTypes[] = {
    {NpyType::u8, 1, "uint8", "|u1", "u1"},    {NpyType::u16, 2, "uint16", "<u2", "u2"},
    {NpyType::u32, 4, "uint32", "<u4", "u4"},  {NpyType::i8, 1, "int8", "|i1", "i1"},
    {NpyType::i16, 2, "int16", "<i2", "i2"},   {NpyType::i32, 4, "int32", "<i4", "i4"},
    {NpyType::f32, 4, "float32", "<f4", "f4"}, {NpyType::f64, 8, "float64", "<f8", "f8"},
    {NpyType::b1, 1, "bool", "|b1", "b1"},     {NpyType::u64, 8, "uint64", "<u8", "u8"},
    {NpyType::i64, 8, "int64", "<i8", "i8"},
};

const TypeInfo& type_info(NpyType t) {
    for (const TypeInfo& i : kTypes) {
        if (i.type == t) {
            return i;
        }
    }
    return kTypes[0];
}

std::size_t elem_size(NpyType t) {
    return type_info(t).size;
}

const char* type_name(NpyType t) {
    return type_info(t).name;
}

const char* descr_of(NpyType t) {
    return type_info(t).descr;
}

// A Python literal as found in a .npy header: a string, a bool, an int, a tuple of ints, or a
// list (a structured dtype's fields, kept as written).
struct Value {
    enum class Kind { string, boolean, integer, tuple, list, none } kind = Kind::none;
    std::string text;                  // string
    bool flag = false;                 // boolean
    std::uint64_t number = 0;          // integer
    std::vector<std::uint64_t> items;  // tuple
    std::string source;                // as written, for messages
};

class HeaderParser {
  public:
    HeaderParser(const std::string& file, const std::string& text) : file_(file), s_(text) {}

    // Parses "{'key': value, ...}" into (key, value) pairs.
    std::vector<std::pair<std::string, Value>> parse_dict() {
        std::vector<std::pair<std::string, Value>> out;
        skip_ws();
        expect('{');
        skip_ws();
        while (peek() != '}') {
            Value key = parse_value();
            if (key.kind != Value::Kind::string) {
                fail("expected a string key at '" + key.source + "'");
            }
            skip_ws();
            expect(':');
            skip_ws();
            Value value = parse_value();
            out.emplace_back(key.text, value);
            skip_ws();
            if (peek() == ',') {
                ++i_;
                skip_ws();
            } else if (peek() != '}') {
                fail_here("expected ',' or '}'");
            }
        }
        ++i_;
        skip_ws();
        if (i_ != s_.size()) {
            fail_here("unexpected text after the dictionary");
        }
        return out;
    }

  private:
    [[noreturn]] void fail(const std::string& what) const {
        throw InputError(file_ + ": malformed header: " + what);
    }
    [[noreturn]] void fail_here(const std::string& what) const {
        if (i_ >= s_.size()) {
            fail(what + " but the header ends");
        }
        fail(what + " at column " + std::to_string(i_ + 1) + " ('" + s_.substr(i_, 16) + "')");
    }
    char peek() const { return i_ < s_.size() ? s_[i_] : '\0'; }
    void skip_ws() {
        while (i_ < s_.size() && (s_[i_] == ' ' || s_[i_] == '\t' || s_[i_] == '\n' ||
                                  s_[i_] == '\r' || s_[i_] == '\0')) {
            ++i_;
        }
    }
    void expect(char c) {
        if (peek() != c) {
            fail_here(std::string("expected '") + c + "'");
        }
        ++i_;
    }
    static bool is_digit(char c) { return c >= '0' && c <= '9'; }

    std::uint64_t parse_int() {
        const std::size_t start = i_;
        if (!is_digit(peek())) {
            fail_here("expected a non-negative integer");
        }
        std::uint64_t v = 0;
        while (is_digit(peek())) {
            const auto digit = static_cast<std::uint64_t>(s_[i_] - '0');
            if (v > (std::numeric_limits<std::uint64_t>::max() - digit) / 10) {
                fail("integer '" + s_.substr(start, i_ - start + 1) + "...' is too large");
            }
            v = v * 10 + digit;
            ++i_;
        }
        if (peek() == 'L') {  // Python 2 long suffix
            ++i_;
        }
        return v;
    }

    Value parse_value() {
        Value v;
        const std::size_t start = i_;
        const char c = peek();
        if (c == '\'' || c == '"') {
            ++i_;
            const std::size_t end = s_.find(c, i_);
            if (end == std::string::npos) {
                fail("unterminated string starting at column " + std::to_string(start + 1));
            }
            v.kind = Value::Kind::string;
            v.text = s_.substr(i_, end - i_);
            i_ = end + 1;
        } else if (s_.compare(i_, 4, "True") == 0) {
            v.kind = Value::Kind::boolean;
            v.flag = true;
            i_ += 4;
        } else if (s_.compare(i_, 5, "False") == 0) {
            v.kind = Value::Kind::boolean;
            i_ += 5;
        } else if (c == '(') {
            ++i_;
            v.kind = Value::Kind::tuple;
            skip_ws();
            while (peek() != ')') {
                v.items.push_back(parse_int());
                skip_ws();
                if (peek() == ',') {
                    ++i_;
                    skip_ws();
                } else if (peek() != ')') {
                    fail_here("expected ',' or ')' in a tuple");
                }
            }
            ++i_;
        } else if (is_digit(c)) {
            v.kind = Value::Kind::integer;
            v.number = parse_int();
        } else if (c == '[') {
            skip_list();
            v.kind = Value::Kind::list;
        } else {
            fail_here("expected a string, True, False, an integer, a tuple or a list");
        }
        v.source = s_.substr(start, i_ - start);
        return v;
    }

    // Past a list and everything nested in it (brackets, parentheses, quoted strings).
    void skip_list() {
        const std::size_t start = i_;
        int depth = 0;
        do {
            const char c = peek();
            if (c == '\0' && i_ >= s_.size()) {
                fail("unterminated list starting at column " + std::to_string(start + 1));
            }
            if (c == '\'' || c == '"') {
                const std::size_t end = s_.find(c, i_ + 1);
                if (end == std::string::npos) {
                    fail("unterminated string starting at column " + std::to_string(i_ + 1));
                }
                i_ = end;
            } else if (c == '[' || c == '(') {
                ++depth;
            } else if (c == ']' || c == ')') {
                --depth;
            }
            ++i_;
        } while (depth > 0);
    }

    std::string file_;
    std::string s_;
    std::size_t i_ = 0;
};

// What every dtype rejection says a world .npy must hold (the reader also takes float32 and
// float64, for fields read back, but every input a command reads is a world).
constexpr const char* kWorldDtypes =
    "a world is a bool or integer array (a label volume: 0 = empty, nonzero = solid)";

// NumPy's name of a dtype kind ("c8" -> "complex64", "U3" -> "str"), "" when unknown.
std::string numpy_name(const std::string& kind) {
    static const std::pair<const char*, const char*> names[] = {
        {"b1", "bool"},      {"i1", "int8"},      {"i2", "int16"},       {"i4", "int32"},
        {"i8", "int64"},     {"u1", "uint8"},     {"u2", "uint16"},      {"u4", "uint32"},
        {"u8", "uint64"},    {"f2", "float16"},   {"f4", "float32"},     {"f8", "float64"},
        {"f16", "float128"}, {"c8", "complex64"}, {"c16", "complex128"}, {"c32", "complex256"},
        {"O", "object"},     {"O8", "object"},    {"?", "bool"}};
    for (const auto& [k, name] : names) {
        if (kind == k) {
            return name;
        }
    }
    if (kind.empty()) {
        return "";
    }
    switch (kind[0]) {
        case 'U':
            return "str";
        case 'S':
        case 'a':
            return "bytes";
        case 'V':
            return "void";
        case 'M':
            return "datetime64";
        case 'm':
            return "timedelta64";
        default:
            return "";
    }
}

std::string shape_text(const std::vector<std::uint64_t>& shape) {
    std::string s = "(";
    for (std::size_t k = 0; k < shape.size(); ++k) {
        s += (k ? ", " : "") + std::to_string(shape[k]);
    }
    if (shape.size() == 1) {
        s += ",";
    }
    return s + ")";
}

}  // namespace

struct NpyReader::File {
    explicit File(const std::filesystem::path& path) : fd(path) {}
    detail::InputFd fd;
};

NpyReader::~NpyReader() = default;
NpyReader::NpyReader(NpyReader&&) noexcept = default;
NpyReader& NpyReader::operator=(NpyReader&&) noexcept = default;

NpyReader::NpyReader(const std::filesystem::path& path) : file_(std::make_unique<File>(path)) {
    const std::string file = path.string();
    const detail::InputFd& in = file_->fd;
    const std::uint64_t size = in.size();

    // Preamble: magic (6), version (2), header length (2 or 4).
    const char magic[] = "\x93NUMPY";
    char pre[12] = {};
    if (size < 10) {
        throw InputError(file + ": not a .npy file (only " + std::to_string(size) +
                         " bytes, shorter than the 10-byte preamble)");
    }
    in.read_at(0, pre, 10);
    if (std::memcmp(pre, magic, 6) != 0) {
        throw InputError(file + ": not a .npy file (missing the \\x93NUMPY magic)");
    }
    const auto major = static_cast<unsigned char>(pre[6]);
    const auto minor = static_cast<unsigned char>(pre[7]);
    if (major < 1 || major > 3) {
        throw InputError(file + ": .npy format version " + std::to_string(major) + "." +
                         std::to_string(minor) + " is not supported (expected 1.0, 2.0 or 3.0)");
    }
    std::uint64_t header_len = 0;
    std::uint64_t header_start = 10;
    if (major == 1) {
        header_len = static_cast<std::uint64_t>(static_cast<unsigned char>(pre[8])) |
                     (static_cast<std::uint64_t>(static_cast<unsigned char>(pre[9])) << 8);
    } else {
        if (size < 12) {
            throw InputError(file + ": truncated: the .npy " + std::to_string(major) +
                             ".0 preamble needs 12 bytes, file has " + std::to_string(size));
        }
        in.read_at(10, pre + 10, 2);
        for (int k = 0; k < 4; ++k) {
            header_len |= static_cast<std::uint64_t>(static_cast<unsigned char>(pre[8 + k]))
                          << (8 * k);
        }
        header_start = 12;
    }
    if (header_start + header_len > size) {
        throw InputError(file + ": truncated: header needs " + std::to_string(header_len) +
                         " bytes at offset " + std::to_string(header_start) + ", file has " +
                         std::to_string(size - header_start));
    }
    std::string header(static_cast<std::size_t>(header_len), '\0');
    in.read_at(header_start, header.data(), header.size());

    HeaderParser parser(file, header);
    std::optional<Value> descr, fortran, shape;
    for (auto& [key, value] : parser.parse_dict()) {
        if (key == "descr") {
            descr = value;
        } else if (key == "fortran_order") {
            fortran = value;
        } else if (key == "shape") {
            shape = value;
        }
    }
    if (!descr || !fortran || !shape) {
        throw InputError(file + ": malformed header: missing key '" +
                         std::string(!descr     ? "descr"
                                     : !fortran ? "fortran_order"
                                                : "shape") +
                         "'");
    }
    if (descr->kind != Value::Kind::string) {
        throw InputError(file + ": dtype " + descr->source +
                         (descr->kind == Value::Kind::list ? " (a structured array)" : "") +
                         " is not supported: " + kWorldDtypes);
    }
    if (fortran->kind != Value::Kind::boolean) {
        throw InputError(file + ": malformed header: fortran_order is " + fortran->source +
                         ", expected True or False");
    }
    if (shape->kind != Value::Kind::tuple) {
        throw InputError(file + ": malformed header: shape is " + shape->source +
                         ", expected a tuple");
    }

    const std::string& d = descr->text;
    const char order = d.size() == 3 ? d[0] : '\0';
    const std::string kind = d.size() == 3 ? d.substr(1) : d;
    const TypeInfo* found = nullptr;
    for (const TypeInfo& i : kTypes) {
        if (kind == i.kind) {
            found = &i;
        }
    }
    const bool one_byte = found != nullptr && found->size == 1;
    const bool is_float =
        found != nullptr && (found->type == NpyType::f32 || found->type == NpyType::f64);
    if (found != nullptr && !one_byte && !is_float && order == '>') {
        throw InputError(file + ": dtype '" + printable(d) + "' (" + found->name +
                         ", big-endian) is not supported: only little-endian arrays are read "
                         "(save it with a.astype('<" +
                         kind + "'))");
    }
    const bool order_ok = d.size() == 2 || order == '<' || order == '=' ||
                          (one_byte && (order == '|' || order == '>'));
    if (found == nullptr || !order_ok || (is_float && order == '>')) {
        const bool ordered = !d.empty() && std::string("<>|=").find(d[0]) != std::string::npos;
        const std::string name = numpy_name(ordered ? d.substr(1) : d);
        throw InputError(file + ": dtype '" + printable(d) + "'" +
                         (name.empty() ? "" : " (" + name + ")") +
                         " is not supported: " + kWorldDtypes);
    }
    type_ = found->type;
    if (fortran->flag) {
        throw InputError(file + ": fortran_order is True (only C-order arrays are supported)");
    }
    const auto& sh = shape->items;
    if (sh.size() != 3) {
        throw InputError(file + ": shape " + shape_text(sh) + " has " + std::to_string(sh.size()) +
                         " dimensions (expected 3: Z, Y, X)");
    }
    for (std::uint64_t n : sh) {
        if (n == 0) {
            throw InputError(file + ": shape " + shape_text(sh) + " has an empty axis");
        }
        if (n > std::numeric_limits<std::uint32_t>::max()) {
            throw InputError(file + ": shape " + shape_text(sh) + " has an axis too large");
        }
    }
    dims_ = {static_cast<std::uint32_t>(sh[2]), static_cast<std::uint32_t>(sh[1]),
             static_cast<std::uint32_t>(sh[0])};
    const std::uint64_t data_start = header_start + header_len;
    const std::uint64_t available = size - data_start;
    const std::uint64_t es = elem_size(type_);
    // Compare without overflow: count * es <= available.
    const std::uint64_t limit = available / es;
    const bool fits = sh[0] <= limit && sh[1] <= limit / sh[0] && sh[2] <= limit / (sh[0] * sh[1]);
    if (!fits) {
        const long double need = static_cast<long double>(sh[0]) * static_cast<long double>(sh[1]) *
                                 static_cast<long double>(sh[2]) * static_cast<long double>(es);
        std::string need_text = need < 1.8e19L ? std::to_string(static_cast<std::uint64_t>(need))
                                               : std::string("more than 2^64");
        throw InputError(file + ": truncated: shape " + shape_text(sh) + " of " + type_name(type_) +
                         " needs " + need_text + " data bytes at offset " +
                         std::to_string(data_start) + ", file has " + std::to_string(available));
    }
    data_offset_ = data_start;
    data_bytes_ = static_cast<std::size_t>(sh[0] * sh[1] * sh[2] * es);
}

void NpyReader::read_data(std::span<std::uint8_t> dst) const {
    if (dst.size() != data_bytes_) {
        throw std::invalid_argument("NpyReader::read_data: " + std::to_string(dst.size()) +
                                    " bytes for " + std::to_string(data_bytes_) + " of data");
    }
    file_->fd.read_at(data_offset_, dst.data(), dst.size());
}

NpyArray read_npy(const std::filesystem::path& path) {
    const NpyReader reader(path);
    NpyArray a;
    a.type = reader.type();
    a.dims = reader.dims();
    a.data.resize(reader.data_bytes());
    reader.read_data(a.data);
    return a;
}

void write_npy(const std::filesystem::path& path, NpyType type, Dims dims,
               std::span<const std::uint8_t> data) {
    OutputBatch batch;
    write_npy(batch, path, type, dims, data);
    batch.commit();
}

void write_npy(OutputBatch& batch, const std::filesystem::path& path, NpyType type, Dims dims,
               std::span<const std::uint8_t> data) {
    if (dims.x == 0 || dims.y == 0 || dims.z == 0) {
        throw InputError("cannot write '" + path.string() + "': dims " + dims.to_string() +
                         " have an empty axis");
    }
    write_npy_shape(batch, path, type, {dims.z, dims.y, dims.x}, data);
}

void write_npy(const std::filesystem::path& path, NpyType type, Dims dims,
               const std::vector<std::uint8_t>& data) {
    write_npy(path, type, dims, std::span<const std::uint8_t>(data));
}

void write_npy_shape(const std::filesystem::path& path, NpyType type,
                     const std::vector<std::uint64_t>& shape,
                     const std::vector<std::uint8_t>& data) {
    write_npy_shape(path, type, shape, std::span<const std::uint8_t>(data));
}

void write_npy_shape(const std::filesystem::path& path, NpyType type,
                     const std::vector<std::uint64_t>& shape, std::span<const std::uint8_t> data) {
    OutputBatch batch;
    write_npy_shape(batch, path, type, shape, data);
    batch.commit();
}

namespace {

// Elements of an array of `shape` and its shape as the header writes it: "(a, b, c)", "(a,)".
std::uint64_t shape_count(const std::vector<std::uint64_t>& shape, std::string& text) {
    std::uint64_t count = 1;
    text.clear();
    for (std::uint64_t n : shape) {
        count *= n;
        text += std::to_string(n) + ", ";
    }
    if (shape.size() > 1) {
        text.resize(text.size() - 2);
    }
    return count;
}

}  // namespace

void write_npy_shape(OutputBatch& batch, const std::filesystem::path& path, NpyType type,
                     const std::vector<std::uint64_t>& shape, std::span<const std::uint8_t> data) {
    std::string dims_text;
    if (data.size() != shape_count(shape, dims_text) * elem_size(type)) {
        throw InputError("cannot write '" + path.string() + "': " + std::to_string(data.size()) +
                         " bytes do not match shape (" + dims_text + ") of " + type_name(type));
    }
    write_npy_shape(batch, path, type, shape, [&](const OutputBatch::Sink& sink) { sink(data); });
}

void write_npy_shape(OutputBatch& batch, const std::filesystem::path& path, NpyType type,
                     const std::vector<std::uint64_t>& shape,
                     const std::function<void(const OutputBatch::Sink&)>& produce) {
    std::string dims_text;
    const std::uint64_t data_bytes = shape_count(shape, dims_text) * elem_size(type);
    std::string header = std::string("{'descr': '") + descr_of(type) +
                         "', 'fortran_order': False, 'shape': (" + dims_text + "), }";
    const std::size_t unpadded = 10 + header.size() + 1;  // + '\n'
    header.append((64 - unpadded % 64) % 64, ' ');
    header += '\n';
    // Magic, version 1.0, the header's length (little-endian u16), the header.
    std::string prefix("\x93NUMPY\x01\x00", 8);
    prefix += static_cast<char>(header.size() & 0xFF);
    prefix += static_cast<char>(header.size() >> 8);
    prefix += header;
    const std::span<const std::uint8_t> bytes(reinterpret_cast<const std::uint8_t*>(prefix.data()),
                                              prefix.size());

    batch.write(path, [&](const OutputBatch::Sink& sink) {
        sink(bytes);
        std::uint64_t written = 0;
        produce([&](std::span<const std::uint8_t> piece) {
            written += piece.size();
            if (written > data_bytes) {
                throw std::logic_error("write_npy_shape: more data than the shape holds");
            }
            sink(piece);
        });
        if (written != data_bytes) {
            throw std::logic_error("write_npy_shape: less data than the shape holds");
        }
    });
}

namespace {

// Element i of little-endian integer data of `type`, widened (bool: 0 or 1).
std::int64_t label_at(NpyType type, const std::uint8_t* p, std::size_t i) {
    switch (type) {
        case NpyType::u8:
        case NpyType::b1:
            return p[i];
        case NpyType::i8:
            return static_cast<std::int8_t>(p[i]);
        default:
            break;
    }
    const std::size_t es = elem_size(type);
    std::uint64_t v = 0;
    std::memcpy(&v, p + i * es, es);
    switch (type) {
        case NpyType::i16:
            return static_cast<std::int16_t>(v);
        case NpyType::i32:
            return static_cast<std::int32_t>(v);
        case NpyType::u64:
            // Above INT64_MAX only "nonzero" and "above 255" matter: saturate.
            return v > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max())
                       ? std::numeric_limits<std::int64_t>::max()
                       : static_cast<std::int64_t>(v);
        default:
            return static_cast<std::int64_t>(v);  // u16, u32, i64
    }
}

}  // namespace

const char* npy_type_name(NpyType type) {
    return type_name(type);
}

std::size_t npy_element_size(NpyType type) {
    return elem_size(type);
}

World world_from_labels(NpyType type, Dims dims, std::span<const std::uint8_t> data,
                        Labels labels) {
    if (type == NpyType::f32 || type == NpyType::f64) {
        throw InputError(std::string("dtype '") + descr_of(type) + "' (" + type_name(type) +
                         ") is not supported: " + kWorldDtypes);
    }
    const std::size_t es = elem_size(type);
    World world(dims);
    const std::size_t n = world.size();
    if (data.size() != n * es) {
        throw InputError("npy array of dims " + dims.to_string() + " has " +
                         std::to_string(data.size()) + " data bytes, expected " +
                         std::to_string(n * es));
    }
    auto& vox = world.voxels();
    const std::uint8_t* p = data.data();
    if (type == NpyType::u8) {
        std::memcpy(vox.data(), p, n);
        return world;
    }
    for (std::size_t i = 0; i < n; ++i) {
        const std::int64_t v = label_at(type, p, i);
        if (v >= 0 && v <= 255) {
            vox[i] = static_cast<std::uint8_t>(v);
        } else if (labels == Labels::solid) {
            vox[i] = 1;
        } else {
            const std::size_t x = i % dims.x, y = (i / dims.x) % dims.y,
                              z = i / (std::size_t{dims.x} * dims.y);
            throw InputError("value " + std::to_string(v) + " at voxel (x=" + std::to_string(x) +
                             ", y=" + std::to_string(y) + ", z=" + std::to_string(z) +
                             ") is not a palette index (expected 0..255)");
        }
    }
    return world;
}

World world_from_npy(const NpyArray& array, Labels labels) {
    return world_from_labels(array.type, array.dims, array.data, labels);
}

NpyArray npy_from_world(const World& world) {
    NpyArray a;
    a.type = NpyType::u8;
    a.dims = world.dims();
    a.data = world.voxels();
    return a;
}

}  // namespace voxfield
