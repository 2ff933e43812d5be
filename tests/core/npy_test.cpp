#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <random>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "test_util.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield {
namespace {

namespace fs = std::filesystem;
using test::expect_input_error;
using test::read_bytes;
using test::TempDir;
using test::write_bytes;

std::size_t esize(NpyType t) {
    return t == NpyType::u8 ? 1 : t == NpyType::u16 ? 2 : 4;
}

std::vector<std::uint8_t> random_data(NpyType t, Dims d, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::vector<std::uint8_t> b(d.count() * esize(t));
    for (auto& x : b) {
        x = static_cast<std::uint8_t>(rng());
    }
    return b;
}

// A .npy file with the given version, header text (padded as numpy does) and data bytes.
std::vector<std::uint8_t> make_npy(const std::string& dict, std::size_t data_bytes, int major = 1) {
    std::string header = dict;
    const std::size_t pre = major == 1 ? 10 : 12;
    while ((pre + header.size() + 1) % 64 != 0) {
        header += ' ';
    }
    header += '\n';
    std::vector<std::uint8_t> b = {0x93, 'N', 'U', 'M', 'P', 'Y'};
    b.push_back(static_cast<std::uint8_t>(major));
    b.push_back(0);
    b.push_back(static_cast<std::uint8_t>(header.size()));
    b.push_back(static_cast<std::uint8_t>(header.size() >> 8));
    if (major != 1) {
        b.push_back(0);
        b.push_back(0);
    }
    b.insert(b.end(), header.begin(), header.end());
    for (std::size_t i = 0; i < data_bytes; ++i) {
        b.push_back(static_cast<std::uint8_t>(i % 7));
    }
    return b;
}

std::string dict(const std::string& descr, const std::string& fortran, const std::string& shape) {
    return "{'descr': '" + descr + "', 'fortran_order': " + fortran + ", 'shape': " + shape + ", }";
}

TEST(Npy, RoundTripAllTypesAndOddShapes) {
    TempDir dir;
    const std::vector<Dims> shapes = {{1, 1, 1}, {3, 5, 7}, {17, 1, 2}, {1, 9, 1}, {64, 3, 33}};
    std::uint64_t seed = 1;
    for (NpyType t : {NpyType::u8, NpyType::u16, NpyType::u32}) {
        for (const Dims& d : shapes) {
            const auto data = random_data(t, d, seed++);
            const fs::path p = dir / "a.npy";
            write_npy(p, t, d, data);
            const auto raw = read_bytes(p);
            // Format 1.0, header padded so the data starts on a 64-byte boundary, ends in \n.
            ASSERT_GE(raw.size(), 10u);
            EXPECT_EQ(raw[6], 1);
            EXPECT_EQ(raw[7], 0);
            const std::size_t hl = raw[8] | (std::size_t{raw[9]} << 8);
            EXPECT_EQ((10 + hl) % 64, 0u);
            EXPECT_EQ(raw[10 + hl - 1], '\n');
            EXPECT_EQ(raw.size(), 10 + hl + data.size());
            const std::string header(raw.begin() + 10, raw.begin() + 10 + static_cast<long>(hl));
            std::string shape("(");  // by append: GCC 12 warns falsely on "(" + std::string
            shape.append(std::to_string(d.z)).append(", ").append(std::to_string(d.y));
            shape.append(", ").append(std::to_string(d.x)).append(")");
            EXPECT_NE(header.find(shape), std::string::npos) << header;
            const NpyArray a = read_npy(p);
            EXPECT_EQ(a.type, t);
            EXPECT_EQ(a.dims, d);
            EXPECT_EQ(a.data, data);
        }
    }
    // No temporary files are left behind.
    int files = 0;
    for (const auto& e : fs::directory_iterator(dir.path())) {
        ++files;
        EXPECT_EQ(e.path().filename(), "a.npy");
    }
    EXPECT_EQ(files, 1);
}

TEST(Npy, ReadsVersions2And3AndVariants) {
    TempDir dir;
    const std::vector<std::pair<std::string, NpyType>> ok = {
        {"|u1", NpyType::u8},  {"<u1", NpyType::u8},  {"=u1", NpyType::u8}, {"<u2", NpyType::u16},
        {"=u2", NpyType::u16}, {"<u4", NpyType::u32}, {"=u4", NpyType::u32}};
    int major = 1;
    for (const auto& [descr, type] : ok) {
        std::string name("v");
        name.append(descr).append(".npy");
        const fs::path p = dir / name;
        const std::size_t bytes = 2 * 3 * 4 * esize(type);
        write_bytes(p, make_npy(dict(descr, "False", "(4, 3, 2)"), bytes, major));
        major = major % 3 + 1;
        const NpyArray a = read_npy(p);
        EXPECT_EQ(a.type, type) << descr;
        EXPECT_EQ(a.dims, (Dims{2, 3, 4}));
        EXPECT_EQ(a.data.size(), bytes);
        EXPECT_EQ(a.data[1], 1);
    }
    // Key order, double quotes and no trailing comma are all accepted.
    const fs::path p = dir / "order.npy";
    write_bytes(p,
                make_npy("{\"shape\": (1,2,3), \"fortran_order\": False, \"descr\": \"|u1\"}", 6));
    EXPECT_EQ(read_npy(p).dims, (Dims{3, 2, 1}));
}

TEST(Npy, FloatFieldsAreNoWorldIntegerFieldsAreLabels) {
    TempDir dir;
    const std::vector<std::pair<std::string, NpyType>> fields = {{"<f4", NpyType::f32},
                                                                 {"<f8", NpyType::f64}};
    for (const auto& [descr, type] : fields) {
        const fs::path p = dir / "field.npy";
        write_bytes(p, make_npy(dict(descr, "False", "(2, 2, 2)"), 8 * npy_element_size(type)));
        const NpyArray a = read_npy(p);
        EXPECT_EQ(a.type, type) << descr;
        expect_input_error([&] { world_from_npy(a); }, {"bool or integer", npy_type_name(type)});
    }
    // Every integer and bool dtype reads as a label volume: nonzero = solid.
    const std::vector<std::pair<std::string, NpyType>> labels = {
        {"|i1", NpyType::i8},  {"<i2", NpyType::i16}, {"<i4", NpyType::i32},
        {"<i8", NpyType::i64}, {"|u1", NpyType::u8},  {"<u2", NpyType::u16},
        {"<u4", NpyType::u32}, {"<u8", NpyType::u64}, {"|b1", NpyType::b1}};
    for (const auto& [descr, type] : labels) {
        const fs::path p = dir / "labels.npy";
        const std::size_t es = npy_element_size(type);
        std::vector<std::uint8_t> body(8 * es, 0);
        body[1 * es] = 1;    // voxel (1, 0, 0): 1
        body[3 * es] = 200;  // voxel (1, 1, 0): 200, or -56 for a signed byte
        if (es > 1) {
            body[5 * es + 1] = 3;  // voxel (1, 0, 1): 768
        }
        body[6 * es + es - 1] = type == NpyType::b1 ? 1 : 0x80;  // most negative / huge / true
        std::vector<std::uint8_t> file = make_npy(dict(descr, "False", "(2, 2, 2)"), 0);
        file.insert(file.end(), body.begin(), body.end());
        write_bytes(p, file);
        const NpyArray a = read_npy(p);
        EXPECT_EQ(a.type, type) << descr;
        const World w = world_from_npy(a);
        const std::vector<bool> solid = {false, true, false, true, false, es > 1, true, false};
        for (std::size_t i = 0; i < 8; ++i) {
            EXPECT_EQ(w.voxels()[i] != 0, solid[i]) << descr << " voxel " << i;
        }
        EXPECT_EQ(w.voxels()[1], 1) << descr;
        if (type != NpyType::i8 && type != NpyType::b1) {
            EXPECT_EQ(w.voxels()[3], 200) << descr;  // palette indices survive
        }
        if (type == NpyType::b1 || type == NpyType::u8) {
            continue;
        }
        // Values outside 0..255 are refused, naming the voxel, where palette values are needed.
        try {
            world_from_npy(a, Labels::palette);
            ADD_FAILURE() << descr << " gave palette values outside 0..255";
        } catch (const InputError& e) {
            const std::string what = e.what();
            EXPECT_NE(what.find("is not a palette index"), std::string::npos) << what;
            EXPECT_NE(what.find(type == NpyType::i8 ? "(x=1, y=1, z=0)" : "(x=1, y=0, z=1)"),
                      std::string::npos)
                << what;
        }
    }
    // A 4-D int32 array (the feature transform's layout) round-trips its header.
    const fs::path p = dir / "idx.npy";
    write_npy_shape(p, NpyType::i32, {3, 1, 1, 2}, std::vector<std::uint8_t>(24, 0));
    std::ifstream in(p, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    EXPECT_NE(bytes.find("'descr': '<i4', 'fortran_order': False, 'shape': (3, 1, 1, 2), }"),
              std::string::npos);
}

TEST(Npy, Rejections) {
    TempDir dir;
    struct Case {
        std::string name;
        std::vector<std::uint8_t> bytes;
        std::vector<std::string> expect;
    };
    std::vector<Case> cases;
    cases.push_back({"c8.npy",
                     make_npy(dict("<c8", "False", "(2, 2, 2)"), 64),
                     {"c8.npy", "dtype '<c8' (complex64) is not supported",
                      "a world is a bool or integer array"}});
    cases.push_back({"be_f4.npy",
                     make_npy(dict(">f4", "False", "(2, 2, 2)"), 32),
                     {"dtype '>f4' (float32) is not supported", "a world is a bool"}});
    cases.push_back({"be_u8.npy", make_npy(dict(">u8", "False", "(2, 2, 2)"), 64), {"big-endian"}});
    cases.push_back({"pipe_u2.npy", make_npy(dict("|u2", "False", "(2, 2, 2)"), 16), {"'|u2'"}});
    cases.push_back({"be2.npy",
                     make_npy(dict(">u2", "False", "(2, 2, 2)"), 16),
                     {"be2.npy", "'>u2'", "big-endian"}});
    cases.push_back({"be4.npy", make_npy(dict(">u4", "False", "(2, 2, 2)"), 32), {"big-endian"}});
    // A descr's control characters and NUL quoted, so that the message is one whole line.
    cases.push_back({"nl.npy",
                     make_npy(dict("x\ny", "False", "(2, 2, 2)"), 8),
                     {"dtype 'x\\x0ay' is not supported"}});
    cases.push_back({"nul.npy",
                     make_npy(dict(std::string("|u1\0", 4), "False", "(2, 2, 2)"), 8),
                     {"dtype '|u1\\x00' is not supported"}});
    cases.push_back({"fortran.npy",
                     make_npy(dict("|u1", "True", "(2, 2, 2)"), 8),
                     {"fortran.npy", "fortran_order"}});
    cases.push_back({"ndim2.npy",
                     make_npy(dict("|u1", "False", "(2, 2)"), 4),
                     {"ndim2.npy", "(2, 2)", "2 dimensions", "expected 3"}});
    cases.push_back({"ndim1.npy", make_npy(dict("|u1", "False", "(8,)"), 8), {"1 dimensions"}});
    cases.push_back(
        {"ndim4.npy", make_npy(dict("|u1", "False", "(1, 2, 2, 2)"), 8), {"4 dimensions"}});
    cases.push_back({"ndim0.npy", make_npy(dict("|u1", "False", "()"), 1), {"0 dimensions"}});
    cases.push_back({"zero.npy",
                     make_npy(dict("|u1", "False", "(2, 0, 2)"), 0),
                     {"zero.npy", "(2, 0, 2)", "empty axis"}});
    cases.push_back({"short.npy",
                     make_npy(dict("<u2", "False", "(2, 3, 4)"), 47),
                     {"short.npy", "truncated", "needs 48", "file has 47"}});
    cases.push_back({"nodata.npy",
                     make_npy(dict("<u4", "False", "(1, 1, 1)"), 0),
                     {"truncated", "needs 4", "file has 0"}});
    cases.push_back({"huge.npy",
                     make_npy(dict("<u4", "False", "(4294967295, 4294967295, 4294967295)"), 8),
                     {"truncated"}});
    cases.push_back(
        {"bigaxis.npy", make_npy(dict("|u1", "False", "(1, 1, 4294967296)"), 8), {"too large"}});
    cases.push_back({"nodescr.npy",
                     make_npy("{'fortran_order': False, 'shape': (1, 1, 1), }", 1),
                     {"nodescr.npy", "missing key 'descr'"}});
    cases.push_back({"noshape.npy",
                     make_npy("{'descr': '|u1', 'fortran_order': False}", 1),
                     {"missing key 'shape'"}});
    cases.push_back({"garbage.npy",
                     make_npy("{'descr': '|u1', 'fortran_order': Fals", 1),
                     {"garbage.npy", "malformed header"}});
    cases.push_back({"notdict.npy", make_npy("[1, 2, 3]", 1), {"malformed header"}});
    cases.push_back({"unterminated.npy", make_npy("{'descr: |u1}", 1), {"unterminated string"}});
    cases.push_back(
        {"shape_str.npy", make_npy(dict("|u1", "False", "'abc'"), 1), {"shape is 'abc'"}});
    cases.push_back(
        {"fo_int.npy", make_npy(dict("|u1", "0", "(1, 1, 1)"), 1), {"fortran_order is 0"}});
    cases.push_back(
        {"neg.npy", make_npy(dict("|u1", "False", "(1, -1, 1)"), 1), {"malformed header"}});
    {
        auto b = make_npy(dict("|u1", "False", "(1, 1, 1)"), 1);
        b[0] = 'X';
        cases.push_back({"magic.npy", b, {"magic.npy", "not a .npy file", "magic"}});
    }
    {
        auto b = make_npy(dict("|u1", "False", "(1, 1, 1)"), 1);
        b[6] = 4;
        cases.push_back({"version.npy", b, {"version 4.0", "not supported"}});
    }
    {
        auto b = make_npy(dict("|u1", "False", "(1, 1, 1)"), 1);
        b[8] = 0xFF;
        b[9] = 0xFF;
        cases.push_back({"hlen.npy", b, {"hlen.npy", "truncated", "header needs 65535"}});
    }
    {
        auto b = make_npy(dict("|u1", "False", "(1, 1, 1)"), 1, 2);
        b[11] = 0x80;  // 2 GiB header length
        cases.push_back({"hlen2.npy", b, {"truncated", "header needs"}});
    }
    cases.push_back({"tiny.npy", {0x93, 'N', 'U'}, {"tiny.npy", "3 bytes"}});
    cases.push_back({"empty.npy", {}, {"empty.npy", "0 bytes"}});
    for (const auto& c : cases) {
        SCOPED_TRACE(c.name);
        write_bytes(dir / c.name, c.bytes);
        expect_input_error([&] { read_npy(dir / c.name); }, c.expect);
    }
    // Every prefix of a valid file is rejected cleanly.
    const auto good = make_npy(dict("<u2", "False", "(2, 3, 4)"), 48);
    for (std::size_t cut = 0; cut < good.size(); ++cut) {
        write_bytes(dir / "cut.npy",
                    std::vector<std::uint8_t>(good.begin(), good.begin() + static_cast<long>(cut)));
        EXPECT_THROW(read_npy(dir / "cut.npy"), InputError) << cut;
    }
    write_bytes(dir / "cut.npy", good);
    EXPECT_NO_THROW(read_npy(dir / "cut.npy"));
}

TEST(Npy, MissingFileAndFolder) {
    TempDir dir;
    const fs::path missing = dir / "nope.npy";
    expect_input_error([&] { read_npy(missing); },
                       {test::cat({"'", missing.string(), "': no such file"})});
    expect_input_error([&] { read_npy(dir.path()); }, {"directory"});
}

TEST(Npy, AtomicWriteLeavesNothingWhenFolderMissing) {
    TempDir dir;
    const fs::path target = dir / "missing" / "out.npy";
    const std::vector<std::uint8_t> data(8, 1);
    expect_input_error(
        [&] {
            write_npy(target, NpyType::u8, Dims{2, 2, 2}, data);
        },
        {test::cat({"cannot write '", target.string(), "'"}),
         test::cat({"folder '", (dir / "missing").string(), "' does not exist"})});
    EXPECT_FALSE(fs::exists(target));
    EXPECT_TRUE(fs::is_empty(dir.path()));
    // A size mismatch is rejected before anything is written.
    EXPECT_THROW(write_npy(dir / "bad.npy", NpyType::u16, Dims{2, 2, 2}, data), InputError);
    EXPECT_TRUE(fs::is_empty(dir.path()));
    // Overwriting an existing file replaces it whole.
    write_npy(dir / "x.npy", NpyType::u8, Dims{2, 2, 2}, data);
    write_npy(dir / "x.npy", NpyType::u8, Dims{1, 1, 1}, {5});
    const NpyArray a = read_npy(dir / "x.npy");
    EXPECT_EQ(a.dims, (Dims{1, 1, 1}));
    EXPECT_EQ(a.data, std::vector<std::uint8_t>{5});
    int files = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path())) {
        ++files;
    }
    EXPECT_EQ(files, 1);
}

