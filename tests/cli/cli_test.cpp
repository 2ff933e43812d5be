// End-to-end tests of the `voxfield` executable (DESIGN §4): runs the binary, captures its
// stdout, stderr and exit code, and checks outputs against the exact CPU reference.
#include <fcntl.h>
#include <spawn.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include "cli_test_util.hpp"

#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "voxfield/core/chunks.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/vox.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield {
namespace {

using namespace voxfield::test;  // the spawn and file helpers of cli_test_util.hpp

namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kVox = fs::path(VOXFIELD_DATA_DIR) / "vox" / "chr_army1.vox";
const std::vector<std::string> kFormats = {"u8", "u16", "u32", "packed32"};

// A .npy file with an arbitrary header dict (format 1.0, padded with spaces to a multiple of
// 64 bytes, ending in '\n') followed by `data`.
std::string raw_npy(const std::string& descr, const std::string& shape, const std::string& data) {
    std::string dict =
        "{'descr': '" + descr + "', 'fortran_order': False, 'shape': " + shape + ", }";
    std::size_t total = 10 + dict.size() + 1;
    const std::size_t padded = (total + 63) / 64 * 64;
    dict.append(padded - total, ' ');
    dict += '\n';
    const auto len = static_cast<std::uint16_t>(dict.size());
    std::string out = "\x93NUMPY";
    out += '\x01';
    out += '\x00';
    out += static_cast<char>(len & 0xFF);
    out += static_cast<char>(len >> 8);
    out += dict;
    out += data;
    return out;
}

NpyType expected_type(const std::string& format) {
    if (format == "u8") {
        return NpyType::u8;
    }
    if (format == "u16") {
        return NpyType::u16;
    }
    return NpyType::u32;
}

// Index of the first differing element (element size `es`), or -1.
long long first_difference(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b,
                           std::size_t es) {
    const std::size_t n = std::min(a.size(), b.size());
    for (std::size_t i = 0; i < n; ++i) {
        if (a[i] != b[i]) {
            return static_cast<long long>(i / es);
        }
    }
    return a.size() == b.size() ? -1 : static_cast<long long>(n / es);
}

class CliTest : public TempDirsTest {
  protected:
    CliTest() : TempDirsTest("voxfield_cli") {}

