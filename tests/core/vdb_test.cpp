// .vdb in and out: fields written with write_vdb read back with OpenVDB's own API and compared
// voxel by voxel; grids built with OpenVDB read by read_vdb against the DESIGN §3 rules applied
// here voxel by voxel; unusable files.
#include <gtest/gtest.h>

#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "test_util.hpp"
#include "voxfield/core/format.hpp"
#include "voxfield/core/reference.hpp"
#include "voxfield/core/scenes.hpp"
#include "voxfield/core/vdb.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield {
namespace {

namespace fs = std::filesystem;
using test::expect_input_error;
using test::TempDir;

const fs::path kData = fs::path(VOXFIELD_DATA_DIR) / "vox";

openvdb::GridPtrVecPtr read_all(const fs::path& p) {
    openvdb::initialize();
    openvdb::io::File f(p.string());
    f.open(false);
    auto grids = f.getGrids();
    f.close();
    return grids;
}

// io::File writes the grids sorted by name; io::Stream in the order given.
void write_grids(const fs::path& p, const openvdb::GridPtrVec& grids) {
    openvdb::initialize();
    openvdb::io::File f(p.string());
    f.write(grids);
    f.close();
}

void stream_grids(const fs::path& p, const openvdb::GridPtrVec& grids) {
    openvdb::initialize();
    std::ofstream out(p, std::ios::binary);
    openvdb::io::Stream(out).write(grids);
}

struct Case {
    Metric metric;
    Spacing spacing;
    bool signed_field;
    Format format;
    double bound;
};

// World + field -> write_vdb -> OpenVDB reads: grid order, names, classes, voxel size,
// background, and per voxel the active state and value the contract gives.
void check_round_trip(const World& w, const Case& c, const fs::path& p) {
    const std::vector<double> real = c.signed_field ? reference_signed(w, c.metric, c.spacing)
                                                    : reference_distance(w, c.metric, c.spacing);
    const std::vector<std::uint8_t> field = encode_real_field(real, w, Palette(), c.format);
    const VdbFieldSpec spec{c.spacing.x, c.bound, c.signed_field};
    write_vdb(p, w.dims(), w.voxels(), field, c.format, spec);
    const auto grids = read_all(p);
    ASSERT_EQ(grids->size(), 2u);
    EXPECT_EQ((*grids)[0]->getName(), "material");
    EXPECT_EQ((*grids)[1]->getName(), "distance");
    const auto mat = openvdb::gridPtrCast<openvdb::Int32Grid>((*grids)[0]);
    const auto dist = openvdb::gridPtrCast<openvdb::FloatGrid>((*grids)[1]);
    ASSERT_TRUE(mat && dist);
    EXPECT_EQ(dist->getGridClass(),
              c.signed_field ? openvdb::GRID_LEVEL_SET : openvdb::GRID_UNKNOWN);
    EXPECT_EQ(dist->background(), static_cast<float>(c.bound));
    EXPECT_EQ(mat->background(), 0);
    EXPECT_DOUBLE_EQ(dist->voxelSize()[0], c.spacing.x);
    EXPECT_DOUBLE_EQ(dist->voxelSize()[2], c.spacing.x);
    EXPECT_DOUBLE_EQ(mat->voxelSize()[1], c.spacing.x);
    const Dims d = w.dims();
    std::size_t wrong_mat = 0, wrong_dist = 0, active = 0;
    auto ma = mat->getConstAccessor();
    auto da = dist->getConstAccessor();
    for (std::uint32_t z = 0; z < d.z; ++z) {
        for (std::uint32_t y = 0; y < d.y; ++y) {
            for (std::uint32_t x = 0; x < d.x; ++x) {
                const openvdb::Coord ijk(static_cast<int>(x), static_cast<int>(y),
                                         static_cast<int>(z));
                const std::uint8_t v = w.at(x, y, z);
                wrong_mat += ma.isValueOn(ijk) != (v != 0) || ma.getValue(ijk) != v;
                const double e = decode_value(field, c.format, d.index(x, y, z));
                const bool on = std::fabs(e) < c.bound;
                active += on;
                const float want =
                    on ? static_cast<float>(e) : static_cast<float>(e < 0 ? -c.bound : c.bound);
                wrong_dist += da.isValueOn(ijk) != on || da.getValue(ijk) != want;
            }
        }
    }
    EXPECT_EQ(wrong_mat, 0u);
    EXPECT_EQ(wrong_dist, 0u);
    EXPECT_EQ(dist->activeVoxelCount(), active);
    EXPECT_EQ(mat->activeVoxelCount(), w.solid_count());
    // Nothing outside the world is active.
    EXPECT_TRUE(dist->evalActiveVoxelBoundingBox().empty() ||
                openvdb::CoordBBox(openvdb::Coord(0), openvdb::Coord(d.x - 1, d.y - 1, d.z - 1))
                    .isInside(dist->evalActiveVoxelBoundingBox()));
}

TEST(Vdb, FieldsRoundTripThroughOpenVdb) {
    TempDir dir;
    const std::vector<Case> cases = {
        {Metric::manhattan, {1, 1, 1}, false, Format::u16, 16},
        {Metric::manhattan, {1, 1, 1}, false, Format::u8, 5},
        {Metric::chebyshev, {1, 1, 1}, false, Format::u32, 3.5},
        {Metric::euclidean, {1, 1, 1}, false, Format::f32, 6},
        {Metric::euclidean, {0.5, 0.5, 0.5}, false, Format::f64, 2.25},
        {Metric::euclidean, {1, 1, 1}, true, Format::f32, 4},
        {Metric::manhattan, {2, 2, 2}, true, Format::i16, 6},
        {Metric::chebyshev, {1, 1, 1}, true, Format::i8, 2},
        {Metric::manhattan, {1, 1, 1}, false, Format::packed32, 9},
    };
    std::mt19937_64 rng(77);
    for (std::size_t k = 0; k < cases.size(); ++k) {
        SCOPED_TRACE(k);
        // Awkward sizes, big solid blocks (deep interiors for the level sets) and noise.
        const Dims d{static_cast<std::uint32_t>(9 + rng() % 20),
                     static_cast<std::uint32_t>(5 + rng() % 20),
                     static_cast<std::uint32_t>(7 + rng() % 20)};
        World w = make_scene("spheres", d, rng());
        for (int n = 0; n < 30; ++n) {
            w.set(static_cast<std::uint32_t>(rng() % d.x), static_cast<std::uint32_t>(rng() % d.y),
                  static_cast<std::uint32_t>(rng() % d.z),
                  static_cast<std::uint8_t>(1 + rng() % 255));
        }
        check_round_trip(w, cases[k], dir / ("f" + std::to_string(k) + ".vdb"));
    }
    // An empty world (every distance infinite) and a shipped model.
    check_round_trip(World(Dims{4, 5, 6}), cases[3], dir / "empty.vdb");
    const VoxModel army = read_vox(kData / "chr_army1.vox");
    check_round_trip(army.world, cases[5], dir / "army.vdb");
}

// The solid bounding box of a world, as a cropped copy.
World crop_to(const World& w, const Dims& lo, const Dims& n) {
    World out(n);
    for (std::uint32_t z = 0; z < n.z; ++z) {
        for (std::uint32_t y = 0; y < n.y; ++y) {
            for (std::uint32_t x = 0; x < n.x; ++x) {
                out.set(x, y, z, w.at(x + lo.x, y + lo.y, z + lo.z));
            }
        }
    }
    return out;
}

// Two files' grids agree: names, classes, active voxel counts, and every value and its state
// over `d` and one voxel around it (a file holds a random UUID, so bytes always differ).
template <typename G>
void expect_same_grid(const openvdb::GridBase::Ptr& a, const openvdb::GridBase::Ptr& b, Dims d) {
    const auto ga = openvdb::gridPtrCast<G>(a), gb = openvdb::gridPtrCast<G>(b);
    ASSERT_TRUE(ga && gb);
    EXPECT_EQ(ga->getName(), gb->getName());
    EXPECT_EQ(ga->getGridClass(), gb->getGridClass());
    EXPECT_EQ(ga->activeVoxelCount(), gb->activeVoxelCount());
    auto aa = ga->getConstAccessor();
    auto ab = gb->getConstAccessor();
    std::size_t differ = 0;
    for (int z = -1; z <= static_cast<int>(d.z); ++z) {
        for (int y = -1; y <= static_cast<int>(d.y); ++y) {
            for (int x = -1; x <= static_cast<int>(d.x); ++x) {
                const openvdb::Coord c(x, y, z);
                differ += aa.getValue(c) != ab.getValue(c) || aa.isValueOn(c) != ab.isValueOn(c);
            }
        }
    }
    EXPECT_EQ(differ, 0u);
}

// The box-wise writer (sparse worlds, tile by tile) writes the same file as the dense one when
// the boxes tile the world, in any order.
TEST(Vdb, BoxWiseWriterEqualsTheDenseOne) {
    TempDir dir;
    std::mt19937_64 rng(31);
    for (const Case& c : {Case{Metric::euclidean, {1, 1, 1}, true, Format::f32, 4},
                          Case{Metric::manhattan, {1, 1, 1}, false, Format::u16, 5}}) {
        const Dims d{37, 21, 29};
        World w = make_scene("spheres", d, rng());
        const std::vector<double> real = c.signed_field
                                             ? reference_signed(w, c.metric, c.spacing)
                                             : reference_distance(w, c.metric, c.spacing);
        std::vector<double> bounded(real);
        for (double& v : bounded) {
            v = std::clamp(v, -c.bound, c.bound);
        }
        const auto field = encode_real_field(bounded, w, Palette(), c.format);
        const VdbFieldSpec spec{1, c.bound, c.signed_field};
        write_vdb(dir / "dense.vdb", d, w.voxels(), field, c.format, spec);
        // Boxes of 8^3 (cut by the world's edge), in reverse order.
        const std::size_t es = element_size(c.format);
        std::vector<Box> boxes;
        for (std::int64_t z = 0; z < d.z; z += 8) {
            for (std::int64_t y = 0; y < d.y; y += 8) {
                for (std::int64_t x = 0; x < d.x; x += 8) {
                    boxes.push_back(
                        {{x, y, z},
                         {std::min<std::int64_t>(x + 8, d.x), std::min<std::int64_t>(y + 8, d.y),
                          std::min<std::int64_t>(z + 8, d.z)}});
                }
            }
        }
        std::reverse(boxes.begin(), boxes.end());
        std::vector<std::uint8_t> voxels, values;
        std::size_t next = 0;
        OutputBatch batch;
        write_vdb(
            batch, dir / "boxes.vdb",
            [&](VdbBox& b) {
                if (next == boxes.size()) {
                    return false;
                }
                const Box& box = boxes[next++];
                voxels.clear();
                values.clear();
                for (std::int64_t z = box.min.z; z < box.max.z; ++z) {
                    for (std::int64_t y = box.min.y; y < box.max.y; ++y) {
                        for (std::int64_t x = box.min.x; x < box.max.x; ++x) {
                            const std::size_t i = d.index(static_cast<std::uint32_t>(x),
                                                          static_cast<std::uint32_t>(y),
                                                          static_cast<std::uint32_t>(z));
                            voxels.push_back(w.voxels()[i]);
                            values.insert(values.end(), field.begin() + static_cast<long>(i * es),
                                          field.begin() + static_cast<long>((i + 1) * es));
                        }
                    }
                }
                b = VdbBox{box, voxels, values};
                return true;
            },
            c.format, spec);
        batch.commit();
        const auto want = read_all(dir / "dense.vdb");
        const auto got = read_all(dir / "boxes.vdb");
        ASSERT_EQ(got->size(), 2u);
        ASSERT_EQ(want->size(), 2u);
        expect_same_grid<openvdb::Int32Grid>((*got)[0], (*want)[0], d);
        expect_same_grid<openvdb::FloatGrid>((*got)[1], (*want)[1], d);
    }
}

// A grid's extent and its sparse reading (no dense world) against the dense reading.
TEST(Vdb, SparseReadingEqualsTheDenseOne) {
    TempDir dir;
    const VoxModel car = read_vox(kData / "veh_car1.vox");
    const World& w = car.world;
    const std::vector<double> real = reference_signed(w, Metric::euclidean, Spacing{});
    const auto field = encode_real_field(real, w, Palette(), Format::f32);
    write_vdb(dir / "car.vdb", w.dims(), w.voxels(), field, Format::f32, {1, 3, true});
    for (const std::string grid : {"material", "distance"}) {
        SCOPED_TRACE(grid);
        const World dense = read_vdb(dir / "car.vdb", grid).world;
        EXPECT_EQ(vdb_extent(dir / "car.vdb", grid), dense.dims());
        const SparseWorld sparse = read_vdb_sparse(dir / "car.vdb", grid);
        ASSERT_EQ(sparse.dims(), dense.dims());
        EXPECT_EQ(sparse.to_dense().voxels(), dense.voxels());
    }
}

TEST(Vdb, OurOutputReadsBackAsTheWorld) {
    TempDir dir;
    const VoxModel car = read_vox(kData / "veh_car1.vox");
    const World& w = car.world;
    const std::vector<double> real = reference_signed(w, Metric::euclidean, Spacing{});
    const auto field = encode_real_field(real, w, Palette(), Format::f32);
    write_vdb(dir / "car.vdb", w.dims(), w.voxels(), field, Format::f32, {1, 3, true});
    // First grid = material: the solid voxels, origin at their bounding box.
    Dims lo{~0u, ~0u, ~0u}, hi{0, 0, 0};
    for (std::uint32_t z = 0; z < w.dims().z; ++z) {
        for (std::uint32_t y = 0; y < w.dims().y; ++y) {
            for (std::uint32_t x = 0; x < w.dims().x; ++x) {
                if (w.at(x, y, z) != 0) {
                    lo = {std::min(lo.x, x), std::min(lo.y, y), std::min(lo.z, z)};
                    hi = {std::max(hi.x, x), std::max(hi.y, y), std::max(hi.z, z)};
                }
            }
        }
    }
    const World solid_box = crop_to(w, lo, {hi.x - lo.x + 1, hi.y - lo.y + 1, hi.z - lo.z + 1});
    const VoxModel first = read_vdb(dir / "car.vdb", "");
    EXPECT_EQ(first.world.dims(), solid_box.dims());
    EXPECT_EQ(first.world.voxels(), solid_box.voxels());
    EXPECT_EQ(read_vdb(dir / "car.vdb", "material").world.voxels(), solid_box.voxels());
    // The level set: its interior is exactly the solid voxels (material 1).
    const VoxModel ls = read_vdb(dir / "car.vdb", "distance");
    EXPECT_EQ(ls.world.solid_count(), w.solid_count());
    // By extension too, and described without a dense world.
    EXPECT_EQ(load_world(dir / "car.vdb", InputOptions{"material"}).world.voxels(),
              solid_box.voxels());
    const WorldInfo info = describe_input(dir / "car.vdb", InputOptions{"distance"}, 16);
    EXPECT_EQ(info.kind, "vdb");
    EXPECT_EQ(info.grid, "distance");
    EXPECT_EQ(info.grid_class, "level set");
    EXPECT_EQ(info.solid, w.solid_count());
}

// read_vdb against the rule applied voxel by voxel with OpenVDB's accessor.
void expect_read_matches(const fs::path& p, const std::string& name, bool level_set) {
    const auto grids = read_all(p);
    openvdb::GridBase::Ptr g;
    for (const auto& x : *grids) {
        if (x->getName() == name) {
            g = x;
        }
    }
    ASSERT_TRUE(g);
    const openvdb::CoordBBox box = g->evalActiveVoxelBoundingBox();
    const VoxModel m = read_vdb(p, name);
    ASSERT_EQ(m.world.dims(), (Dims{static_cast<std::uint32_t>(box.dim().x()),
                                    static_cast<std::uint32_t>(box.dim().y()),
                                    static_cast<std::uint32_t>(box.dim().z())}));
    std::size_t wrong = 0;
    for (auto it = box.begin(); it; ++it) {
        const openvdb::Coord c = *it;
        std::uint8_t want = 0;
        if (level_set) {
            const auto fg = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
            want = fg->tree().getValue(c) < 0 ? 1 : 0;
        } else if (const auto ig = openvdb::gridPtrCast<openvdb::Int32Grid>(g)) {
            want = ig->tree().isValueOn(c) ? static_cast<std::uint8_t>(ig->tree().getValue(c)) : 0;
        } else if (const auto fg = openvdb::gridPtrCast<openvdb::FloatGrid>(g)) {
            want = fg->tree().isValueOn(c) && fg->tree().getValue(c) != 0 ? 1 : 0;
        }
        const Dims o{static_cast<std::uint32_t>(c.x() - box.min().x()),
                     static_cast<std::uint32_t>(c.y() - box.min().y()),
                     static_cast<std::uint32_t>(c.z() - box.min().z())};
        wrong += m.world.at(o.x, o.y, o.z) != want;
    }
    EXPECT_EQ(wrong, 0u) << name;
}

TEST(Vdb, ReadsGridsOfOtherTools) {
    TempDir dir;
    openvdb::initialize();
    // A level set sphere (OpenVDB's own tool): inactive interior tiles are solid too.
    auto sphere = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(
        20.0f, openvdb::Vec3f(3.5f, -7.0f, 40.25f), 1.0f, 3.0f);
    sphere->setName("sphere");
    // An integer grid with voxels and an active tile (materials), negative coordinates.
    auto labels = openvdb::Int32Grid::create(0);
    labels->setName("labels");
    labels->tree().setValue(openvdb::Coord(-5, 2, 9), 7);
    labels->tree().setValue(openvdb::Coord(30, -4, 0), 255);
    labels->tree().setValueOn(openvdb::Coord(1, 1, 1), 0);        // active but zero: empty
    labels->tree().addTile(1, openvdb::Coord(8, 8, 8), 3, true);  // an 8^3 tile of 3
    // A fog volume: active nonzero values solid (material 1).
    auto fog = openvdb::FloatGrid::create(0.0f);
    fog->setName("fog");
    fog->setGridClass(openvdb::GRID_FOG_VOLUME);
    std::mt19937_64 rng(3);
    for (int k = 0; k < 500; ++k) {
        fog->tree().setValue(
            openvdb::Coord(static_cast<int>(rng() % 40), static_cast<int>(rng() % 30) - 15,
                           static_cast<int>(rng() % 20)),
            k % 5 == 0 ? 0.0f : 0.25f * static_cast<float>(k));
    }
    stream_grids(dir / "tools.vdb", {labels, sphere, fog});
    write_grids(dir / "sorted.vdb", {labels, sphere, fog});
    expect_read_matches(dir / "tools.vdb", "labels", false);
    expect_read_matches(dir / "tools.vdb", "sphere", true);
    expect_read_matches(dir / "tools.vdb", "fog", false);
    expect_read_matches(dir / "sorted.vdb", "sphere", true);
    // The first grid in the file by default: as written by io::Stream, by name for io::File.
    EXPECT_EQ(read_vdb(dir / "tools.vdb", "").world.voxels(),
              read_vdb(dir / "tools.vdb", "labels").world.voxels());
    EXPECT_EQ(read_vdb(dir / "sorted.vdb", "").world.voxels(),
              read_vdb(dir / "sorted.vdb", "fog").world.voxels());
    // The sphere's deep interior (inactive tiles) is solid.
    const World s = read_vdb(dir / "tools.vdb", "sphere").world;
    EXPECT_EQ(s.at(s.dims().x / 2, s.dims().y / 2, s.dims().z / 2), 1);
    EXPECT_EQ(describe_vdb(dir / "tools.vdb", "sphere", 16).solid, s.solid_count());
    EXPECT_EQ(read_vdb(dir / "tools.vdb", "labels").world.at(13, 12, 8), 3);  // in the tile
}

TEST(Vdb, UnusableFilesAreOneLineErrors) {
    TempDir dir;
    openvdb::initialize();
    test::write_text(dir / "text.vdb", "not a vdb file\n");
    expect_input_error([&] { read_vdb(dir / "text.vdb", ""); },
                       {"text.vdb", "not a readable OpenVDB file"});
    expect_input_error([&] { read_vdb(dir / "none.vdb", ""); }, {"none.vdb", "no such file"});
    // A truncated copy of a good file, cut at several places.
    World w(Dims{20, 20, 20});
    w.set(3, 4, 5, 9);
    const std::vector<std::uint8_t> field(w.size() * 4, 0);
    write_vdb(dir / "good.vdb", w.dims(), w.voxels(), field, Format::f32, {});
    const auto good = test::read_bytes(dir / "good.vdb");
    for (const std::size_t cut :
         {std::size_t{0}, std::size_t{8}, good.size() / 3, good.size() / 2, good.size() - 9}) {
        SCOPED_TRACE(cut);
        test::write_bytes(
            dir / "cut.vdb",
            std::vector<std::uint8_t>(good.begin(), good.begin() + static_cast<long>(cut)));
        expect_input_error([&] { read_vdb(dir / "cut.vdb", ""); }, {"cut.vdb"});
    }
    write_grids(dir / "nogrids.vdb", {});
    expect_input_error([&] { read_vdb(dir / "nogrids.vdb", ""); }, {"nogrids.vdb", "no grid"});
    expect_input_error([&] { read_vdb(dir / "good.vdb", "density"); },
                       {"no grid named 'density'", "'material', 'distance'"});
    auto empty = openvdb::FloatGrid::create(1.0f);
    empty->setName("empty");
    write_grids(dir / "empty.vdb", {empty});
    expect_input_error([&] { read_vdb(dir / "empty.vdb", ""); },
                       {"grid 'empty'", "no active voxels"});
    // Integer values outside 1..255 are solid with material 1, as in label volumes.
    auto wide_labels = openvdb::Int64Grid::create(0);
    wide_labels->setName("labels");
    wide_labels->tree().setValue(openvdb::Coord(1, 2, 3), 300);
    wide_labels->tree().setValue(openvdb::Coord(2, 2, 3), -4);
    wide_labels->tree().setValue(openvdb::Coord(3, 2, 3), 200);
    write_grids(dir / "labels.vdb", {wide_labels});
    EXPECT_EQ(read_vdb(dir / "labels.vdb", "").world.voxels(),
              (std::vector<std::uint8_t>{1, 1, 200}));
    auto wide = openvdb::BoolGrid::create(false);
    wide->setName("wide");
    wide->tree().setValue(openvdb::Coord(0, 0, 0), true);
    wide->tree().setValue(openvdb::Coord(1 << 21, 0, 0), true);
    write_grids(dir / "wide.vdb", {wide});
    expect_input_error([&] { read_vdb(dir / "wide.vdb", ""); },
                       {"over the limit of 1048576 per axis"});
    // Voxels 2^31 or more apart, whose extent wraps around in OpenVDB's 32-bit Coord (it read
    // as 3000000001 or as 0 voxels: then `info` allocated until it ran out of memory).
    for (const auto& [lo, hi] : {std::pair{-1500000000, 1500000000},
                                 std::pair{std::numeric_limits<openvdb::Int32>::min(),
                                           std::numeric_limits<openvdb::Int32>::max()}}) {
        auto wrap = openvdb::FloatGrid::create(0.0f);
        wrap->setName("wrap");
        wrap->tree().setValue(openvdb::Coord(lo, 0, 0), 1.0f);
        wrap->tree().setValue(openvdb::Coord(hi, 0, 0), 1.0f);
        write_grids(dir / "wrap.vdb", {wrap});
        expect_input_error([&] { read_vdb(dir / "wrap.vdb", ""); },
                           {"wrap.vdb", "over the limit of 1048576 per axis"});
        expect_input_error([&] { describe_input(dir / "wrap.vdb", InputOptions{}, 16); },
                           {"wrap.vdb", "over the limit of 1048576 per axis"});
    }
    // Output: non-uniform spacing is refused; other extensions are not .vdb.
    expect_input_error(
        [&] {
            vdb_output_spec(dir / "o.vdb", Spacing{1, 2, 1}, std::nullopt, false);
        },
        {"o.vdb", "1,2,1", "same on every axis"});
    EXPECT_FALSE(vdb_output_spec(dir / "o.npy", Spacing{1, 2, 1}, std::nullopt, false));
    const auto spec = vdb_output_spec(dir / "O.VDB", Spacing{0.5, 0.5, 0.5}, 3.0, true);
    ASSERT_TRUE(spec);
    EXPECT_EQ(spec->voxel_size, 0.5);
    EXPECT_EQ(spec->background, 3.0);
    EXPECT_TRUE(spec->level_set);
    EXPECT_EQ(vdb_output_spec(dir / "o.vdb", Spacing{}, std::nullopt, false)->background, 16.0);
}

}  // namespace
}  // namespace voxfield
