// End-to-end tests of the `voxfield` executable (DESIGN §4): runs the binary, captures its
// stdout, stderr and exit code, and checks outputs against the exact CPU reference.
#include <fcntl.h>
#include <spawn.h>
#include <stdlib.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <algorithm>
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

#include "voxfield/core/format.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/palette.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/vox.hpp"
#include "voxfield/core/world.hpp"

extern char** environ;

namespace voxfield {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kExe = VOXFIELD_EXE;
const fs::path kVox = fs::path(VOXFIELD_DATA_DIR) / "vox" / "chr_army1.vox";
const std::vector<std::string> kFormats = {"u8", "u16", "u32", "packed32"};

struct RunResult {
    int code = -1;
    std::string out, err;
};

std::string read_text(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::vector<std::uint8_t> read_bytes(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const fs::path& p, const std::string& bytes) {
    std::ofstream out(p, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    ASSERT_TRUE(out.good()) << p;
}

fs::path make_temp_dir(const std::string& stem) {
    std::string tmpl = (fs::temp_directory_path() / (stem + "_XXXXXX")).string();
    if (::mkdtemp(tmpl.data()) == nullptr) {
        throw std::runtime_error("mkdtemp failed for " + tmpl);
    }
    return tmpl;
}

std::set<std::string> list_dir(const fs::path& dir) {
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) {
        names.insert(e.path().filename().string());
    }
    return names;
}

std::vector<std::string> split_lines(const std::string& text) {
    std::vector<std::string> lines;
    std::istringstream in(text);
    for (std::string line; std::getline(in, line);) {
        lines.push_back(line);
    }
    return lines;
}

// Runs the binary with `args`; stdout/stderr go to files in `io_dir` (never the work folder,
// so that the folder listing checks see only what voxfield wrote).
RunResult run_voxfield(const std::vector<std::string>& args, const fs::path& io_dir) {
    static int counter = 0;
    ++counter;
    const fs::path out_path = io_dir / ("stdout_" + std::to_string(counter));
    const fs::path err_path = io_dir / ("stderr_" + std::to_string(counter));
    std::vector<std::string> argv_s = {kExe.string()};
    argv_s.insert(argv_s.end(), args.begin(), args.end());
    std::vector<char*> argv;
    for (auto& a : argv_s) {
        argv.push_back(a.data());
    }
    argv.push_back(nullptr);

    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&fa, 2, err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
    pid_t pid = 0;
    const int rc = posix_spawn(&pid, argv[0], &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    RunResult r;
    if (rc != 0) {
        r.err = std::string("posix_spawn failed: ") + std::strerror(rc);
        return r;
    }
    int status = 0;
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    if (WIFEXITED(status)) {
        r.code = WEXITSTATUS(status);
    } else if (WIFSIGNALED(status)) {
        r.code = 128 + WTERMSIG(status);
    }
    r.out = read_text(out_path);
    r.err = read_text(err_path);
    fs::remove(out_path);
    fs::remove(err_path);
    return r;
}

std::string describe(const RunResult& r) {
    return "exit " + std::to_string(r.code) + "\n--- stdout ---\n" + r.out + "--- stderr ---\n" +
           r.err;
}

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

class CliTest : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = make_temp_dir("voxfield_cli");
        io_ = make_temp_dir("voxfield_cli_io");
    }
    void TearDown() override {
        std::error_code ec;
        fs::remove_all(dir_, ec);
        fs::remove_all(io_, ec);
    }
    RunResult run(const std::vector<std::string>& args) { return run_voxfield(args, io_); }

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

    fs::path dir_, io_;
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

TEST_F(CliTest, GenerateOverwritesExistingOutput) {
    const World w = test_world();
    const fs::path in = dir_ / "world.npy";
    write_npy(in, NpyType::u8, w.dims(), w.voxels());
    const fs::path out = dir_ / "field.npy";
    write_bytes(out, "old contents");
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
                     write_bytes(d / "empty.vox", "");
                     return gen(d / "empty.vox", o);
                 },
                 {"empty.vox"}});
    c.push_back({"TruncatedVox",
                 [](const fs::path& d, const fs::path& o) {
                     write_bytes(d / "trunc.vox", vox_bytes().substr(0, 100));
                     return gen(d / "trunc.vox", o);
                 },
                 {"trunc.vox"}});
    c.push_back({"CorruptVoxMagic",
                 [](const fs::path& d, const fs::path& o) {
                     std::string b = vox_bytes();
                     b.replace(0, 4, "XOV ");
                     write_bytes(d / "corrupt.vox", b);
                     return gen(d / "corrupt.vox", o);
                 },
                 {"corrupt.vox"}});
    c.push_back({"NpyFloat32",
                 [](const fs::path& d, const fs::path& o) {
                     write_bytes(d / "float.npy",
                                 raw_npy("<f4", "(2, 2, 2)", std::string(32, '\0')));
                     return gen(d / "float.npy", o);
                 },
                 {"float.npy", "dtype"}});
    c.push_back({"Npy2D",
                 [](const fs::path& d, const fs::path& o) {
                     write_bytes(d / "flat.npy", raw_npy("|u1", "(4, 4)", std::string(16, '\1')));
                     return gen(d / "flat.npy", o);
                 },
                 {"flat.npy", "shape"}});
    c.push_back({"NpyZeroAxis",
                 [](const fs::path& d, const fs::path& o) {
                     write_bytes(d / "zero.npy", raw_npy("|u1", "(0, 4, 4)", ""));
                     return gen(d / "zero.npy", o);
                 },
                 {"zero.npy", "empty axis"}});
    c.push_back({"NpyUint16Over255",
                 [](const fs::path& d, const fs::path& o) {
                     std::string data(2 * 2 * 3 * 2, '\0');
                     data[14] = static_cast<char>(300 & 0xFF);  // element 7 = 300
                     data[15] = static_cast<char>(300 >> 8);
                     write_bytes(d / "big.npy", raw_npy("<u2", "(2, 2, 3)", data));
                     return gen(d / "big.npy", o);
                 },
                 {"big.npy", "300"}});
    c.push_back({"UnknownExtension",
                 [](const fs::path& d, const fs::path& o) {
                     write_bytes(d / "world.txt", "hello");
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
                 {"99", "not index 99"}});
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

}  // namespace
}  // namespace voxfield
