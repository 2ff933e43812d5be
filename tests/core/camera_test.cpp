#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "voxfield/core/camera.hpp"
#include "voxfield/core/error.hpp"

namespace voxfield {
namespace {

void expect_near(const Vec3d& a, const Vec3d& b, double eps = 1e-9) {
    for (int i = 0; i < 3; ++i) {
        EXPECT_NEAR(a[i], b[i], eps) << "component " << i;
    }
}

double length(const Vec3d& a) {
    return std::sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]);
}

Vec3d sub(const Vec3d& a, const Vec3d& b) {
    return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}

TEST(Camera, AnglesFollowTheConvention) {
    expect_near(direction_from_angles(0, 0), {1, 0, 0});
    expect_near(direction_from_angles(90, 0), {0, 0, 1});
    expect_near(direction_from_angles(0, 90), {0, 1, 0});
    expect_near(direction_from_angles(180, -45), {-std::sqrt(0.5), -std::sqrt(0.5), 0});
}

TEST(Camera, BasisFollowsTheDesignFormula) {
    // DESIGN §4: right = cross(forward, +y), up = cross(right, forward). That the ray marcher
    // hands its shader exactly this basis (image_basis below) is checked where the renderer is
    // linked: tests/vk march_params_test, MarchParams.PushConstantsCarryCoresImageBasis.
    ViewBasis b = view_basis({0, 0, 2});
    expect_near(b.forward, {0, 0, 1});
    expect_near(b.right, {-1, 0, 0});
    expect_near(b.up, {0, 1, 0});
    b = view_basis({1, 0, 0});
    expect_near(b.right, {0, 0, 1});
    b = view_basis({0, -3, 0});  // straight down: right is +x
    expect_near(b.right, {1, 0, 0});
    expect_near(b.up, {0, 0, -1});
}

TEST(Camera, ImageBasisScalesTheViewBasis) {
    // right by aspect * tan(fov/2), up by tan(fov/2), forward unit: what the shader gets.
    const Vec3d f = {0.3, -0.5, 0.8};
    const ViewBasis v = view_basis(f);
    const ImageBasis b = image_basis(f, 70, 800, 600);
    const double t = std::tan(35 * M_PI / 180);
    expect_near(b.forward, v.forward);
    expect_near(b.right, {v.right[0] * 4 / 3 * t, v.right[1] * 4 / 3 * t, v.right[2] * 4 / 3 * t});
    expect_near(b.up, {v.up[0] * t, v.up[1] * t, v.up[2] * t});
    EXPECT_NEAR(length(b.forward), 1, 1e-12);
}

TEST(Camera, PixelDirectionsFollowDesign) {
    const Vec3d f = {0, 0, 1};
    // The centre of the image looks straight ahead.
    expect_near(pixel_direction(f, 60, 800, 600, 400, 300), f);
    // The top-left corner: sx = -1 (scaled by aspect * tan 30), sy = +1 (tan 30).
    const double t = std::tan(M_PI / 6);
    Vec3d d = pixel_direction(f, 60, 800, 600, 0, 0);
    const Vec3d want = {-(-1 * 800.0 / 600.0 * t), t, 1};  // right is -x
    const double n = length(want);
    expect_near(d, {want[0] / n, want[1] / n, want[2] / n});
    // Pixel (i, j)'s centre as the renderer samples it.
    d = pixel_direction(f, 90, 4, 2, 3.5, 0.5);
    const double sx = (3.5 / 4 * 2 - 1) * 2, sy = 1 - 0.5 / 2 * 2;
    const Vec3d w2 = {-sx, sy, 1};
    const double n2 = length(w2);
    expect_near(d, {w2[0] / n2, w2[1] / n2, w2[2] / n2});
}

TEST(Camera, ProjectPointInvertsPixelDirection) {
    const Vec3d eye = {3, -2, 7};
    for (const Vec3d& f :
         {Vec3d{0, 0, 1}, Vec3d{0.3, -0.5, 0.8}, Vec3d{0, 1, 0}, Vec3d{-1, 0.2, 0}}) {
        for (const auto& [px, py] : {std::pair{0.0, 0.0}, std::pair{400.0, 300.0},
                                     std::pair{799.5, 12.25}, std::pair{-50.0, 700.0}}) {
            const Vec3d d = pixel_direction(f, 70, 800, 600, px, py);
            const Vec3d p = {eye[0] + 9 * d[0], eye[1] + 9 * d[1], eye[2] + 9 * d[2]};
            const auto ip = project_point(eye, f, 70, 800, 600, p);
            ASSERT_TRUE(ip.has_value());
            EXPECT_NEAR(ip->x, px, 1e-9);
            EXPECT_NEAR(ip->y, py, 1e-9);
        }
        // Behind the eye and on its image plane: not visible.
        const double n = length(f);
        EXPECT_FALSE(project_point(eye, f, 70, 800, 600,
                                   {eye[0] - f[0] / n, eye[1] - f[1] / n, eye[2] - f[2] / n}));
        EXPECT_FALSE(project_point(eye, f, 70, 800, 600, eye));
    }
}