// NpyReader parses and checks the header first; the data goes straight into memory the caller
// owns, at any address and at any later time, and equals what read_npy returns.
TEST(Npy, ReaderReadsIntoCallerMemory) {
    TempDir dir;
    std::uint64_t seed = 7;
    int major = 1;
    for (const auto& [descr, type] : std::vector<std::pair<std::string, NpyType>>{
             {"|u1", NpyType::u8}, {"<u2", NpyType::u16}, {"<u4", NpyType::u32}}) {
        SCOPED_TRACE(descr);
        const Dims d{5, 3, 2};
        const auto data = random_data(type, d, seed++);
        auto bytes = make_npy(dict(descr, "False", "(2, 3, 5)"), 0, major);
        major = major % 3 + 1;
        bytes.insert(bytes.end(), data.begin(), data.end());
        const fs::path p = dir / "r.npy";
        write_bytes(p, bytes);
        const NpyReader reader(p);
        EXPECT_EQ(reader.type(), type);
        EXPECT_EQ(reader.dims(), d);
        ASSERT_EQ(reader.data_bytes(), data.size());
        // An odd offset into a larger buffer, guarded on both sides.
        std::vector<std::uint8_t> memory(data.size() + 16, 0xAB);
        reader.read_data(std::span<std::uint8_t>(memory.data() + 3, data.size()));
        EXPECT_EQ(std::vector<std::uint8_t>(memory.begin() + 3, memory.end() - 13), data);
        EXPECT_EQ(memory[2], 0xAB);
        EXPECT_EQ(memory[3 + data.size()], 0xAB);
        // Reading twice gives the same bytes; read_npy agrees.
        std::vector<std::uint8_t> again(data.size());
        reader.read_data(again);
        EXPECT_EQ(again, data);
        EXPECT_EQ(read_npy(p).data, data);
    }
    // The header alone is checked: a reader over a 64 MiB world reads none of its data yet.
    const fs::path big = dir / "big.npy";
    auto header = make_npy(dict("|u1", "False", "(256, 512, 512)"), 0);
    write_bytes(big, header);
    fs::resize_file(big, header.size() + (std::uint64_t{64} << 20));
    const NpyReader lazy(big);
    EXPECT_EQ(lazy.dims(), (Dims{512, 512, 256}));
    EXPECT_EQ(lazy.data_bytes(), std::size_t{64} << 20);
}

