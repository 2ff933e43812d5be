// The default camera's front (solid_framing): the side with the most visible detail, so that a
// model whose face is not MagicaVoxel's front (scene_store8's shop front faces vox +y, our +z)
// is first seen from its face, not its blank back wall.
#include <gtest/gtest.h>

#include "voxfield/core/camera.hpp"
#include "voxfield/core/vox.hpp"

namespace voxfield {
namespace {

// A 10x8x6 box of material 1 inside a 12x10x8 world.
World plain_box() {
    World w(Dims{12, 10, 8});
    for (std::uint32_t z = 1; z < 7; ++z) {
        for (std::uint32_t y = 1; y < 9; ++y) {
            for (std::uint32_t x = 1; x < 11; ++x) {
                w.set(x, y, z, 1);
            }
        }
    }
    return w;
}

TEST(Framing, APlainBoxKeepsTheMagicaVoxelFront) {
    const Framing f = solid_framing(plain_box());
    EXPECT_EQ(f.front, (Vec3d{0, 0, -1}));
    const Vec3d eye = framing_position(f, 60, 4.0 / 3.0);
    EXPECT_LT(eye[0], f.centre[0]);  // front-left
    EXPECT_GT(eye[1], f.centre[1]);  // above
    EXPECT_LT(eye[2], f.centre[2]);  // in front of -z
}

TEST(Framing, TheSideWithTheMostDetailIsTheFront) {
    const Vec3d sides[] = {{0, 0, 1}, {-1, 0, 0}, {1, 0, 0}, {0, 0, -1}};
    for (const Vec3d& n : sides) {
        World w = plain_box();
        // Windows of other colours on the side facing n.
        for (std::uint32_t a = 2; a < 6; a += 2) {
            for (std::uint32_t y = 2; y < 8; y += 2) {
                const std::uint32_t x = n[0] < 0 ? 1 : n[0] > 0 ? 10 : a + 2;
                const std::uint32_t z = n[2] < 0 ? 1 : n[2] > 0 ? 6 : a;
                w.set(x, y, z, 5);
            }
        }
        const Framing f = solid_framing(w);
        EXPECT_EQ(f.front, n) << n[0] << "," << n[2];
        const Vec3d eye = framing_position(f, 60, 4.0 / 3.0);
        // The camera stands on that side: its offset from the centre points the same way.
        const double along = (eye[0] - f.centre[0]) * n[0] + (eye[2] - f.centre[2]) * n[2];
        EXPECT_GT(along, 0) << n[0] << "," << n[2];
    }
}

TEST(Framing, TheStoreIsSeenFromItsShopFront) {
    const VoxModel m = load_world(std::string(VOXFIELD_DATA_DIR) + "/vox/scene_store8.vox");
    EXPECT_EQ(solid_framing(m.world).front, (Vec3d{0, 0, 1}));
}

}  // namespace
}  // namespace voxfield