    // Runs `generate` in every format and checks the output files against the reference.
    void check_generate(const fs::path& input, const World& world, const Palette& palette) {
        const std::vector<std::uint32_t> distances = reference_manhattan(world);
        for (const std::string& format : kFormats) {
            SCOPED_TRACE("format " + format);
            const fs::path out = dir_ / ("field_" + format + ".npy");
            const RunResult r = run({"generate", input.string(), "-o", out.string(), "--format",
                                     format, "--device", "cpu"});
            ASSERT_EQ(r.code, 0) << describe(r);
            ASSERT_TRUE(fs::is_regular_file(out)) << describe(r);
            const NpyArray a = read_npy(out);
            EXPECT_EQ(a.type, expected_type(format));
            EXPECT_EQ(a.dims, world.dims())
                << a.dims.to_string() << " vs " << world.dims().to_string();
            const Format f = parse_format(format);
            const std::vector<std::uint8_t> want = encode_field(distances, world, palette, f);
            EXPECT_EQ(a.data.size(), want.size());
            const long long diff = first_difference(a.data, want, element_size(f));
            EXPECT_EQ(diff, -1) << "first differing voxel (linear index) " << diff
                                << ": got distance "
                                << (diff >= 0 && a.data.size() == want.size()
                                        ? decode_distance(a.data, f, static_cast<std::size_t>(diff))
                                        : 0u)
                                << ", want "
                                << (diff >= 0
                                        ? decode_distance(want, f, static_cast<std::size_t>(diff))
                                        : 0u);
        }
        // Nothing but the outputs: no temporary files left next to them.
        std::set<std::string> expected = {input.filename().string()};
        for (const auto& format : kFormats) {
            expected.insert("field_" + format + ".npy");
        }
        if (input.parent_path() != dir_) {
            expected.erase(input.filename().string());
        }
        EXPECT_EQ(list_dir(dir_), expected);
    }
};

// A non-cubic world (distinct X, Y, Z catch axis-order mistakes) with palette indices up to
// 255 and a few isolated voxels.
World test_world() {
    World w = scene_floor_spheres(Dims{23, 17, 11}, 1234, 4);
    w.set(22, 16, 10, 255);
    w.set(0, 16, 0, 7);
    w.set(11, 9, 5, 200);
    return w;
}

std::vector<std::uint8_t> widen(const std::vector<std::uint8_t>& v, std::size_t es) {
    std::vector<std::uint8_t> out(v.size() * es, 0);
    for (std::size_t i = 0; i < v.size(); ++i) {
        out[i * es] = v[i];
    }
    return out;
}

// ---------------------------------------------------------------------------------------
// generate: end to end

TEST_F(CliTest, GenerateVoxMatchesReferenceInEveryFormat) {
    ASSERT_TRUE(fs::is_regular_file(kVox)) << kVox;
    const VoxModel model = read_vox(kVox);
    ASSERT_GT(model.world.solid_count(), 0u);
    check_generate(kVox, model.world, model.palette);
}

TEST_F(CliTest, GenerateUint8NpyMatchesReferenceInEveryFormat) {
    const World w = test_world();
    const fs::path in = dir_ / "world_u8.npy";
    write_npy(in, NpyType::u8, w.dims(), w.voxels());
    check_generate(in, w, Palette());
}

TEST_F(CliTest, GenerateUint16NpyMatchesReferenceInEveryFormat) {
    const World w = test_world();
    const fs::path in = dir_ / "world_u16.npy";
    write_npy(in, NpyType::u16, w.dims(), widen(w.voxels(), 2));
    check_generate(in, w, Palette());
}

TEST_F(CliTest, GenerateUint32NpyInput) {
    const World w = test_world();
    const fs::path in = dir_ / "world_u32.npy";
    write_npy(in, NpyType::u32, w.dims(), widen(w.voxels(), 4));
    const fs::path out = dir_ / "field.npy";
    const RunResult r =
        run({"generate", in.string(), "-o", out.string(), "--format", "u32", "--device", "cpu"});
    ASSERT_EQ(r.code, 0) << describe(r);
    const NpyArray a = read_npy(out);
    EXPECT_EQ(a.type, NpyType::u32);
    EXPECT_EQ(a.data, encode_field(reference_manhattan(w), w, Palette(), Format::u32));
}

// A label volume (DESIGN §3): uint16 labels above 255 are solid like any nonzero value; the
// field is the field of the volume's nonzero mask.
TEST_F(CliTest, GenerateUint16LabelVolumeIsItsNonzeroMask) {
    const World w = test_world();
    std::vector<std::uint8_t> labels = widen(w.voxels(), 2);
    for (std::size_t i = 0; i < w.voxels().size(); ++i) {
        if (w.voxels()[i] != 0) {
            labels[2 * i + 1] = static_cast<std::uint8_t>(1 + i % 250);  // labels 256..64255
        }
    }
    const fs::path in = dir_ / "labels_u16.npy";
    write_npy(in, NpyType::u16, w.dims(), labels);
    const fs::path out = dir_ / "field.npy";
    const RunResult r = run({"generate", in.string(), "-o", out.string(), "--device", "cpu"});
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(read_npy(out).data, encode_field(reference_manhattan(w), w, Palette(), Format::u16));
}

TEST_F(CliTest, GenerateEveryShippedVoxModel) {
    for (const auto& entry : fs::directory_iterator(fs::path(VOXFIELD_DATA_DIR) / "vox")) {
        if (entry.path().extension() != ".vox") {
            continue;
        }
        SCOPED_TRACE(entry.path().string());
        const VoxModel model = read_vox(entry.path());
        const fs::path out = dir_ / (entry.path().stem().string() + ".npy");
        const RunResult r = run({"generate", entry.path().string(), "-o", out.string(), "--format",
                                 "packed32", "--device", "cpu"});
        ASSERT_EQ(r.code, 0) << describe(r);
        const NpyArray a = read_npy(out);
        EXPECT_EQ(a.dims, model.world.dims());
        EXPECT_EQ(first_difference(a.data,
                                   encode_field(reference_manhattan(model.world), model.world,
                                                model.palette, Format::packed32),
                                   4),
                  -1);
    }
}

// Odd, larger dims (several work-groups along every axis, none a power of two) and only two
// solid voxels near one corner, so the far corner is 259 away: u8 must saturate at 255.
TEST_F(CliTest, GenerateLargerOddWorld) {
    World w(Dims{131, 9, 127});
    w.set(0, 0, 0, 3);
    w.set(1, 4, 0, 200);
    const fs::path in = dir_ / "odd.npy";
    write_npy(in, NpyType::u8, w.dims(), w.voxels());
    const std::vector<std::uint32_t> distances = reference_manhattan(w);
    for (const std::string format : {"u8", "u32"}) {
        SCOPED_TRACE(format);
        const fs::path out = dir_ / ("odd_" + format + ".npy");
        const RunResult r = run(
            {"generate", in.string(), "-o", out.string(), "--format", format, "--device", "cpu"});
        ASSERT_EQ(r.code, 0) << describe(r);
        const Format f = parse_format(format);
        const NpyArray a = read_npy(out);
        EXPECT_EQ(decode_distance(a.data, f, w.size() - 1), format == "u8" ? 255u : 259u);
        EXPECT_EQ(
            first_difference(a.data, encode_field(distances, w, Palette(), f), element_size(f)),
            -1);
    }
}

TEST_F(CliTest, GenerateEmptyWorldSaturates) {
    const World w(Dims{5, 4, 3});
    const fs::path in = dir_ / "empty.npy";
    write_npy(in, NpyType::u8, w.dims(), w.voxels());
    const fs::path out = dir_ / "field.npy";
    const RunResult r =
        run({"generate", in.string(), "-o", out.string(), "--format", "u16", "--device", "cpu"});
    ASSERT_EQ(r.code, 0) << describe(r);
    const NpyArray a = read_npy(out);
    ASSERT_EQ(a.data.size(), w.size() * 2);
    for (std::size_t i = 0; i < w.size(); ++i) {
        ASSERT_EQ(decode_distance(a.data, Format::u16, i), 65535u) << "voxel " << i;
    }
}

TEST_F(CliTest, GenerateStatsAndJson) {
    const World w = test_world();
    const fs::path in = dir_ / "world.npy";
    write_npy(in, NpyType::u8, w.dims(), w.voxels());
    const fs::path out = dir_ / "field.npy";
    const fs::path js = dir_ / "run.json";
    const RunResult r = run({"generate", in.string(), "-o", out.string(), "--device", "cpu",
                             "--stats", "--json", js.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_NE(r.out.find("max error 0"), std::string::npos) << r.out;
    ASSERT_TRUE(fs::is_regular_file(js));
    json j;
    ASSERT_NO_THROW(j = json::parse(read_text(js))) << read_text(js);
    ASSERT_TRUE(j.is_object());
    ASSERT_TRUE(j.contains("kernel_ms"));
    EXPECT_TRUE(j["kernel_ms"].is_number());
    EXPECT_GE(j["kernel_ms"].get<double>(), 0.0);
    ASSERT_TRUE(j.contains("size"));
    EXPECT_EQ(j["size"], json::array({23, 17, 11}));
    ASSERT_TRUE(j.contains("device"));
    ASSERT_TRUE(j["device"].is_object());
    EXPECT_TRUE(j["device"].contains("name"));
    EXPECT_EQ(j.value("max_error", 999u), 0u);
    EXPECT_EQ(list_dir(dir_), (std::set<std::string>{"world.npy", "field.npy", "run.json"}));
}

// --stats prints one line with the wall time of every phase and --json records them, on the
// main job's path (a uint8 .npy read straight into the kernels' memory) and on the others (a
// .vox, a uint16 .npy, another metric), with --repeat and --warmup too. No timing asserted.
TEST_F(CliTest, GenerateStatsPrintsPhases) {
    const World w = test_world();
    const fs::path u8 = dir_ / "world_u8.npy";
    write_npy(u8, NpyType::u8, w.dims(), w.voxels());
    const fs::path u16 = dir_ / "world_u16.npy";
    write_npy(u16, NpyType::u16, w.dims(), widen(w.voxels(), 2));
    struct Case {
        fs::path input;
        std::vector<std::string> extra;
        bool in_place;
    };
    const std::vector<Case> cases = {
        {u8, {}, true},
        {u8, {"--format", "packed32", "--repeat", "3", "--warmup", "1"}, true},
        {kVox, {}, false},
        {u16, {}, false},
        {u8, {"--metric", "chebyshev"}, true},  // the sweeps' CPU layout
        {u8, {"--metric", "euclidean"}, false},
        {u8, {"--algorithm", "fim"}, false},
    };
    const std::vector<std::string> phases = {"read",     "setup", "upload", "kernels",
                                             "download", "write", "wall"};
    for (const Case& c : cases) {
        std::string trace = c.input.filename().string();
        for (const auto& e : c.extra) {
            trace.append(" ").append(e);
        }
        SCOPED_TRACE(trace);
        const fs::path out = dir_ / "field.npy";
        const fs::path js = dir_ / "run.json";
        std::vector<std::string> args = {"generate",   c.input.string(), "-o",
                                         out.string(), "--device",       "cpu",
                                         "--stats",    "--json",         js.string()};
        args.insert(args.end(), c.extra.begin(), c.extra.end());
        const RunResult r = run(args);
        ASSERT_EQ(r.code, 0) << describe(r);
        std::string line;
        for (const std::string& l : split_lines(r.out)) {
            if (l.rfind("phases:", 0) == 0) {
                EXPECT_TRUE(line.empty()) << "two phases lines\n" << r.out;
                line = l;
            }
        }
        ASSERT_FALSE(line.empty()) << r.out;
        std::size_t at = 0;
        for (const std::string& p : phases) {
            const std::size_t found = line.find(" " + p + " ", at);
            ASSERT_NE(found, std::string::npos) << "no '" << p << "' in order in: " << line;
            at = found + p.size();
            // Each phase is followed by its milliseconds.
            const std::string rest = line.substr(found + p.size() + 2);
            EXPECT_TRUE(!rest.empty() && std::isdigit(static_cast<unsigned char>(rest[0]))) << line;
        }
        EXPECT_NE(line.find("ms (program start to output written)"), std::string::npos) << line;
        EXPECT_NE(r.out.find("max error 0"), std::string::npos) << r.out;
        json j;
        ASSERT_NO_THROW(j = json::parse(read_text(js))) << read_text(js);
        ASSERT_TRUE(j.contains("phases_ms")) << j.dump();
        for (const std::string& p : phases) {
            ASSERT_TRUE(j["phases_ms"].contains(p)) << p << ": " << j.dump();
            EXPECT_TRUE(j["phases_ms"][p].is_number());
            EXPECT_GE(j["phases_ms"][p].get<double>(), 0.0);
        }
        EXPECT_EQ(j.value("world_read_in_place", !c.in_place), c.in_place);
        EXPECT_TRUE(j["end_to_end_ms"].is_number());
        EXPECT_EQ(j.value("max_error", 999u), 0u);
        EXPECT_TRUE(fs::is_regular_file(out));
    }
}

// With --indices, --stats checks every index against the CPU reference: a nearest solid, and
// for unit-spacing L1 and L2 SciPy's choice among equally near ones. One line, three JSON keys.
TEST_F(CliTest, GenerateStatsChecksIndices) {
    const World w = test_world();
    const fs::path in = dir_ / "world.npy";
    write_npy(in, NpyType::u8, w.dims(), w.voxels());
    const std::size_t n = w.dims().count();
    struct Case {
        std::vector<std::string> extra;
        bool ties;
    };
    const std::vector<Case> cases = {
        {{"--metric", "euclidean"}, true},
        {{"--metric", "manhattan"}, true},
        {{"--metric", "chebyshev"}, false},
        {{"--metric", "euclidean", "--spacing", "1.5,0.75,2", "--format", "f64"}, false},
    };
    for (const Case& c : cases) {
        SCOPED_TRACE(c.extra[1] + (c.extra.size() > 2 ? " " + c.extra[3] : ""));
        const fs::path js = dir_ / "run.json";
        std::vector<std::string> args = {"generate",  in.string(),
                                         "-o",        (dir_ / "field.npy").string(),
                                         "--indices", (dir_ / "indices.npy").string(),
                                         "--device",  "cpu",
                                         "--stats",   "--json",
                                         js.string()};
        args.insert(args.end(), c.extra.begin(), c.extra.end());
        const RunResult r = run(args);
        ASSERT_EQ(r.code, 0) << describe(r);
        const std::string want =
            "stats:   indices: 0 of " + std::to_string(n) + " name no nearest solid" +
            (c.ties ? ", 0 a nearest solid other than SciPy's" : " (ties not compared: ");
        EXPECT_NE(r.out.find(want), std::string::npos) << r.out;
        const json j = json::parse(read_text(js));
        EXPECT_EQ(j.value("indices_checked", 0u), n);
        EXPECT_EQ(j.value("indices_not_nearest", 999u), 0u);
        ASSERT_TRUE(j.contains("indices_not_scipy"));
        if (c.ties) {
            EXPECT_EQ(j["indices_not_scipy"], 0u);
        } else {
            EXPECT_TRUE(j["indices_not_scipy"].is_null());
        }
    }
}

TEST_F(CliTest, GenerateOverwritesExistingOutput) {
    const World w = test_world();
    const fs::path in = dir_ / "world.npy";
    write_npy(in, NpyType::u8, w.dims(), w.voxels());
    const fs::path out = dir_ / "field.npy";
    write_file(out, "old contents");
    const RunResult r =
        run({"generate", in.string(), "-o", out.string(), "--format", "u8", "--device", "cpu"});
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_EQ(read_npy(out).data, encode_field(reference_manhattan(w), w, Palette(), Format::u8));
}

// ---------------------------------------------------------------------------------------
// generate: bad input. Each case: exit 2, one stderr line "voxfield: ..." naming the problem,
// no output file, nothing else left in the folder.

struct BadCase {
    std::string name;
    // Creates the input in `dir` and returns the generate arguments; `out` is the -o path.
    std::function<std::vector<std::string>(const fs::path& dir, const fs::path& out)> setup;
    std::vector<std::string> keywords;  // each must appear in the stderr line
};

void PrintTo(const BadCase& c, std::ostream* os) {
    *os << c.name;
}

std::vector<std::string> gen(const fs::path& in, const fs::path& out,
                             std::vector<std::string> extra = {}) {
    std::vector<std::string> a = {"generate", in.string(), "-o", out.string()};
    if (std::find(extra.begin(), extra.end(), "--device") == extra.end()) {
        a.insert(a.end(), {"--device", "cpu"});
    }
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
}

fs::path good_npy(const fs::path& dir) {
    const fs::path p = dir / "good.npy";
    const World w = scene_floor_spheres(Dims{8, 8, 8}, 1, 2);
    write_npy(p, NpyType::u8, w.dims(), w.voxels());
    return p;
}

// A floor-and-spheres world of `dims` written as world_XxYxZ.npy.
fs::path npy_world(const fs::path& dir, Dims dims) {
    const fs::path p = dir / ("world_" + dims.to_string() + ".npy");
    const World w = scene_floor_spheres(dims, 5, 3);
    write_npy(p, NpyType::u8, w.dims(), w.voxels());
    return p;
}

std::string vox_bytes() {
    const auto b = read_bytes(kVox);
    return std::string(b.begin(), b.end());
}

std::vector<BadCase> bad_cases() {
    std::vector<BadCase> c;
    c.push_back({"MissingInput",
                 [](const fs::path& d, const fs::path& o) { return gen(d / "nope.vox", o); },
                 {"nope.vox"}});
    c.push_back({"InputIsDirectory",
                 [](const fs::path& d, const fs::path& o) {
                     fs::create_directory(d / "adir.npy");
                     return gen(d / "adir.npy", o);
                 },
                 {"adir.npy"}});
    c.push_back({"EmptyVox",
                 [](const fs::path& d, const fs::path& o) {
                     write_file(d / "empty.vox", "");
                     return gen(d / "empty.vox", o);
                 },
                 {"empty.vox"}});
    c.push_back({"TruncatedVox",
                 [](const fs::path& d, const fs::path& o) {
                     write_file(d / "trunc.vox", vox_bytes().substr(0, 100));
                     return gen(d / "trunc.vox", o);
                 },
                 {"trunc.vox"}});
    c.push_back({"CorruptVoxMagic",
                 [](const fs::path& d, const fs::path& o) {
                     std::string b = vox_bytes();
                     b.replace(0, 4, "XOV ");
                     write_file(d / "corrupt.vox", b);
                     return gen(d / "corrupt.vox", o);
                 },
                 {"corrupt.vox"}});
    c.push_back({"NpyFloat32",
                 [](const fs::path& d, const fs::path& o) {
                     write_file(d / "float.npy",
                                raw_npy("<f4", "(2, 2, 2)", std::string(32, '\0')));
                     return gen(d / "float.npy", o);
                 },
                 {"float.npy", "dtype"}});
    c.push_back({"Npy2D",
                 [](const fs::path& d, const fs::path& o) {
                     write_file(d / "flat.npy", raw_npy("|u1", "(4, 4)", std::string(16, '\1')));
                     return gen(d / "flat.npy", o);
                 },
                 {"flat.npy", "shape"}});
    c.push_back({"NpyZeroAxis",
                 [](const fs::path& d, const fs::path& o) {
                     write_file(d / "zero.npy", raw_npy("|u1", "(0, 4, 4)", ""));
                     return gen(d / "zero.npy", o);
                 },
                 {"zero.npy", "empty axis"}});
    c.push_back({"NpyUint8Truncated",
                 [](const fs::path& d, const fs::path& o) {
                     write_file(d / "short.npy",
                                raw_npy("|u1", "(4, 4, 4)", std::string(63, '\1')));
                     return gen(d / "short.npy", o);
                 },
                 {"short.npy", "truncated"}});
    c.push_back({"NpyUint16Over255",
                 [](const fs::path& d, const fs::path& o) {
                     std::string data(2 * 2 * 3 * 2, '\0');
                     data[14] = static_cast<char>(300 & 0xFF);  // element 7 = 300
                     data[15] = static_cast<char>(300 >> 8);
                     write_file(d / "big.npy", raw_npy("<u2", "(2, 2, 3)", data));
                     // A label volume is solid wherever nonzero; only packed32 (and rendering)
                     // reads the value as a palette index, so only it refuses 300.
                     return gen(d / "big.npy", o, {"--format", "packed32"});
                 },
                 {"big.npy", "300"}});
    c.push_back({"UnknownExtension",
                 [](const fs::path& d, const fs::path& o) {
                     write_file(d / "world.txt", "hello");
                     return gen(d / "world.txt", o);
                 },
                 {"world.txt", ".txt"}});
    c.push_back({"UnknownAlgorithm",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(good_npy(d), o, {"--algorithm", "bogo"});
                 },
                 {"--algorithm", "bogo"}});
    c.push_back({"UnknownFormat",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(good_npy(d), o, {"--format", "u12"});
                 },
                 {"--format", "u12"}});
    c.push_back({"UnknownMetric",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(good_npy(d), o, {"--metric", "taxi"});
                 },
                 {"--metric", "taxi"}});
    c.push_back({"DeviceIndexOutOfRange",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(good_npy(d), o, {"--device", "99"});
                 },
                 {"99", "the indices are 0.."}});
    c.push_back({"DeviceBogus",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(good_npy(d), o, {"--device", "bogus"});
                 },
                 {"bogus"}});
    c.push_back({"OutputFolderMissing",
                 [](const fs::path& d, const fs::path&) {
                     return gen(good_npy(d), d / "nowhere" / "out.npy");
                 },
                 {"nowhere"}});
    c.push_back({"JsonFolderMissing",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(good_npy(d), o, {"--json", (d / "nojson" / "r.json").string()});
                 },
                 {"nojson"}});
    // The dissertation's algorithms (DESIGN §4): --chunk, --focus and --jfa-extra are checked
    // against the algorithm and the world before any work starts.
    c.push_back(
        {"ChunkNotPowerOfTwo",
         [](const fs::path& d, const fs::path& o) {
             return gen(npy_world(d, Dims{32, 32, 32}), o, {"--algorithm", "fim", "--chunk", "12"});
         },
         {"12", "power of two"}});
    c.push_back(
        {"ChunkZero",
         [](const fs::path& d, const fs::path& o) {
             return gen(npy_world(d, Dims{16, 16, 16}), o, {"--algorithm", "fim", "--chunk", "0"});
         },
         {"--chunk"}});
    c.push_back({"ChunkLargerThanWorldAlongX",
                 [](const fs::path&, const fs::path& o) {
                     return gen(kVox, o, {"--algorithm", "fim", "--chunk", "16"});
                 },
                 {"16", "8x12x7", "along x"}});
    c.push_back({"ChunkLargerThanWorldAlongZ",
                 [](const fs::path&, const fs::path& o) {
                     return gen(kVox, o, {"--algorithm", "jfa", "--chunk", "8"});
                 },
                 {"8", "8x12x7", "along z"}});
    c.push_back({"DefaultChunkLargerThanWorld",
                 [](const fs::path&, const fs::path& o) {
                     return gen(kVox, o, {"--algorithm", "lod"});  // lod defaults to 16^3 chunks
                 },
                 {"16", "8x12x7"}});
    c.push_back({"FocusOutsideChunkGrid",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(npy_world(d, Dims{16, 16, 16}), o,
                                {"--algorithm", "lod", "--chunk", "8", "--focus", "1,1,2,0"});
                 },
                 {"focus", "1,1,2", "2x2x2"}});
    c.push_back({"FocusNegativeCentre",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(
                         npy_world(d, Dims{16, 16, 16}), o,
                         {"--algorithm", "monolithic", "--chunk", "8", "--focus", "-1,0,0,1"});
                 },
                 {"focus", "-1,0,0", "2x2x2"}});
    c.push_back({"FocusThreeNumbers",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(npy_world(d, Dims{16, 16, 16}), o,
                                {"--algorithm", "lod", "--chunk", "8", "--focus", "1,2,3"});
                 },
                 {"--focus", "1,2,3"}});
    c.push_back({"FocusNotNumbers",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(npy_world(d, Dims{16, 16, 16}), o,
                                {"--algorithm", "lod", "--chunk", "8", "--focus", "a,b,c,d"});
                 },
                 {"--focus", "a,b,c,d"}});
    c.push_back({"FocusEmptyField",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(npy_world(d, Dims{16, 16, 16}), o,
                                {"--algorithm", "lod", "--chunk", "8", "--focus", "1,,1,1"});
                 },
                 {"--focus", "1,,1,1"}});
    c.push_back({"FocusNegativeSize",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(npy_world(d, Dims{16, 16, 16}), o,
                                {"--algorithm", "lod", "--chunk", "8", "--focus", "0,0,0,-1"});
                 },
                 {"focus", "-1", "negative"}});
    c.push_back({"FocusWithFim",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(npy_world(d, Dims{16, 16, 16}), o,
                                {"--algorithm", "fim", "--chunk", "8", "--focus", "0,0,0,1"});
                 },
                 {"--focus", "fim"}});
    c.push_back({"FocusWithExact",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(npy_world(d, Dims{16, 16, 16}), o, {"--focus", "0,0,0,1"});
                 },
                 {"--focus", "exact"}});
    c.push_back({"JfaExtraThree",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(good_npy(d), o, {"--algorithm", "jfa", "--jfa-extra", "3"});
                 },
                 {"--jfa-extra", "3"}});
    c.push_back({"JfaExtraWithFim",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(good_npy(d), o, {"--algorithm", "fim", "--jfa-extra", "1"});
                 },
                 {"--jfa-extra", "fim"}});
    c.push_back({"JfaExtraWithBruteChunked",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(
                         good_npy(d), o,
                         {"--algorithm", "brute-chunked", "--chunk", "4", "--jfa-extra", "2"});
                 },
                 {"--jfa-extra", "brute-chunked"}});
    c.push_back({"ExactWithChunk",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(good_npy(d), o, {"--algorithm", "exact", "--chunk", "4"});
                 },
                 {"--chunk", "exact"}});
    c.push_back({"UnknownAlgorithmUnderscore",
                 [](const fs::path& d, const fs::path& o) {
                     return gen(good_npy(d), o, {"--algorithm", "fim_host"});
                 },
                 {"--algorithm", "fim_host"}});
    // Brute force over 160^3 would take far longer than anyone waits: refused up front with a
    // pointer to `exact`, no output and no JSON.
    c.push_back({"BruteRefusedOnLargeWorld",
                 [](const fs::path& d, const fs::path& o) {
                     World w(Dims{160, 160, 160});
                     w.set(80, 0, 80, 1);
                     write_npy(d / "large.npy", NpyType::u8, w.dims(), w.voxels());
                     return gen(d / "large.npy", o,
                                {"--algorithm", "brute", "--json", (d / "brute.json").string()});
                 },
                 {"brute", "exact"}});
    c.push_back(
        {"MissingOutputOption",
         [](const fs::path& d, const fs::path&) {
             return std::vector<std::string>{"generate", good_npy(d).string(), "--device", "cpu"};
         },
         {"output"}});
    return c;
}