TEST(Npy, ReaderRejectsWhatReadNpyRejects) {
    TempDir dir;
    write_bytes(dir / "short.npy", make_npy(dict("<u2", "False", "(2, 3, 4)"), 47));
    expect_input_error([&] { NpyReader r(dir / "short.npy"); },
                       {"short.npy", "truncated", "needs 48", "file has 47"});
    expect_input_error([&] { NpyReader r(dir / "nope.npy"); }, {"nope.npy", "no such file"});
    expect_input_error([&] { NpyReader r(dir.path()); }, {"directory"});
    write_bytes(dir / "ok.npy", make_npy(dict("|u1", "False", "(1, 2, 3)"), 6));
    const NpyReader r(dir / "ok.npy");
    std::vector<std::uint8_t> wrong(5);
    EXPECT_THROW(r.read_data(wrong), std::invalid_argument);
    // A file that shrinks after its header was read is a read error, not a short array.
    fs::resize_file(dir / "ok.npy", fs::file_size(dir / "ok.npy") - 2);
    std::vector<std::uint8_t> six(6);
    expect_input_error([&] { r.read_data(six); }, {"ok.npy", "read error", "of 6 bytes"});
}

// write_npy from a pointer and size (memory that is no vector, e.g. a mapped device buffer)
// writes the same file as from a vector, atomically.
TEST(Npy, WritesFromCallerMemory) {
    TempDir dir;
    const Dims d{7, 3, 2};
    const auto data = random_data(NpyType::u16, d, 99);
    std::vector<std::uint8_t> memory(data.size() + 5, 0);
    std::copy(data.begin(), data.end(), memory.begin() + 5);
    const std::span<const std::uint8_t> view(memory.data() + 5, data.size());
    write_npy(dir / "span.npy", NpyType::u16, d, view);
    write_npy(dir / "vector.npy", NpyType::u16, d, data);
    EXPECT_EQ(read_bytes(dir / "span.npy"), read_bytes(dir / "vector.npy"));
    const NpyArray a = read_npy(dir / "span.npy");
    EXPECT_EQ(a.dims, d);
    EXPECT_EQ(a.data, data);
    write_npy_shape(dir / "shape.npy", NpyType::u16, {2, 3, 7}, view);
    EXPECT_EQ(read_bytes(dir / "shape.npy"), read_bytes(dir / "vector.npy"));
    // A failing write leaves nothing: wrong size, missing folder.
    EXPECT_THROW(write_npy(dir / "bad.npy", NpyType::u32, d, view), InputError);
    EXPECT_THROW(write_npy(dir / "no" / "x.npy", NpyType::u16, d, view), InputError);
    int files = 0;
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path())) {
        ++files;
    }
    EXPECT_EQ(files, 3);
}