TEST(Camera, ChunkAtClampsIntoTheGrid) {
    const Dims w{64, 40, 33};  // 16^3 chunks: 4 x 3 x 3 (edge chunks clipped)
    EXPECT_EQ(chunk_at({0, 0, 0}, w, 16), (Int3{0, 0, 0}));
    EXPECT_EQ(chunk_at({15.99, 16, 32.5}, w, 16), (Int3{0, 1, 2}));
    EXPECT_EQ(chunk_at({-100, 1e9, 20}, w, 16), (Int3{0, 2, 1}));
    EXPECT_EQ(chunk_at({64, 40, 33}, w, 16), (Int3{3, 2, 2}));
    EXPECT_EQ(chunk_at({NAN, 5, 5}, w, 8), (Int3{0, 0, 0}));
}

TEST(Camera, StartsAtTheRenderersOverview) {
    ViewCamera cam(Dims{64, 32, 48});
    const Vec3d c = {32, 16, 24};
    expect_near(cam.centre(), c);
    const Vec3d want = framing_position(world_framing(Dims{64, 32, 48}), 60, 4.0 / 3.0);
    expect_near(cam.position(), want, 1e-9);
    const Vec3d from = {-0.6, 0.5, -0.75};
    const Vec3d f = cam.forward();
    expect_near(f, {-from[0] / length(from), -from[1] / length(from), -from[2] / length(from)});
    EXPECT_EQ(cam.mode(), ViewCamera::Mode::fly);
}

TEST(Camera, FramesTheSolidVoxelsTightly) {
    World w(Dims{100, 60, 80});
    w.set(10, 5, 60, 1);
    w.set(30, 20, 70, 2);
    const Framing f = solid_framing(w);
    expect_near(f.centre, {20.5, 13, 65.5});
    expect_near(f.half, {10.5, 8, 5.5});
    EXPECT_EQ(solid_framing(World(Dims{4, 6, 8})).centre, (Vec3d{2, 3, 4}));  // no solid: all
    for (const double aspect : {0.5, 4.0 / 3.0, 2.5}) {
        const Vec3d eye = framing_position(f, 50, aspect);
        const Vec3d forward = sub(f.centre, eye);
        EXPECT_LT(eye[0], f.centre[0]);  // left of, above and in front of (-z) the box
        EXPECT_GT(eye[1], f.centre[1]);
        EXPECT_LT(eye[2], f.centre[2]);
        // Every corner inside the image, and one within a few percent of its edge.
        const double W = 1000 * aspect, H = 1000;
        double margin = 1e9;
        for (int k = 0; k < 8; ++k) {
            const Vec3d corner = {f.centre[0] + (k & 1 ? 1 : -1) * f.half[0],
                                  f.centre[1] + (k & 2 ? 1 : -1) * f.half[1],
                                  f.centre[2] + (k & 4 ? 1 : -1) * f.half[2]};
            const auto p = project_point(eye, forward, 50, W, H, corner);
            ASSERT_TRUE(p.has_value());
            EXPECT_GT(p->x, 0);
            EXPECT_LT(p->x, W);
            EXPECT_GT(p->y, 0);
            EXPECT_LT(p->y, H);
            margin = std::min({margin, p->x / W, 1 - p->x / W, p->y / H, 1 - p->y / H});
        }
        EXPECT_LT(margin, 0.06) << "aspect " << aspect << ": the box could be framed closer";
    }
    // The viewer starts at the same view and orbits the box's centre.
    const ViewCamera cam(w.dims(), f, 1.5);
    expect_near(cam.position(), framing_position(f, cam.settings.fov_deg, 1.5), 1e-9);
    expect_near(cam.centre(), f.centre);
}

TEST(Camera, DissertationStart) {
    ViewCamera cam(Dims{128, 128, 128});
    cam.dissertation_start();
    expect_near(cam.position(), {-128, 64, 64});
    expect_near(cam.forward(), {1, 0, 0});
}

TEST(Camera, MotionIsFrameRateIndependent) {
    ViewCamera a(Dims{16, 16, 16}), b(Dims{16, 16, 16});
    a.dissertation_start();
    b.dissertation_start();
    CameraInput in;
    in.forward = true;
    a.update(in, 1.0);
    for (int i = 0; i < 144; ++i) {
        b.update(in, 1.0 / 144);
    }
    expect_near(a.position(), {-16 + 10, 8, 8});  // base speed 10 voxels/s along +x
    expect_near(b.position(), a.position(), 1e-9);
    // Left Ctrl: x4.
    in.fast = true;
    a.update(in, 0.5);
    expect_near(a.position(), {-6 + 20, 8, 8});
}