class BadInputTest : public CliTest, public ::testing::WithParamInterface<BadCase> {};

TEST_P(BadInputTest, ExitsTwoWithOneLineAndNoOutput) {
    const BadCase& c = GetParam();
    const fs::path out = dir_ / "out.npy";
    const std::vector<std::string> args = c.setup(dir_, out);
    const std::set<std::string> before = list_dir(dir_);
    const RunResult r = run(args);
    EXPECT_EQ(r.code, 2) << describe(r);
    const std::vector<std::string> lines = split_lines(r.err);
    ASSERT_FALSE(lines.empty()) << describe(r);
    EXPECT_EQ(lines[0].rfind("voxfield: ", 0), 0u) << describe(r);
    EXPECT_EQ(lines.size(), 1u) << "stderr should be exactly one line\n" << describe(r);
    EXPECT_EQ(r.err.back(), '\n');
    for (const auto& k : c.keywords) {
        EXPECT_NE(lines[0].find(k), std::string::npos) << "stderr does not mention '" << k << "'\n"
                                                       << describe(r);
    }
    EXPECT_FALSE(fs::exists(out)) << "output file left behind";
    EXPECT_FALSE(fs::exists(dir_ / "nowhere"));
    EXPECT_EQ(list_dir(dir_), before) << "stray files left in the folder";
}