TEST(Npy, WorldConversions) {
    World w(Dims{3, 2, 4});
    w.set(2, 1, 3, 200);
    w.set(0, 0, 1, 1);
    const NpyArray a = npy_from_world(w);
    EXPECT_EQ(a.type, NpyType::u8);
    EXPECT_EQ(a.dims, w.dims());
    const World back = world_from_npy(a);
    EXPECT_EQ(back.voxels(), w.voxels());

    NpyArray wide;
    wide.type = NpyType::u16;
    wide.dims = Dims{3, 2, 4};
    wide.data.assign(24 * 2, 0);
    wide.data[2 * w.dims().index(1, 1, 2)] = 255;
    World ok = world_from_npy(wide);
    EXPECT_EQ(ok.at(1, 1, 2), 255);
    EXPECT_EQ(ok.solid_count(), 1u);
    // 256 at (2, 0, 3) and 300 later: the first offending voxel is named.
    wide.data[2 * w.dims().index(2, 0, 3) + 1] = 1;
    wide.data[2 * w.dims().index(2, 1, 3)] = 44;
    wide.data[2 * w.dims().index(2, 1, 3) + 1] = 1;
    EXPECT_EQ(world_from_npy(wide).at(2, 0, 3), 1);  // a label above 255: solid
    expect_input_error([&] { world_from_npy(wide, Labels::palette); },
                       {"value 256", "(x=2, y=0, z=3)"});

    NpyArray u32;
    u32.type = NpyType::u32;
    u32.dims = Dims{1, 1, 2};
    u32.data = {7, 0, 0, 0, 0, 0, 0, 0x80};
    expect_input_error([&] { world_from_npy(u32, Labels::palette); },
                       {"value 2147483648", "(x=0, y=0, z=1)"});

    NpyArray bad;
    bad.dims = Dims{2, 2, 2};
    bad.data.assign(7, 0);
    EXPECT_THROW(world_from_npy(bad), InputError);
}