TEST(Camera, KeysMoveAlongTheViewBasis) {
    ViewCamera cam(Dims{16, 16, 16});
    cam.dissertation_start();  // looking along +x: right is +z
    CameraInput in;
    in.right = true;
    cam.update(in, 1);
    expect_near(cam.position(), {-16, 8, 18});
    in = {};
    in.up = true;
    cam.update(in, 0.5);
    expect_near(cam.position(), {-16, 13, 18});
    in = {};
    in.down = true;
    in.left = true;  // diagonal: still 10 voxels/s
    cam.update(in, 1);
    const double h = 10 / std::sqrt(2.0);
    expect_near(cam.position(), {-16, 13 - h, 18 - h});
    in = {};
    in.forward = in.back = true;  // opposite keys cancel
    cam.update(in, 1);
    expect_near(cam.position(), {-16, 13 - h, 18 - h});
}

TEST(Camera, MouseLooksAndPitchIsClamped) {
    ViewCamera cam(Dims{16, 16, 16});
    cam.dissertation_start();
    CameraInput in;
    in.look_dx = 900;  // 0.1 deg/pixel: 90 degrees to the right (towards +z)
    cam.update(in, 0.016);
    EXPECT_NEAR(cam.yaw(), 90, 1e-9);
    expect_near(cam.forward(), {0, 0, 1});
    in = {};
    in.look_dy = -5000;  // mouse up looks up, clamped at 89 degrees
    cam.update(in, 0.016);
    EXPECT_NEAR(cam.pitch(), 89, 1e-9);
    in.look_dy = 100000;
    cam.update(in, 0.016);
    EXPECT_NEAR(cam.pitch(), -89, 1e-9);
    // The deltas of a frame are a sum: one update with 30 px equals three with 10 px.
    ViewCamera a(Dims{8, 8, 8}), b(Dims{8, 8, 8});
    in = {};
    in.look_dx = 30;
    a.update(in, 0.01);
    in.look_dx = 10;
    for (int i = 0; i < 3; ++i) {
        b.update(in, 0.01);
    }
    EXPECT_NEAR(a.yaw(), b.yaw(), 1e-9);
}

TEST(Camera, OrbitTurnsAroundTheCentre) {
    ViewCamera cam(Dims{32, 32, 32});
    cam.dissertation_start();  // (-32, 16, 16), 48 from the centre (16, 16, 16)
    cam.set_mode(ViewCamera::Mode::orbit);
    EXPECT_NEAR(cam.orbit_distance(), 48, 1e-9);
    CameraInput in;
    in.look_dx = 900;  // a quarter turn
    cam.update(in, 0.016);
    const Vec3d p = cam.position();
    const Vec3d c = cam.centre();
    const Vec3d d = {p[0] - c[0], p[1] - c[1], p[2] - c[2]};
    EXPECT_NEAR(length(d), 48, 1e-9);
    expect_near(p, {16, 16, -32});
    // Looking at the centre.
    const Vec3d f = cam.forward();
    expect_near(f, {-d[0] / 48, -d[1] / 48, -d[2] / 48});
    // Forward zooms in at the movement speed, never closer than 1 voxel.
    in = {};
    in.forward = true;
    cam.update(in, 1);
    EXPECT_NEAR(cam.orbit_distance(), 38, 1e-9);
    cam.update(in, 100);
    EXPECT_NEAR(cam.orbit_distance(), 1, 1e-9);
    // Back to fly keeps the view; reset returns to the start view in fly mode.
    const Vec3d before = cam.position();
    cam.toggle_mode();
    EXPECT_EQ(cam.mode(), ViewCamera::Mode::fly);
    expect_near(cam.position(), before);
    cam.reset();
    EXPECT_EQ(cam.mode(), ViewCamera::Mode::fly);
    ViewCamera fresh(Dims{32, 32, 32});
    expect_near(cam.position(), fresh.position());
}

TEST(Camera, LookAtRejectsDegenerateViews) {
    ViewCamera cam(Dims{8, 8, 8});
    EXPECT_THROW(cam.look_at({1, 2, 3}, {1, 2, 3}), InputError);
    EXPECT_THROW(cam.look_at({NAN, 2, 3}, {1, 2, 3}), InputError);
    cam.look_at({0, 0, 0}, {0, 10, 0});  // straight up: clamped to the pitch limit
    EXPECT_NEAR(cam.pitch(), 89, 1e-9);
}

}  // namespace
}  // namespace voxfield