INSTANTIATE_TEST_SUITE_P(Generate, BadInputTest, ::testing::ValuesIn(bad_cases()),
                         [](const ::testing::TestParamInfo<BadCase>& param_info) {
                             return param_info.param.name;
                         });

// ---------------------------------------------------------------------------------------
// generate: the dissertation's algorithms (DESIGN §3-§4). Without --chunk they compute the
// global field, with --chunk C the chunk-local one (everything outside a chunk solid);
// brute-chunked, lod and monolithic are always chunk-local (16^3 by default).

const std::vector<std::string> kExactAlgorithms = {
    "brute", "brute-chunked", "fim", "fim-host", "jfa-fim", "lod", "monolithic"};

bool always_chunked(const std::string& algorithm) {
    return algorithm == "brute-chunked" || algorithm == "lod" || algorithm == "monolithic";
}

bool focused(const std::string& algorithm) {
    return algorithm == "lod" || algorithm == "monolithic";
}

// The reference of the semantics an algorithm run claims: global (chunk 0) or chunk-local.
std::vector<std::uint32_t> reference_for(const World& world, std::uint32_t chunk) {
    return chunk == 0 ? reference_manhattan(world) : reference_manhattan_chunked(world, chunk);
}

// "X,Y,Z,SIZE" of a focus that covers every chunk of the grid.
std::string focus_covering_all(Dims world, std::uint32_t chunk) {
    const Dims n = ChunkGrid(world, chunk).chunks();
    return "0,0,0," + std::to_string(std::max({n.x, n.y, n.z}));
}

