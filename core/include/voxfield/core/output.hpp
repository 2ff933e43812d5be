#pragma once
// Writing output files: the one writer behind every file voxfield writes (fields, indices,
// worlds, .vox, JSON, CSV, PNG). What happens to each kind of target:
//   - a new path or an existing regular file: the bytes go to a unique temporary file beside
//     it (O_EXCL, a random name), renamed onto it once complete, so readers never see a partial
//     file and a failure leaves the old file as it was (an old file is swapped with it by
//     renameat2's RENAME_EXCHANGE, then unlinked: no writeback started in the rename, so like a
//     new file it reaches the disk with the page cache's writeback). A symbolic link is
//     followed: the file it names is replaced and the link kept;
//   - an existing character device (/dev/null, a terminal) or FIFO (a named pipe, a shell's
//     process substitution): written directly, never replaced (opening a FIFO waits for its
//     reader, as cp does);
//   - a directory, a socket or a block device: refused (InputError) before any work.
// Failures: a target refused, a missing, non-folder or unwritable folder, a read-only existing
// file: InputError (the command line's exit 2). Failing while writing (no space left, an I/O
// error, a reader that went away): OutputError (exit 1), naming the path and the reason.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <initializer_list>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace voxfield {

// Writing an output failed at run time (ENOSPC, EIO, EPIPE...): not the user's input.
class OutputError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

// Throws InputError unless `path` can be written as described above (checked before work).
void check_output_path(const std::filesystem::path& path);

// A path given for a command-line option, e.g. {"--json", "t.json"}.
struct NamedPath {
    std::string option;
    std::filesystem::path path;
};

// Checks a command's outputs before any work: each as check_output_path, no two naming the
// same file (character devices, which are written directly, may repeat), none naming one of
// `inputs` (existing files compared by device and inode, so links count as the same file).
// Empty paths are skipped.
void check_outputs(const std::vector<NamedPath>& outputs, const std::vector<NamedPath>& inputs);

// Outputs written together: write() puts each file in its temporary (or straight into its
// device or FIFO), commit() renames them all onto their targets. Destroyed before commit(), it
// removes every temporary, so a run that fails part-way (a later output out of space, an
// exception between two writes) leaves none of its outputs and no temporary behind.
class OutputBatch {
  public:
    // Takes one piece of a file's content, appended after the pieces before it.
    using Sink = std::function<void(std::span<const std::uint8_t>)>;

    OutputBatch() = default;
    ~OutputBatch();
    OutputBatch(const OutputBatch&) = delete;
    OutputBatch& operator=(const OutputBatch&) = delete;

    // The concatenation of `parts` (any memory, e.g. a mapped device buffer, written from
    // where it is) as the content of `path`.
    void write(const std::filesystem::path& path,
               std::initializer_list<std::span<const std::uint8_t>> parts);
    void write(const std::filesystem::path& path, const std::string& text);
    // The content of `path` made piece by piece: `produce` hands each piece, in order, to the
    // sink it is given, which writes it out at once (a file larger than any buffer the
    // program holds, e.g. a device buffer read in slabs). An exception from `produce` leaves
    // no temporary behind.
    void write(const std::filesystem::path& path, const std::function<void(const Sink&)>& produce);
    // Creates the temporary of `path` now, before its content exists, and takes `bytes` of
    // room for it from the file system (fallocate): a later write() of `path` fills that
    // file and then only copies (on tmpfs and ext4 the pages or blocks are found here, e.g.
    // on a second thread while the device is set up), and a disk too full for the output
    // fails here rather than part-way through the write. The file keeps the written length.
    // A path written directly (a device, a FIFO), or a file system without fallocate,
    // reserves nothing. Not thread-safe: nothing else may use the batch while it runs.
    void reserve(const std::filesystem::path& path, std::uint64_t bytes);
    void commit();

  private:
    std::vector<std::pair<std::string, std::string>> pending_;  // (temporary, target)
    // Reserved temporaries, open until written: (target, descriptor).
    std::vector<std::pair<std::string, int>> reserved_;
};

// Removes the temporaries of every OutputBatch alive (created, not yet renamed or removed):
// for the executable's handler of a signal that ends the process (Ctrl-C, SIGTERM), which
// runs no destructor. Async-signal-safe (unlink only).
void remove_output_temporaries() noexcept;

// One file written on its own: an OutputBatch of one, committed.
void write_output_file(const std::filesystem::path& path,
                       std::initializer_list<std::span<const std::uint8_t>> parts);
void write_output_file(const std::filesystem::path& path, const std::string& text);

}  // namespace voxfield
