// The OpenCL program cache (ocl::Context::program) on PoCL: keyed by name, options and source,
// as runtime.hpp says, so that one name built from two sources gives two programs; and its
// disk cache across runs (a second context loads the entry; a spoilt entry is rebuilt).
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cl_test_util.hpp"

namespace voxfield {
namespace {

using test::pocl;

// The value kernel `k` of `program` writes into one int.
int run_value(ocl::Context& ctx, const cl::Program& program) {
    cl::Buffer out(ctx.context(), CL_MEM_READ_WRITE, sizeof(cl_int));
    cl::Kernel k(program, "value");
    k.setArg(0, out);
    ctx.queue().enqueueNDRangeKernel(k, cl::NullRange, cl::NDRange(1));
    cl_int v = 0;
    ctx.queue().enqueueReadBuffer(out, CL_TRUE, 0, sizeof v, &v);
    return v;
}

TEST(ProgramCache, OneNameFromTwoSourcesIsTwoPrograms) {
    const std::string a = "kernel void value(global int* out) { *out = 1; }";
    const std::string b = "kernel void value(global int* out) { *out = 2; }";
    const cl::Program pa = pocl().program("program_cache_test", {a}, "");
    const cl::Program pb = pocl().program("program_cache_test", {b}, "");
    EXPECT_EQ(run_value(pocl(), pa), 1);
    EXPECT_EQ(run_value(pocl(), pb), 2);
    // And the same source again is the cached program.
    EXPECT_EQ(pocl().program("program_cache_test", {a}, "")(), pa());
}

// The disk cache (program_cache_dir): each test points $XDG_CACHE_HOME at a folder of its own
// and makes fresh contexts, as separate runs would. PoCL keeps its own cache under the
// $XDG_CACHE_HOME it saw first in the process, so the folders live until the suite ends (when
// the tests run in one process) and a test removes only voxfield's part of its own.
class DiskProgramCache : public ::testing::Test {
  protected:
    static std::filesystem::path root() {
        return std::filesystem::temp_directory_path() /
               ("voxfield_program_cache_" + std::to_string(::getpid()));
    }
    static void TearDownTestSuite() { std::filesystem::remove_all(root()); }
    void SetUp() override {
        dir = root() / ::testing::UnitTest::GetInstance()->current_test_info()->name();
        std::filesystem::remove_all(dir);
        std::filesystem::create_directories(dir);
        save("XDG_CACHE_HOME", xdg);
        save("VOXFIELD_NO_PROGRAM_CACHE", off);
        ::setenv("XDG_CACHE_HOME", dir.c_str(), 1);
        ::unsetenv("VOXFIELD_NO_PROGRAM_CACHE");
    }
    void TearDown() override {
        restore("XDG_CACHE_HOME", xdg);
        restore("VOXFIELD_NO_PROGRAM_CACHE", off);
        std::filesystem::remove_all(dir / "voxfield");
    }
    static void save(const char* name, std::optional<std::string>& value) {
        const char* v = std::getenv(name);
        value = v == nullptr ? std::nullopt : std::optional<std::string>(v);
    }
    static void restore(const char* name, const std::optional<std::string>& value) {
        if (value) {
            ::setenv(name, value->c_str(), 1);
        } else {
            ::unsetenv(name);
        }
    }
    // A fresh context on the PoCL device (as a new run would make).
    static std::unique_ptr<ocl::Context> fresh() {
        return std::make_unique<ocl::Context>(pocl().info());
    }
    // The cache's entries (files in its folder).
    std::vector<std::filesystem::path> entries() const {
        std::vector<std::filesystem::path> out;
        const auto programs = dir / "voxfield" / "programs";
        if (std::filesystem::is_directory(programs)) {
            for (const auto& e : std::filesystem::directory_iterator(programs)) {
                out.push_back(e.path());
            }
        }
        return out;
    }
    // Builds `source` in a fresh context and checks the kernel's value.
    ocl::ProgramCacheStats build_and_run(const std::string& text, int want) {
        auto ctx = fresh();
        const cl::Program p = ctx->program("program_cache_test", {text}, "-cl-std=CL1.2");
        EXPECT_EQ(run_value(*ctx, p), want);
        return ctx->program_cache_stats();
    }

