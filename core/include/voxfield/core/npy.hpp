#pragma once
// NumPy .npy files (format 1.0/2.0/3.0 read, 1.0 write): 3-D C-order arrays of shape (Z, Y, X)
// of bool or any integer type (worlds: label volumes, nonzero = solid; uint8/16/32 and
// int8/16/32 fields too) and float32/64 (fields); 4-D int32 for the feature transform is
// written only. Anything else is rejected with an InputError.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include "voxfield/core/output.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield {

enum class NpyType { u8, u16, u32, i8, i16, i32, f32, f64, b1, u64, i64 };

// NumPy's name of a type ("uint8", "bool", ...) and its element size in bytes.
const char* npy_type_name(NpyType type);
std::size_t npy_element_size(NpyType type);

struct NpyArray {
    NpyType type = NpyType::u8;
    Dims dims;                       // x = shape[2], y = shape[1], z = shape[0]
    std::vector<std::uint8_t> data;  // little-endian elements, x fastest
};

NpyArray read_npy(const std::filesystem::path& path);

// A .npy file opened and its header read and checked as read_npy checks them, to read the
// data straight into memory the caller provides (no copy on the way, nothing zero-filled):
// a caller can parse the header first, allocate, and read later (or on another thread).
class NpyReader {
  public:
    explicit NpyReader(const std::filesystem::path& path);  // InputError as read_npy
    ~NpyReader();
    NpyReader(NpyReader&&) noexcept;
    NpyReader& operator=(NpyReader&&) noexcept;

    NpyType type() const { return type_; }
    const Dims& dims() const { return dims_; }
    std::size_t data_bytes() const { return data_bytes_; }  // element size x voxel count
    // Reads the data (little-endian elements, x fastest) into `dst`, which must hold exactly
    // data_bytes(); InputError on a read error, std::invalid_argument on a size mismatch.
    void read_data(std::span<std::uint8_t> dst) const;

  private:
    struct File;
    std::unique_ptr<File> file_;
    NpyType type_ = NpyType::u8;
    Dims dims_;
    std::uint64_t data_offset_ = 0;
    std::size_t data_bytes_ = 0;
};

// Writes through the output writer (voxfield/core/output.hpp): a temporary file beside a
// regular or new target, renamed on success, so a failure never leaves a partial file (not
// forced to disk: no fsync, as numpy.save); a character device or FIFO written directly.
// InputError for a target refused, OutputError when the write fails. `data` may be any
// memory, e.g. a mapped device buffer: it is written from where it is, without a copy.
void write_npy(const std::filesystem::path& path, NpyType type, Dims dims,
               std::span<const std::uint8_t> data);
// The same, into `batch`: on disk once the caller commits it with the command's other outputs.
void write_npy(OutputBatch& batch, const std::filesystem::path& path, NpyType type, Dims dims,
               std::span<const std::uint8_t> data);
void write_npy(const std::filesystem::path& path, NpyType type, Dims dims,
               const std::vector<std::uint8_t>& data);

// Writes an array of any shape (C order, `data` little-endian), atomically as write_npy.
void write_npy_shape(const std::filesystem::path& path, NpyType type,
                     const std::vector<std::uint64_t>& shape, std::span<const std::uint8_t> data);
void write_npy_shape(const std::filesystem::path& path, NpyType type,
                     const std::vector<std::uint64_t>& shape,
                     const std::vector<std::uint8_t>& data);
void write_npy_shape(OutputBatch& batch, const std::filesystem::path& path, NpyType type,
                     const std::vector<std::uint64_t>& shape, std::span<const std::uint8_t> data);
// The same with the data made piece by piece (OutputBatch's streaming write): `produce` hands
// the pieces, in order, to its sink; std::logic_error when they do not add up to the shape.
void write_npy_shape(OutputBatch& batch, const std::filesystem::path& path, NpyType type,
                     const std::vector<std::uint64_t>& shape,
                     const std::function<void(const OutputBatch::Sink&)>& produce);

// How a label volume's values become a world's voxels (DESIGN §3). Any integer or bool array
// is a world: 0 is empty, every other value solid, and values 1..255 stay the voxel's palette
// index. `solid`: every other nonzero value (negative, or above 255) becomes a solid voxel of
// palette index 1 (the distance does not depend on it). `palette`: the caller needs palette
// values (packed32 fields, rendering, .vox), and such a value is an InputError naming the
// voxel.
enum class Labels { solid, palette };

// A world from a .npy array of bool or any integer type; InputError for other types.
World world_from_npy(const NpyArray& array, Labels labels = Labels::solid);
// The same from `dims.count()` C-order little-endian elements of `type` in memory.
World world_from_labels(NpyType type, Dims dims, std::span<const std::uint8_t> data,
                        Labels labels = Labels::solid);
NpyArray npy_from_world(const World& world);

}  // namespace voxfield