// Checks an output file against the encoded reference, reporting the first difference.
void expect_field_equals(const fs::path& out, const std::vector<std::uint32_t>& distances,
                         const World& world, const Palette& palette, const std::string& format) {
    ASSERT_TRUE(fs::is_regular_file(out)) << out;
    const NpyArray a = read_npy(out);
    const Format f = parse_format(format);
    EXPECT_EQ(a.type, expected_type(format));
    EXPECT_EQ(a.dims, world.dims()) << a.dims.to_string() << " vs " << world.dims().to_string();
    const std::vector<std::uint8_t> want = encode_field(distances, world, palette, f);
    ASSERT_EQ(a.data.size(), want.size());
    const long long diff = first_difference(a.data, want, element_size(f));
    if (diff >= 0) {
        const auto i = static_cast<std::size_t>(diff);
        const Dims d = world.dims();
        ADD_FAILURE() << "first differing voxel (" << i % d.x << "," << (i / d.x) % d.y << ","
                      << i / (std::size_t{d.x} * d.y) << "): got distance "
                      << decode_distance(a.data, f, i) << ", want " << decode_distance(want, f, i);
    }
}

// An input world and the chunk sizes that fit it.
struct Input {
    fs::path path;
    VoxModel model;
    std::vector<std::uint32_t> chunks;
};

// "random_npy": a sparse random 20x17x18 .npy world (16^3 chunks fit, clipped along every
// axis); "chr_army1" (8x12x7), "veh_car1" (15x11x32): shipped .vox models.
Input load_input(const std::string& name, const fs::path& dir) {
    if (name == "random_npy") {
        World w = scene_random(Dims{20, 17, 18}, 0.04, 4242);
        w.set(19, 16, 17, 255);
        w.set(0, 0, 0, 9);
        const fs::path p = dir / "random.npy";
        write_npy(p, NpyType::u8, w.dims(), w.voxels());
        return {p, VoxModel{w, Palette()}, {4, 8}};
    }
    const fs::path p = fs::path(VOXFIELD_DATA_DIR) / "vox" / (name + ".vox");
    return {
        p, read_vox(p),
        name == "chr_army1" ? std::vector<std::uint32_t>{2, 4} : std::vector<std::uint32_t>{4, 8}};
}

struct AlgorithmCase {
    std::string world, algorithm;
};

void PrintTo(const AlgorithmCase& c, std::ostream* os) {
    *os << c.world << " " << c.algorithm;
}

std::vector<AlgorithmCase> algorithm_cases() {
    std::vector<AlgorithmCase> cases;
    for (const std::string world : {"random_npy", "chr_army1", "veh_car1"}) {
        for (const auto& algorithm : kExactAlgorithms) {
            cases.push_back({world, algorithm});
        }
    }
    return cases;
}

class ExactAlgorithmTest : public CliTest, public ::testing::WithParamInterface<AlgorithmCase> {};

// Every exact algorithm (lod and monolithic with a focus covering all chunks) gives exactly
// the CPU reference of its semantics, in every format: global where the algorithm allows
// it, chunk-local for each chunk size that fits, and the default 16^3 chunks where they fit.
TEST_P(ExactAlgorithmTest, MatchesReferenceOfItsSemantics) {
    const AlgorithmCase& c = GetParam();
    const Input in = load_input(c.world, dir_);
    const World& world = in.model.world;
    ASSERT_GT(world.solid_count(), 0u);

    struct Mode {
        std::uint32_t chunk;  // semantics: 0 = global
        bool pass_chunk;      // give --chunk (else the algorithm's default)
    };
    std::vector<Mode> modes;
    if (!always_chunked(c.algorithm)) {
        modes.push_back({0, false});
    }
    for (const std::uint32_t chunk : in.chunks) {
        modes.push_back({chunk, true});
    }
    const Dims d = world.dims();
    if (always_chunked(c.algorithm) && d.x >= 16 && d.y >= 16 && d.z >= 16) {
        modes.push_back({16, false});
    }

    bool extra_done = false;
    for (const Mode& mode : modes) {
        SCOPED_TRACE(mode.chunk == 0 ? std::string("global")
                                     : "chunk " + std::to_string(mode.chunk) +
                                           (mode.pass_chunk ? "" : " (default)"));
        const std::vector<std::uint32_t> distances = reference_for(world, mode.chunk);
        std::vector<std::string> base = {"--algorithm", c.algorithm};
        if (mode.pass_chunk) {
            base.insert(base.end(), {"--chunk", std::to_string(mode.chunk)});
        }
        if (focused(c.algorithm)) {
            base.insert(base.end(), {"--focus", focus_covering_all(d, mode.chunk)});
        }
        for (const std::string& format : kFormats) {
            SCOPED_TRACE("format " + format);
            const fs::path out = dir_ / ("field_" + format + ".npy");
            const fs::path js = dir_ / "run.json";
            std::vector<std::string> extra = base;
            extra.insert(extra.end(), {"--format", format, "--json", js.string()});
            const RunResult r = run(gen(in.path, out, extra));
            ASSERT_EQ(r.code, 0) << describe(r);
            EXPECT_TRUE(r.err.empty()) << describe(r);
            expect_field_equals(out, distances, world, in.model.palette, format);
            json j;
            ASSERT_NO_THROW(j = json::parse(read_text(js))) << read_text(js);
            EXPECT_EQ(j.value("algorithm", ""), c.algorithm);
            EXPECT_EQ(j["chunk"], mode.chunk == 0 ? json() : json(mode.chunk)) << j["chunk"];
            fs::remove(out);
            fs::remove(js);
        }
        // JFA+2 in front of FIM changes the speed, never the result.
        if ((c.algorithm == "jfa-fim" || focused(c.algorithm)) && !extra_done) {
            extra_done = true;
            SCOPED_TRACE("--jfa-extra 2");
            const fs::path out = dir_ / "field_extra.npy";
            std::vector<std::string> extra = base;
            extra.insert(extra.end(), {"--format", "u16", "--jfa-extra", "2"});
            const RunResult r = run(gen(in.path, out, extra));
            ASSERT_EQ(r.code, 0) << describe(r);
            expect_field_equals(out, distances, world, in.model.palette, "u16");
            fs::remove(out);
        }
    }
    // Nothing left behind but the input.
    std::set<std::string> expected;
    if (in.path.parent_path() == dir_) {
        expected.insert(in.path.filename().string());
    }
    EXPECT_EQ(list_dir(dir_), expected);
}

INSTANTIATE_TEST_SUITE_P(Generate, ExactAlgorithmTest, ::testing::ValuesIn(algorithm_cases()),
                         [](const ::testing::TestParamInfo<AlgorithmCase>& param_info) {
                             std::string name =
                                 param_info.param.world + "_" + param_info.param.algorithm;
                             std::replace(name.begin(), name.end(), '-', '_');
                             return name;
                         });

