// The output writer (voxfield/core/output.hpp): what each kind of target gets, no temporary
// left behind, batches that leave nothing when they fail, and the checks made before work.
// Special files are made in a temporary folder (mkfifo, mknod, a bound socket), never the
// system's own; device nodes need root (mknod), else those tests are skipped with the reason.
#include <fcntl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/un.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cstring>
#include <future>
#include <set>
#include <string>
#include <vector>

#include "test_util.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/output.hpp"

namespace voxfield {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

std::set<std::string> names_in(const fs::path& dir) {
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) {
        names.insert(e.path().filename().string());
    }
    return names;
}

std::string text_of(const fs::path& p) {
    const auto b = test::read_bytes(p);
    return {b.begin(), b.end()};
}

// A character device node of `major`, `minor` at `path` (1,3 is null, 1,7 full): empty when
// made, else why not.
std::string make_char_device(const fs::path& path, unsigned major, unsigned minor) {
    if (::mknod(path.c_str(), S_IFCHR | 0666, makedev(major, minor)) != 0) {
        return "mknod " + path.string() + ": " + std::strerror(errno) +
               " (character device nodes need root)";
    }
    return {};
}

bool is_char_device(const fs::path& p) {
    struct stat st {};
    return ::lstat(p.c_str(), &st) == 0 && S_ISCHR(st.st_mode);
}

template <class E, class F>
std::string expect_throw(F&& f) {
    try {
        f();
    } catch (const E& e) {
        return e.what();
    } catch (const std::exception& e) {
        ADD_FAILURE() << "wrong exception type: " << e.what();
        return {};
    }
    ADD_FAILURE() << "no exception";
    return {};
}

TEST(OutputFile, ReplacesARegularFileAndLeavesNoTemporary) {
    TempDir dir;
    test::write_text(dir / "out.json", "old");
    test::write_text(dir / "out.json.tmp", "a user's file");
    write_output_file(dir / "out.json", std::string("new"));
    EXPECT_EQ(text_of(dir / "out.json"), "new");
    EXPECT_EQ(text_of(dir / "out.json.tmp"), "a user's file");
    EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"out.json", "out.json.tmp"}));
}

// The old file is swapped out whole (renameat2's exchange, then unlinked), never written in
// place: another hard link to it keeps the old bytes, and no temporary is left.
TEST(OutputFile, ReplacingAFileLeavesItsOtherLinksTheOldBytes) {
    TempDir dir;
    test::write_text(dir / "out.npy", "old bytes");
    fs::create_hard_link(dir / "out.npy", dir / "backup.npy");
    write_output_file(dir / "out.npy", std::string("new"));
    EXPECT_EQ(text_of(dir / "out.npy"), "new");
    EXPECT_EQ(text_of(dir / "backup.npy"), "old bytes");
    EXPECT_EQ(fs::hard_link_count(dir / "out.npy"), 1u);
    EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"backup.npy", "out.npy"}));
}

TEST(OutputFile, FollowsASymbolicLinkAndKeepsIt) {
    TempDir dir;
    test::write_text(dir / "real.txt", "old");
    fs::create_symlink("real.txt", dir / "link.txt");
    write_output_file(dir / "link.txt", std::string("new"));
    EXPECT_TRUE(fs::is_symlink(dir / "link.txt"));
    EXPECT_EQ(text_of(dir / "real.txt"), "new");
    EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"link.txt", "real.txt"}));
}

TEST(OutputFile, FollowsADanglingLinkBeforeAnyWork) {
    // A link to a file not yet there: the file is created and the link kept; a link into a
    // folder that does not exist is refused by the check before any work, as that folder.
    TempDir dir;
    fs::create_symlink("new.txt", dir / "link.txt");
    check_output_path(dir / "link.txt");
    write_output_file(dir / "link.txt", std::string("new"));
    EXPECT_TRUE(fs::is_symlink(dir / "link.txt"));
    EXPECT_EQ(text_of(dir / "new.txt"), "new");
    EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"link.txt", "new.txt"}));
    fs::create_symlink(dir / "no" / "x.npy", dir / "far.npy");
    const std::string what = expect_throw<InputError>([&] { check_output_path(dir / "far.npy"); });
    EXPECT_NE(what.find("folder '" + (dir / "no").string() + "' does not exist"), std::string::npos)
        << what;
}