    std::filesystem::path dir;
    std::optional<std::string> xdg, off;
    const std::string source = "kernel void value(global int* out) { *out = 7; }";
};

TEST_F(DiskProgramCache, ASecondContextLoadsFromDisk) {
    EXPECT_EQ(ocl::program_cache_dir(), dir / "voxfield" / "programs");
    const auto first = build_and_run(source, 7);
    EXPECT_EQ(first.built, 1u);
    EXPECT_EQ(first.loaded, 0u);
    EXPECT_EQ(first.stored, 1u);
    ASSERT_EQ(entries().size(), 1u);
    const auto second = build_and_run(source, 7);
    EXPECT_EQ(second.loaded, 1u);
    EXPECT_EQ(second.built, 0u);
    EXPECT_EQ(second.rejected, 0u);
    EXPECT_EQ(entries().size(), 1u);
    // Another source (or options) is another entry, never the first one's program.
    const auto other = build_and_run("kernel void value(global int* out) { *out = 8; }", 8);
    EXPECT_EQ(other.built, 1u);
    EXPECT_EQ(other.loaded, 0u);
    EXPECT_EQ(entries().size(), 2u);
    auto ctx = fresh();
    EXPECT_EQ(run_value(*ctx, ctx->program("program_cache_test", {source}, "")), 7);
    EXPECT_EQ(ctx->program_cache_stats().built, 1u) << "other options, another entry";
    EXPECT_EQ(entries().size(), 3u);
}

TEST_F(DiskProgramCache, ACorruptEntryIsRebuiltAndRewritten) {
    build_and_run(source, 7);
    ASSERT_EQ(entries().size(), 1u);
    const std::filesystem::path entry = entries()[0];
    const auto whole = std::filesystem::file_size(entry);
    // A flipped byte in the binary, a truncated file, garbage, an empty file, and a folder
    // where the entry should be: each still gives the program, built from source.
    auto flip_last = [&] {
        std::fstream f(entry, std::ios::in | std::ios::out | std::ios::binary);
        f.seekg(-1, std::ios::end);
        const char c = static_cast<char>(f.get());
        f.seekp(-1, std::ios::end);
        f.put(static_cast<char>(c ^ 0x5A));
    };
    auto truncate = [&] { std::filesystem::resize_file(entry, whole / 2); };
    auto garbage = [&] { std::ofstream(entry, std::ios::binary) << "not a program"; };
    auto empty = [&] { std::ofstream(entry, std::ios::binary | std::ios::trunc); };
    for (const auto& spoil :
         std::vector<std::function<void()>>{flip_last, truncate, garbage, empty}) {
        spoil();
        const auto stats = build_and_run(source, 7);
        EXPECT_EQ(stats.rejected, 1u);
        EXPECT_EQ(stats.built, 1u);
        EXPECT_EQ(stats.loaded, 0u);
        EXPECT_EQ(stats.stored, 1u) << "rewritten";
        // Rewritten whole (PoCL's binary may grow by the work-group functions compiled when
        // the kernel ran, so its size is not the first entry's): a regular file that loads.
        EXPECT_TRUE(std::filesystem::is_regular_file(entry));
        EXPECT_GT(std::filesystem::file_size(entry), whole / 2);
        EXPECT_EQ(build_and_run(source, 7).loaded, 1u) << "the rewritten entry loads";
    }
    std::filesystem::remove(entry);
    std::filesystem::create_directory(entry);
    const auto stats = build_and_run(source, 7);
    EXPECT_EQ(stats.built, 1u);
    EXPECT_EQ(stats.stored, 0u) << "a folder in the way is left alone";
}

// An entry whose header and checksum are right but whose binary the driver refuses (written by
// another build of a driver that kept its version string, say): built from source.
TEST_F(DiskProgramCache, ABinaryTheDriverRefusesIsRebuilt) {
    build_and_run(source, 7);
    ASSERT_EQ(entries().size(), 1u);
    const std::filesystem::path entry = entries()[0];
    std::ifstream in(entry, std::ios::binary);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    in.close();
    // The entry's five header lines (magic, what, digest, size, checksum), then the binary.
    std::size_t pos = 0;
    std::vector<std::string> lines;
    for (int i = 0; i < 5; ++i) {
        const std::size_t end = text.find('\n', pos);
        ASSERT_NE(end, std::string::npos);
        lines.push_back(text.substr(pos, end - pos));
        pos = end + 1;
    }
    const std::string junk(4096, '\x5a');
    std::uint64_t h = 0xcbf29ce484222325ULL;  // FNV-1a 64, the entry's checksum
    for (const char c : junk) {
        h = (h ^ static_cast<unsigned char>(c)) * 0x100000001b3ULL;
    }
    char sum[17];
    std::snprintf(sum, sizeof sum, "%016llx", static_cast<unsigned long long>(h));
    std::ofstream(entry, std::ios::binary | std::ios::trunc) << lines[0] << '\n'
                                                             << lines[1] << '\n'
                                                             << lines[2] << '\n'
                                                             << junk.size() << '\n'
                                                             << sum << '\n'
                                                             << junk;
    const auto stats = build_and_run(source, 7);
    EXPECT_EQ(stats.rejected, 1u);
    EXPECT_EQ(stats.built, 1u);
    EXPECT_EQ(stats.stored, 1u);
    EXPECT_EQ(build_and_run(source, 7).loaded, 1u);
}

TEST_F(DiskProgramCache, WritesLeaveNoTemporaries) {
    build_and_run(source, 7);
    build_and_run("kernel void value(global int* out) { *out = 9; }", 9);
    for (const auto& e : entries()) {
        EXPECT_EQ(e.extension(), ".bin") << e;
        EXPECT_NE(e.filename().string()[0], '.') << e;
    }
    EXPECT_EQ(entries().size(), 2u);
}

TEST_F(DiskProgramCache, TheEnvironmentTurnsItOff) {
    ::setenv("VOXFIELD_NO_PROGRAM_CACHE", "1", 1);
    EXPECT_TRUE(ocl::program_cache_dir().empty());
    const auto a = build_and_run(source, 7);
    const auto b = build_and_run(source, 7);
    EXPECT_EQ(a.built + b.built, 2u);
    EXPECT_EQ(a.stored + b.stored + b.loaded, 0u);
    EXPECT_TRUE(entries().empty());
    ::setenv("VOXFIELD_NO_PROGRAM_CACHE", "0", 1);
    EXPECT_EQ(ocl::program_cache_dir(), dir / "voxfield" / "programs");
    ::setenv("XDG_CACHE_HOME", "relative/path", 1);
    EXPECT_NE(ocl::program_cache_dir().string().find(".cache/voxfield/programs"), std::string::npos)
        << "a relative $XDG_CACHE_HOME is ignored (XDG)";
}

TEST_F(DiskProgramCache, AnUnwritableFolderStillBuilds) {
    std::ofstream(dir / "voxfield") << "a file where the folder should be";
    const auto stats = build_and_run(source, 7);
    EXPECT_EQ(stats.built, 1u);
    EXPECT_EQ(stats.stored, 0u);
}

}  // namespace
}  // namespace voxfield