// Accuracy statistics computed here from the output file and the reference, independently
// of voxfield's own accuracy code.
struct FieldStats {
    std::uint32_t max_error = 0;
    double mean_error = 0, over_fraction = 0, under_fraction = 0;
    std::size_t below = 0;  // voxels under the reference
    long long first_below = -1;
};

FieldStats field_stats(const NpyArray& a, Format f, const std::vector<std::uint32_t>& exact) {
    FieldStats s;
    const std::uint32_t cap = max_distance(f);
    double sum = 0;
    std::size_t over = 0;
    for (std::size_t i = 0; i < exact.size(); ++i) {
        const std::uint32_t got = decode_distance(a.data, f, i);
        const std::uint32_t want = std::min(exact[i], cap);
        const std::uint32_t err = got > want ? got - want : want - got;
        s.max_error = std::max(s.max_error, err);
        sum += err;
        if (got > want) {
            ++over;
        } else if (got < want) {
            if (s.below == 0) {
                s.first_below = static_cast<long long>(i);
            }
            ++s.below;
        }
    }
    const auto n = static_cast<double>(exact.size());
    s.mean_error = sum / n;
    s.over_fraction = static_cast<double>(over) / n;
    s.under_fraction = static_cast<double>(s.below) / n;
    return s;
}

// A non-cubic world whose 4^3 chunk grid is 7x5x10 (centre chunk (3,2,5)).
World stats_world() {
    World w = scene_floor_spheres(Dims{28, 17, 40}, 77, 6);
    w.set(27, 16, 39, 200);
    w.set(3, 12, 30, 5);
    w.set(20, 9, 2, 17);
    return w;
}

class StatsTest : public CliTest {
  protected:
    void SetUp() override {
        CliTest::SetUp();
        input_ = dir_ / "stats_world.npy";
        write_npy(input_, NpyType::u8, world_.dims(), world_.voxels());
    }

    // Runs generate --stats --json with `extra`; checks that the JSON's accuracy is the one
    // computed here against the reference of `chunk` (0: global) and that the field never
    // under-estimates. Leaves the JSON in j_ and the output in field_.
    void run_stats(const std::vector<std::string>& extra, const std::string& format,
                   std::uint32_t chunk) {
        const fs::path out = dir_ / "field.npy";
        const fs::path js = dir_ / "run.json";
        std::vector<std::string> args = extra;
        args.insert(args.end(), {"--format", format, "--stats", "--json", js.string()});
        const RunResult r = run(gen(input_, out, args));
        ASSERT_EQ(r.code, 0) << describe(r);
        EXPECT_NE(r.out.find("under-estimated 0.000%"), std::string::npos) << r.out;
        ASSERT_NO_THROW(j_ = json::parse(read_text(js))) << read_text(js);
        field_ = read_npy(out);
        exact_ = reference_for(world_, chunk);
        const Format f = parse_format(format);
        ASSERT_EQ(field_.data.size(), world_.size() * element_size(f));
        const FieldStats s = field_stats(field_, f, exact_);

        for (const char* key : {"max_error", "mean_error", "over_fraction", "under_fraction",
                                "iterations", "algorithm", "chunk"}) {
            ASSERT_TRUE(j_.contains(key)) << key << "\n" << j_.dump(2);
        }
        EXPECT_EQ(j_["max_error"].get<std::uint32_t>(), s.max_error);
        EXPECT_NEAR(j_["mean_error"].get<double>(), s.mean_error, 1e-9);
        EXPECT_NEAR(j_["over_fraction"].get<double>(), s.over_fraction, 1e-12);
        EXPECT_NEAR(j_["under_fraction"].get<double>(), s.under_fraction, 1e-12);
        EXPECT_EQ(j_["under_fraction"].get<double>(), 0.0);
        EXPECT_EQ(s.below, 0u) << "voxel " << s.first_below << " is below the reference: got "
                               << decode_distance(
                                      field_.data, f,
                                      static_cast<std::size_t>(std::max(0LL, s.first_below)))
                               << ", want "
                               << exact_[static_cast<std::size_t>(std::max(0LL, s.first_below))];
        EXPECT_EQ(j_["chunk"], chunk == 0 ? json() : json(chunk)) << j_["chunk"];
        EXPECT_TRUE(j_["iterations"].is_number_unsigned()) << j_["iterations"];
    }

    // Every voxel of the focus chunks equals the reference (FIM ran there).
    void expect_exact_in_focus(std::uint32_t chunk, const Focus& focus, Format f) {
        const ChunkGrid grid(world_.dims(), chunk);
        const Box chunks = focus_chunks(grid, focus);
        const Dims d = world_.dims();
        const std::uint32_t cap = max_distance(f);
        std::size_t checked = 0;
        for (std::int64_t cz = chunks.min.z; cz < chunks.max.z; ++cz) {
            for (std::int64_t cy = chunks.min.y; cy < chunks.max.y; ++cy) {
                for (std::int64_t cx = chunks.min.x; cx < chunks.max.x; ++cx) {
                    const Box b = grid.voxels_of({cx, cy, cz});
                    for (auto z = b.min.z; z < b.max.z; ++z) {
                        for (auto y = b.min.y; y < b.max.y; ++y) {
                            for (auto x = b.min.x; x < b.max.x; ++x) {
                                const std::size_t i = d.index(static_cast<std::uint32_t>(x),
                                                              static_cast<std::uint32_t>(y),
                                                              static_cast<std::uint32_t>(z));
                                ASSERT_EQ(decode_distance(field_.data, f, i),
                                          std::min(exact_[i], cap))
                                    << "focus voxel (" << x << "," << y << "," << z << ")";
                                ++checked;
                            }
                        }
                    }
                }
            }
        }
        EXPECT_GT(checked, 0u);
    }

    std::uint32_t max_reference_distance() const {
        std::uint32_t m = 0;
        for (const std::uint32_t v : exact_) {
            if (v != kInfinite) {
                m = std::max(m, v);
            }
        }
        return m;
    }

    World world_ = stats_world();
    fs::path input_;
    json j_;
    NpyArray field_;
    std::vector<std::uint32_t> exact_;
};

TEST_F(StatsTest, JfaGlobal) {
    ASSERT_NO_FATAL_FAILURE(run_stats({"--algorithm", "jfa"}, "u16", 0));
    EXPECT_EQ(j_.value("algorithm", ""), "jfa");
    EXPECT_EQ(j_.value("iterations", 99u), 0u) << "jfa runs no FIM pass";
    EXPECT_FALSE(j_.contains("focus")) << j_.dump(2);
}

TEST_F(StatsTest, JfaChunkLocalWithExtraPass) {
    ASSERT_NO_FATAL_FAILURE(
        run_stats({"--algorithm", "jfa", "--chunk", "8", "--jfa-extra", "1"}, "u8", 8));
    EXPECT_EQ(j_.value("algorithm", ""), "jfa");
    EXPECT_EQ(j_.value("jfa_extra", 99u), 1u);
}

TEST_F(StatsTest, JfaHostGlobal) {
    ASSERT_NO_FATAL_FAILURE(run_stats({"--algorithm", "jfa-host"}, "packed32", 0));
    EXPECT_EQ(j_.value("algorithm", ""), "jfa-host");
}

TEST_F(StatsTest, JfaHostChunkLocal) {
    ASSERT_NO_FATAL_FAILURE(run_stats({"--algorithm", "jfa-host", "--chunk", "4"}, "u32", 4));
    EXPECT_EQ(j_.value("algorithm", ""), "jfa-host");
}