TEST(OutputFile, RefusesADirectoryBeforeWritingAnything) {
    TempDir dir;
    fs::create_directory(dir / "adir");
    const std::string what =
        expect_throw<InputError>([&] { write_output_file(dir / "adir", std::string("x")); });
    EXPECT_NE(what.find("is a directory"), std::string::npos) << what;
    EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"adir"}));
    EXPECT_TRUE(fs::is_empty(dir / "adir"));
}

TEST(OutputFile, RefusesAMissingFolderAFileAsFolderAndASocket) {
    TempDir dir;
    std::string what = expect_throw<InputError>([&] { check_output_path(dir / "no" / "x.npy"); });
    EXPECT_NE(what.find("does not exist"), std::string::npos) << what;
    test::write_text(dir / "file", "x");
    what = expect_throw<InputError>([&] { check_output_path(dir / "file" / "x.npy"); });
    EXPECT_NE(what.find("is not a folder"), std::string::npos) << what;

    const fs::path sock = dir / "s.sock";
    const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
    ASSERT_GE(fd, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    ASSERT_LT(sock.string().size(), sizeof addr.sun_path);
    std::strcpy(addr.sun_path, sock.c_str());
    ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
    what = expect_throw<InputError>([&] { write_output_file(sock, std::string("x")); });
    ::close(fd);
    EXPECT_NE(what.find("socket"), std::string::npos) << what;
    struct stat st {};
    ASSERT_EQ(::lstat(sock.c_str(), &st), 0);
    EXPECT_TRUE(S_ISSOCK(st.st_mode));
}

TEST(OutputFile, WritesAFifoDirectlyAndLeavesItAFifo) {
    TempDir dir;
    const fs::path fifo = dir / "pipe";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0) << std::strerror(errno);
    auto reader = std::async(std::launch::async, [&] { return text_of(fifo); });
    write_output_file(fifo, std::string("through the pipe"));
    EXPECT_EQ(reader.get(), "through the pipe");
    struct stat st {};
    ASSERT_EQ(::lstat(fifo.c_str(), &st), 0);
    EXPECT_TRUE(S_ISFIFO(st.st_mode));
    EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"pipe"}));
}

TEST(OutputFile, WritesANullDeviceDirectlyAndLeavesItADevice) {
    TempDir dir;
    const fs::path null = dir / "null";
    if (const std::string why = make_char_device(null, 1, 3); !why.empty()) {
        GTEST_SKIP() << why;
    }
    write_npy(null, NpyType::u8, Dims{2, 2, 2}, std::vector<std::uint8_t>(8, 1));
    EXPECT_TRUE(is_char_device(null));
    EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"null"}));
}

TEST(OutputFile, AFullDeviceIsARuntimeFailureNamingThePathAndTheReason) {
    TempDir dir;
    const fs::path full = dir / "full";
    if (const std::string why = make_char_device(full, 1, 7); !why.empty()) {
        GTEST_SKIP() << why;
    }
    const std::string what = expect_throw<OutputError>([&] {
        write_npy(full, NpyType::u8, Dims{2, 2, 2}, std::vector<std::uint8_t>(8, 1));
    });
    EXPECT_NE(what.find(full.string()), std::string::npos) << what;
    EXPECT_NE(what.find("No space left on device"), std::string::npos) << what;
    EXPECT_TRUE(is_char_device(full));
    EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"full"}));
}

TEST(OutputFile, ABatchThatFailsLeavesNoneOfItsOutputs) {
    TempDir dir;
    const fs::path full = dir / "full";
    if (const std::string why = make_char_device(full, 1, 7); !why.empty()) {
        GTEST_SKIP() << why;
    }
    test::write_text(dir / "b.txt", "kept");
    {
        OutputBatch batch;
        batch.write(dir / "a.txt", std::string("first"));
        batch.write(dir / "b.txt", std::string("second"));
        EXPECT_THROW(batch.write(full, std::string("third")), OutputError);
    }
    EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"b.txt", "full"}));
    EXPECT_EQ(text_of(dir / "b.txt"), "kept");
}

TEST(OutputFile, ABatchCommittedWritesEveryOutput) {
    TempDir dir;
    {
        OutputBatch batch;
        batch.write(dir / "a.txt", std::string("first"));
        write_npy(batch, dir / "f.npy", NpyType::u8, Dims{1, 1, 2},
                  std::vector<std::uint8_t>{1, 2});
        EXPECT_EQ(names_in(dir.path()).count("a.txt"), 0u);
        batch.commit();
    }
    EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"a.txt", "f.npy"}));
    EXPECT_EQ(read_npy(dir / "f.npy").data, (std::vector<std::uint8_t>{1, 2}));
}

