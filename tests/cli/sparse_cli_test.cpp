// `voxfield generate --sparse` end to end: the same .npy as the dense bounded field, the
// default bound of 16, and what sparse worlds refuse (exit 2, no output).
#include <random>

#include "cli_test_util.hpp"
#include "voxfield/core/npy.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield {
namespace {

using test::read_bytes;
using test::run_voxfield;

class SparseCli : public ::testing::Test {
  protected:
    void SetUp() override {
        dir_ = test::make_temp_dir("voxfield_sparse_cli");
        World w(Dims{130, 40, 70});
        std::mt19937 rng(31);
        for (int b = 0; b < 12; ++b) {
            const auto x = static_cast<std::uint32_t>(rng() % 126);
            const auto y = static_cast<std::uint32_t>(rng() % 36);
            const auto z = static_cast<std::uint32_t>(rng() % 66);
            for (std::uint32_t dz = 0; dz < 4; ++dz) {
                for (std::uint32_t dy = 0; dy < 4; ++dy) {
                    for (std::uint32_t dx = 0; dx < 4; ++dx) {
                        w.set(x + dx, y + dy, z + dz, static_cast<std::uint8_t>(1 + b));
                    }
                }
            }
        }
        world_ = dir_ / "world.npy";
        write_npy(world_, NpyType::u8, w.dims(), w.voxels());
    }
    void TearDown() override { std::filesystem::remove_all(dir_); }
    test::RunResult run(const std::vector<std::string>& args) { return run_voxfield(args, dir_); }

    std::filesystem::path dir_, world_;
};

TEST_F(SparseCli, WritesTheDenseBoundedField) {
    const std::vector<std::vector<std::string>> flag_sets = {
        {"--metric", "chebyshev", "--signed", "--format", "i16", "--max-distance", "6"},
        {"--metric", "euclidean", "--max-distance", "9.5"},
        {"--format", "packed32", "--max-distance", "12"}};
    for (const auto& flags : flag_sets) {
        const auto sparse = dir_ / "sparse.npy";
        const auto dense = dir_ / "dense.npy";
        std::vector<std::string> a = {"generate", world_.string(), "-o", sparse.string(),
                                      "--sparse", "--device",      "cpu"};
        a.insert(a.end(), flags.begin(), flags.end());
        const auto r = run(a);
        ASSERT_EQ(r.code, 0) << test::describe(r);
        EXPECT_NE(r.out.find("tiles of 64^3 stored"), std::string::npos) << r.out;
        std::vector<std::string> b = {"generate",     world_.string(), "-o",
                                      dense.string(), "--device",      "cpu"};
        b.insert(b.end(), flags.begin(), flags.end());
        const auto rd = run(b);
        ASSERT_EQ(rd.code, 0) << test::describe(rd);
        EXPECT_EQ(read_bytes(sparse), read_bytes(dense)) << flags[1];
    }
}

TEST_F(SparseCli, BoundsAt16ByDefault) {
    const auto sparse = dir_ / "sparse.npy";
    const auto dense = dir_ / "dense.npy";
    ASSERT_EQ(
        run({"generate", world_.string(), "-o", sparse.string(), "--sparse", "--device", "cpu"})
            .code,
        0);
    ASSERT_EQ(run({"generate", world_.string(), "-o", dense.string(), "--max-distance", "16",
                   "--device", "cpu"})
                  .code,
              0);
    EXPECT_EQ(read_bytes(sparse), read_bytes(dense));
}

TEST_F(SparseCli, RefusesIndicesAndOtherAlgorithms) {
    const auto out = dir_ / "out.npy";
    for (const auto& extra : std::vector<std::vector<std::string>>{
             {"--indices", (dir_ / "idx.npy").string()}, {"--algorithm", "jfa"}}) {
        std::vector<std::string> a = {"generate", world_.string(), "-o", out.string(),
                                      "--sparse", "--device",      "cpu"};
        a.insert(a.end(), extra.begin(), extra.end());
        const auto r = run(a);
        EXPECT_EQ(r.code, 2) << test::describe(r);
        EXPECT_NE(r.err.find("sparse worlds"), std::string::npos) << r.err;
        EXPECT_FALSE(std::filesystem::exists(out));
    }
}

}  // namespace
}  // namespace voxfield