TEST_F(StatsTest, LodPartialFocus) {
    ASSERT_NO_FATAL_FAILURE(
        run_stats({"--algorithm", "lod", "--chunk", "4", "--focus", "1,3,8,1"}, "u16", 4));
    EXPECT_EQ(j_.value("algorithm", ""), "lod");
    EXPECT_EQ(j_["focus"], json::array({1, 3, 8, 1})) << j_.dump(2);
    ASSERT_NO_FATAL_FAILURE(expect_exact_in_focus(4, Focus{{1, 3, 8}, 1}, Format::u16));
}

TEST_F(StatsTest, LodDefaultFocusIsCentreChunk) {
    ASSERT_NO_FATAL_FAILURE(run_stats({"--algorithm", "lod", "--chunk", "4"}, "packed32", 4));
    // Chunk grid 7x5x10: centre chunk (3,2,5), size 1.
    EXPECT_EQ(j_["focus"], json::array({3, 2, 5, 1})) << j_.dump(2);
    ASSERT_NO_FATAL_FAILURE(expect_exact_in_focus(4, Focus{{3, 2, 5}, 1}, Format::packed32));
}

TEST_F(StatsTest, LodDefaultChunkIs16) {
    ASSERT_NO_FATAL_FAILURE(run_stats({"--algorithm", "lod", "--focus", "0,0,0,0"}, "u8", 16));
    EXPECT_EQ(j_["focus"], json::array({0, 0, 0, 0})) << j_.dump(2);
    ASSERT_NO_FATAL_FAILURE(expect_exact_in_focus(16, Focus{{0, 0, 0}, 0}, Format::u8));
}

TEST_F(StatsTest, MonolithicRecordsFocus) {
    // Chunk grid 4x3x5: default focus (2,1,2), size 1.
    ASSERT_NO_FATAL_FAILURE(run_stats({"--algorithm", "monolithic", "--chunk", "8"}, "u16", 8));
    EXPECT_EQ(j_.value("algorithm", ""), "monolithic");
    EXPECT_EQ(j_["focus"], json::array({2, 1, 2, 1})) << j_.dump(2);
    ASSERT_NO_FATAL_FAILURE(expect_exact_in_focus(8, Focus{{2, 1, 2}, 1}, Format::u16));

    ASSERT_NO_FATAL_FAILURE(
        run_stats({"--algorithm", "monolithic", "--chunk", "8", "--focus", "3,0,4,0"}, "u8", 8));
    EXPECT_EQ(j_["focus"], json::array({3, 0, 4, 0})) << j_.dump(2);
    ASSERT_NO_FATAL_FAILURE(expect_exact_in_focus(8, Focus{{3, 0, 4}, 0}, Format::u8));
}

TEST_F(StatsTest, FimGlobalCountsIterations) {
    ASSERT_NO_FATAL_FAILURE(run_stats({"--algorithm", "fim"}, "u16", 0));
    EXPECT_EQ(j_.value("algorithm", ""), "fim");
    EXPECT_EQ(j_.value("max_error", 99u), 0u);
    EXPECT_FALSE(j_.contains("focus")) << j_.dump(2);
    const std::uint32_t maxd = max_reference_distance();
    ASSERT_GT(maxd, 1u);
    const auto iterations = j_.value("iterations", 0u);
    EXPECT_GE(iterations, 1u);
    // Each pass settles at least one more distance level.
    EXPECT_LE(iterations, maxd);
}

TEST_F(StatsTest, FimChunkLocalCountsIterations) {
    for (const std::string algorithm : {"fim", "fim-host"}) {
        SCOPED_TRACE(algorithm);
        ASSERT_NO_FATAL_FAILURE(run_stats({"--algorithm", algorithm, "--chunk", "8"}, "u32", 8));
        EXPECT_EQ(j_.value("algorithm", ""), algorithm);
        EXPECT_EQ(j_.value("max_error", 99u), 0u);
        const auto iterations = j_.value("iterations", 0u);
        EXPECT_GE(iterations, 1u);
        EXPECT_LE(iterations, max_reference_distance());
    }
}

// ---------------------------------------------------------------------------------------
// devices, help, bench

TEST_F(CliTest, DevicesListsAtLeastOneDevice) {
    const RunResult r = run({"devices"});
    ASSERT_EQ(r.code, 0) << describe(r);
    EXPECT_FALSE(r.out.empty());
    EXPECT_NE(r.out.find("0: "), std::string::npos) << r.out;
}

TEST_F(CliTest, DevicesJsonParses) {
    const RunResult r = run({"devices", "--json"});
    ASSERT_EQ(r.code, 0) << describe(r);
    ASSERT_FALSE(r.out.empty());
    EXPECT_EQ(r.out.front(), '[');
    json j;
    ASSERT_NO_THROW(j = json::parse(r.out)) << r.out;
    ASSERT_TRUE(j.is_array());
    ASSERT_FALSE(j.empty());
    bool any_cpu = false;
    for (const auto& d : j) {
        EXPECT_TRUE(d.contains("index"));
        EXPECT_TRUE(d.contains("name"));
        EXPECT_TRUE(d.contains("type"));
        any_cpu = any_cpu || d.value("type", "") == "cpu";
    }
    EXPECT_TRUE(any_cpu) << "tests run with --device cpu; expected a CPU device (PoCL)";
}

TEST_F(CliTest, TopLevelHelp) {
    const RunResult r = run({"--help"});
    ASSERT_EQ(r.code, 0) << describe(r);
    for (const char* word : {"devices", "generate", "bench", "--version"}) {
        EXPECT_NE(r.out.find(word), std::string::npos) << word << "\n" << r.out;
    }
}

TEST_F(CliTest, GenerateHelp) {
    const RunResult r = run({"generate", "--help"});
    ASSERT_EQ(r.code, 0) << describe(r);
    for (const char* word : {"INPUT", "--output", "--algorithm", "--metric", "--device", "--format",
                             "--stats", "--json", "packed32"}) {
        EXPECT_NE(r.out.find(word), std::string::npos) << word << "\n" << r.out;
    }
}

TEST_F(CliTest, BenchHelp) {
    const RunResult r = run({"bench", "--help"});
    ASSERT_EQ(r.code, 0) << describe(r);
    for (const char* word : {"--sizes", "--algorithms", "--device", "--repeat", "--warmup",
                             "--json", "--csv", "--format", "--scene"}) {
        EXPECT_NE(r.out.find(word), std::string::npos) << word << "\n" << r.out;
    }
}

// DESIGN §4: every command that reads a world reads .npy (any integer or bool labels), .vox
// scenes, .vdb and .sdf.json, and its help says so.
TEST_F(CliTest, EveryInputHelpNamesEveryInputKind) {
    for (const char* command : {"generate", "info", "render", "view", "replay", "simulate"}) {
        const RunResult r = run({command, "--help"});
        ASSERT_EQ(r.code, 0) << describe(r);
        for (const char* word : {".vox", ".npy", "any integer or bool", ".vdb", ".sdf.json"}) {
            EXPECT_NE(r.out.find(word), std::string::npos) << command << ": " << word;
        }
    }
    const RunResult g = run({"generate", "--help"});
    for (const char* word : {"--sparse", "--grid", "--max-distance", "--signed", "--indices"}) {
        EXPECT_NE(g.out.find(word), std::string::npos) << word << "\n" << g.out;
    }
    const RunResult b = run({"bench", "--help"});
    for (const char* word : {"--suite", "implicit", "city", "$VOXFIELD_DEVICE"}) {
        EXPECT_NE(b.out.find(word), std::string::npos) << word << "\n" << b.out;
    }
}

TEST_F(CliTest, NoSubcommandIsUsageError) {
    const RunResult r = run({});
    EXPECT_EQ(r.code, 2) << describe(r);
    EXPECT_EQ(r.err.rfind("voxfield: ", 0), 0u) << describe(r);
}