TEST(OutputFile, AReservedFileKeepsWhatWasWrittenAndNothingBeforeCommit) {
    TempDir dir;
    test::write_text(dir / "old.npy", "old content");
    const std::vector<std::uint8_t> field(5000, 7);
    {
        OutputBatch batch;
        // Reserved larger, smaller and exactly: each file keeps the bytes written.
        batch.reserve(dir / "old.npy", 1 << 20);
        batch.reserve(dir / "new.npy", 10);
        batch.reserve(dir / "a.txt", 5);
        EXPECT_EQ(text_of(dir / "old.npy"), "old content");
        EXPECT_EQ(names_in(dir.path()).count("new.npy"), 0u);
        write_npy(batch, dir / "old.npy", NpyType::u8, Dims{50, 10, 10}, field);
        write_npy(batch, dir / "new.npy", NpyType::u8, Dims{50, 10, 10}, field);
        batch.write(dir / "a.txt", std::string("first"));
        batch.commit();
    }
    EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"a.txt", "new.npy", "old.npy"}));
    EXPECT_EQ(read_npy(dir / "old.npy").data, field);
    EXPECT_EQ(read_npy(dir / "new.npy").data, field);
    EXPECT_EQ(fs::file_size(dir / "old.npy"), fs::file_size(dir / "new.npy"));
    EXPECT_EQ(text_of(dir / "a.txt"), "first");
    {
        // Reserved, never written or committed: no temporary stays and the old file is kept.
        OutputBatch batch;
        batch.reserve(dir / "a.txt", 1 << 16);
        batch.reserve(dir / "b.txt", 1 << 16);
    }
    EXPECT_EQ(names_in(dir.path()), (std::set<std::string>{"a.txt", "new.npy", "old.npy"}));
    EXPECT_EQ(text_of(dir / "a.txt"), "first");
    const fs::path null = dir / "null";
    if (make_char_device(null, 1, 3).empty()) {
        OutputBatch batch;
        batch.reserve(null, 1 << 16);
        batch.write(null, std::string("direct"));
        batch.commit();
        EXPECT_TRUE(is_char_device(null));
    }
}

TEST(OutputFile, ChecksOutputsAgainstEachOtherAndTheInputs) {
    TempDir dir;
    test::write_text(dir / "in.npy", "x");
    fs::create_hard_link(dir / "in.npy", dir / "alias.npy");
    std::string what = expect_throw<InputError>([&] {
        check_outputs({{"-o", dir / "o.npy"}, {"--json", dir / "." / "o.npy"}}, {});
    });
    EXPECT_NE(what.find("-o and --json name the same file"), std::string::npos) << what;
    what = expect_throw<InputError>([&] {
        check_outputs({{"-o", dir / "alias.npy"}}, {{"INPUT", dir / "in.npy"}});
    });
    EXPECT_NE(what.find("is the input INPUT"), std::string::npos) << what;
    check_outputs({{"-o", dir / "o.npy"}, {"--json", dir / "o.json"}, {"--csv", ""}},
                  {{"INPUT", dir / "in.npy"}});
    // A dangling link names the file that writing through it would create.
    fs::create_symlink("f.npy", dir / "to_f.npy");
    what = expect_throw<InputError>([&] {
        check_outputs({{"-o", dir / "f.npy"}, {"--indices", dir / "to_f.npy"}}, {});
    });
    EXPECT_NE(what.find("-o and --indices name the same file"), std::string::npos) << what;
    // The same with the output given relative to the working folder, as on a command line.
    const fs::path cwd = fs::current_path();
    fs::current_path(dir.path());
    what = expect_throw<InputError>([&] {
        check_outputs({{"-o", "f.npy"}, {"--indices", "to_f.npy"}}, {});
    });
    fs::current_path(cwd);
    EXPECT_NE(what.find("-o and --indices name the same file"), std::string::npos) << what;
    const fs::path null = dir / "null";
    if (make_char_device(null, 1, 3).empty()) {
        check_outputs({{"-o", null}, {"--indices", null}}, {});
    }
}

}  // namespace
}  // namespace voxfield