TEST(Npy, LoadWorldFromNpy) {
    TempDir dir;
    World w(Dims{4, 3, 2});
    w.set(3, 2, 1, 9);
    const NpyArray a = npy_from_world(w);
    write_npy(dir / "w.NPY", a.type, a.dims, a.data);
    const VoxModel m = load_world(dir / "w.NPY");
    EXPECT_EQ(m.world.dims(), w.dims());
    EXPECT_EQ(m.world.voxels(), w.voxels());
    EXPECT_EQ(m.palette[1], Palette()[1]);
    std::vector<std::uint8_t> wide(4 * 3 * 2 * 2, 0);
    wide[2 * 5 + 1] = 3;  // value 768 at index 5 = (1, 1, 0)
    write_npy(dir / "wide.npy", NpyType::u16, Dims{4, 3, 2}, wide);
    // A label volume: the CLI's reader takes it, label 768 a solid voxel of material 1.
    const VoxModel labels = load_world(dir / "wide.npy");
    EXPECT_EQ(labels.world.at(1, 1, 0), 1);
    EXPECT_EQ(labels.world.solid_count(), 1u);
    // bool and signed label volumes too.
    std::vector<std::uint8_t> flags(4 * 3 * 2, 0);
    flags[7] = 1;
    write_npy(dir / "flags.npy", NpyType::b1, Dims{4, 3, 2}, flags);
    EXPECT_EQ(load_world(dir / "flags.npy").world.solid_count(), 1u);
    std::vector<std::uint8_t> signed_labels(4 * 3 * 2 * 8, 0xFF);  // -1 everywhere
    write_npy(dir / "signed.npy", NpyType::i64, Dims{4, 3, 2}, signed_labels);
    EXPECT_EQ(load_world(dir / "signed.npy").world.solid_count(), 24u);
}

}  // namespace
}  // namespace voxfield