TEST_F(CliTest, BenchWritesJsonAndCsv) {
    const fs::path js = dir_ / "bench.json";
    const fs::path csv = dir_ / "bench.csv";
    const RunResult r = run({"bench", "--sizes", "16,8x4x2", "--repeat", "2", "--warmup", "1",
                             "--json", js.string(), "--csv", csv.string(), "--device", "cpu"});
    ASSERT_EQ(r.code, 0) << describe(r);
    json j;
    ASSERT_NO_THROW(j = json::parse(read_text(js))) << read_text(js);
    EXPECT_TRUE(j.contains("device"));
    EXPECT_TRUE(j.contains("commit"));
    ASSERT_TRUE(j.contains("results"));
    ASSERT_TRUE(j["results"].is_array());
    ASSERT_EQ(j["results"].size(), 2u);
    const json sizes = json::array({json::array({16, 16, 16}), json::array({8, 4, 2})});
    for (std::size_t i = 0; i < 2; ++i) {
        const json& e = j["results"][i];
        SCOPED_TRACE(e.dump());
        for (const char* key :
             {"algorithm", "size", "median_ms", "mean_ms", "std_ms", "ci95_ms", "gvox_per_s"}) {
            EXPECT_TRUE(e.contains(key)) << key;
        }
        EXPECT_EQ(e.value("algorithm", ""), "exact");
        EXPECT_EQ(e["size"], sizes[i]);
        EXPECT_TRUE(e["median_ms"].is_number());
        EXPECT_TRUE(e["mean_ms"].is_number());
        EXPECT_TRUE(e["std_ms"].is_number());
        ASSERT_TRUE(e["ci95_ms"].is_array());
        EXPECT_EQ(e["ci95_ms"].size(), 2u);
        EXPECT_TRUE(e["gvox_per_s"].is_number());
        ASSERT_TRUE(e.contains("max_error"));
        EXPECT_EQ(e["max_error"], 0);
    }
    const std::vector<std::string> lines = split_lines(read_text(csv));
    ASSERT_EQ(lines.size(), 3u) << read_text(csv);
    EXPECT_EQ(lines[0].rfind("algorithm,", 0), 0u) << lines[0];
    EXPECT_EQ(lines[1].rfind("exact,16,16,16,", 0), 0u) << lines[1];
    EXPECT_EQ(lines[2].rfind("exact,8,4,2,", 0), 0u) << lines[2];
    EXPECT_EQ(list_dir(dir_), (std::set<std::string>{"bench.json", "bench.csv"}));
}

// The dissertation's algorithms in bench: --chunk applies to them, exact stays global.
TEST_F(CliTest, BenchAlgorithmsWithChunk) {
    const fs::path js = dir_ / "bench.json";
    const RunResult r =
        run({"bench", "--algorithms", "exact,fim,jfa", "--sizes", "16,24", "--chunk", "8",
             "--repeat", "2", "--warmup", "0", "--device", "cpu", "--json", js.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    json j;
    ASSERT_NO_THROW(j = json::parse(read_text(js))) << read_text(js);
    ASSERT_TRUE(j.contains("results"));
    ASSERT_TRUE(j["results"].is_array());
    ASSERT_EQ(j["results"].size(), 6u) << j["results"].dump(2);
    std::set<std::pair<std::string, int>> seen;
    for (const json& e : j["results"]) {
        SCOPED_TRACE(e.dump());
        ASSERT_TRUE(e.contains("algorithm"));
        ASSERT_TRUE(e.contains("size"));
        const std::string algorithm = e["algorithm"].get<std::string>();
        const int n = e["size"][0].get<int>();
        EXPECT_TRUE(n == 16 || n == 24) << n;
        EXPECT_EQ(e["size"], json::array({n, n, n}));
        EXPECT_TRUE(seen.insert({algorithm, n}).second) << "duplicate row";
        EXPECT_FALSE(e.contains("skipped"));
        ASSERT_TRUE(e.contains("chunk"));
        if (algorithm == "exact") {
            EXPECT_TRUE(e["chunk"].is_null()) << e["chunk"];
        } else {
            EXPECT_EQ(e["chunk"], 8);
        }
        for (const char* key : {"median_ms", "mean_ms", "iterations", "max_error", "mean_error"}) {
            EXPECT_TRUE(e.contains(key) && e[key].is_number()) << key;
        }
        if (algorithm == "exact" || algorithm == "fim") {
            EXPECT_EQ(e.value("max_error", 999u), 0u);
            EXPECT_EQ(e.value("mean_error", 999.0), 0.0);
        }
        if (algorithm == "fim") {
            EXPECT_GE(e.value("iterations", 0u), 1u);
        }
        if (algorithm == "jfa") {
            ASSERT_TRUE(e.contains("under_fraction"));
            EXPECT_EQ(e["under_fraction"].get<double>(), 0.0);
        }
    }
    const std::set<std::pair<std::string, int>> want = {{"exact", 16}, {"exact", 24}, {"fim", 16},
                                                        {"fim", 24},   {"jfa", 16},   {"jfa", 24}};
    EXPECT_EQ(seen, want);
}

// Work an algorithm refuses is a row with the reason, not a failed run.
TEST_F(CliTest, BenchSkipsBruteOnLargeWorld) {
    const fs::path js = dir_ / "bench.json";
    const RunResult r = run({"bench", "--algorithms", "brute", "--sizes", "200", "--repeat", "1",
                             "--warmup", "0", "--device", "cpu", "--json", js.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    json j;
    ASSERT_NO_THROW(j = json::parse(read_text(js))) << read_text(js);
    ASSERT_TRUE(j.contains("results"));
    ASSERT_EQ(j["results"].size(), 1u) << j.dump(2);
    const json& e = j["results"][0];
    EXPECT_EQ(e.value("algorithm", ""), "brute");
    EXPECT_EQ(e["size"], json::array({200, 200, 200}));
    ASSERT_TRUE(e.contains("skipped")) << e.dump(2);
    ASSERT_TRUE(e["skipped"].is_string());
    EXPECT_NE(e["skipped"].get<std::string>().find("exact"), std::string::npos) << e.dump(2);
    EXPECT_FALSE(e.contains("median_ms")) << e.dump(2);
    EXPECT_NE(r.out.find("skipped"), std::string::npos) << r.out;
}

TEST_F(CliTest, BenchSkipsChunkLargerThanWorld) {
    const fs::path js = dir_ / "bench.json";
    const RunResult r =
        run({"bench", "--algorithms", "fim", "--sizes", "4,16", "--chunk", "8", "--repeat", "1",
             "--warmup", "0", "--device", "cpu", "--json", js.string()});
    ASSERT_EQ(r.code, 0) << describe(r);
    json j;
    ASSERT_NO_THROW(j = json::parse(read_text(js))) << read_text(js);
    ASSERT_EQ(j["results"].size(), 2u) << j.dump(2);
    const json& small = j["results"][0];
    EXPECT_EQ(small["size"], json::array({4, 4, 4}));
    ASSERT_TRUE(small.contains("skipped")) << small.dump(2);
    EXPECT_NE(small["skipped"].get<std::string>().find("larger than the world"), std::string::npos)
        << small.dump(2);
    const json& big = j["results"][1];
    EXPECT_EQ(big["size"], json::array({16, 16, 16}));
    EXPECT_FALSE(big.contains("skipped")) << big.dump(2);
    EXPECT_EQ(big.value("max_error", 999u), 0u);
}

TEST_F(CliTest, GenerateHelpDescribesAlgorithmOptions) {
    const RunResult r = run({"generate", "--help"});
    ASSERT_EQ(r.code, 0) << describe(r);
    for (const char* word :
         {"--chunk", "--focus", "--jfa-extra", "exact", "brute", "brute-chunked", "fim", "fim-host",
          "jfa", "jfa-host", "jfa-fim", "lod", "monolithic", "power of two"}) {
        EXPECT_NE(r.out.find(word), std::string::npos) << word << "\n" << r.out;
    }
}

}  // namespace
}  // namespace voxfield
