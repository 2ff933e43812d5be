#pragma once
// The viewer's camera as plain math (no windowing API): free-fly as in the dissertation's
// demo (WASD / arrows, Space up, Left Shift down, Left Ctrl x4, 10 voxels/s, mouse look),
// an orbit mode around the world's centre, and the pinhole rays of DESIGN §4 for picking.
//
// Angles are in degrees. yaw 0 looks along +x, yaw 90 along +z; pitch > 0 looks up (+y).
// The image basis is the renderer's (image_basis, used by vk::camera_basis; DESIGN §4): right =
// normalize(cross(forward, +y)) (+x when looking straight along +-y), up = cross(right,
// forward).
#include <array>
#include <cstdint>
#include <optional>

#include "voxfield/core/chunks.hpp"
#include "voxfield/core/world.hpp"

namespace voxfield {

using Vec3d = std::array<double, 3>;

// Unit view direction for yaw/pitch (degrees).
Vec3d direction_from_angles(double yaw_deg, double pitch_deg);

// Unit right/up vectors of the DESIGN §4 image basis for a view direction (any length > 0).
struct ViewBasis {
    Vec3d forward, right, up;  // unit vectors
};
ViewBasis view_basis(const Vec3d& forward);

// The image plane of DESIGN §4, the one camera model of the project: the image point (px, py)
// (pixels, x right, y down) of a width x height image looks along forward + sx * right +
// sy * up with sx = px / W * 2 - 1, sy = 1 - py / H * 2, where right and up are view_basis's
// scaled by aspect * tan(fov/2) and tan(fov/2). The ray marcher's shader gets exactly these
// (vk::camera_basis); pixel_direction normalises them.
struct ImageBasis {
    Vec3d forward, right, up;  // forward unit; right, up scaled
};
ImageBasis image_basis(const Vec3d& forward, double fov_deg, double width, double height);

// The unit direction through the image point (px, py) in pixels (x right, y down; the centre
// of pixel (i, j) is (i + 0.5, j + 0.5)) of a width x height image with vertical field of
// view fov_deg: forward + sx * aspect * tan(fov/2) * right + sy * tan(fov/2) * up with
// sx = px / W * 2 - 1, sy = 1 - py / H * 2.
Vec3d pixel_direction(const Vec3d& forward, double fov_deg, double width, double height, double px,
                      double py);

// The inverse: where the world point `point` appears in that image, seen from `eye` along
// `forward` (image coordinates as above; may lie outside the image), or nothing when the
// point is not in front of the eye (depth along forward <= 1e-6). For the brush preview.
struct ImagePoint {
    double x = 0, y = 0;
};
std::optional<ImagePoint> project_point(const Vec3d& eye, const Vec3d& forward, double fov_deg,
                                        double width, double height, const Vec3d& point);

// The chunk (chunk coordinates of `chunk`^3 chunks over `world`) that holds `position`, the
// nearest one when the position lies outside the world: where "focus follows camera" puts
// lod's focus. chunk > 0.
Int3 chunk_at(const Vec3d& position, Dims world, std::uint32_t chunk);

// What the default camera frames: the box of a world's solid voxels (the whole world when it
// has none), as its centre and half extents.
struct Framing {
    Vec3d centre{0, 0, 0};
    Vec3d half{0.5, 0.5, 0.5};
    // Where the default camera looks from, relative to the centre (any length): front-left
    // and above, in front of the side `front` faces (horizontal, outward).
    Vec3d front{0, 0, -1};
};
Framing world_framing(Dims dims);

// The solids' bounding box, and its front: MagicaVoxel's (-z, vox -y) unless another of the
// four sides a person stands at (-x, +x, +z) shows at least twice its detail, counted as the
// neighbouring pixels of the view along the side's axis that differ in material or depth
// (scene_store8's shop front, +x, against its blank -z wall); then the most detailed side.
Framing solid_framing(const World& world);
// The default camera's position for `f`: from the front-left and above (along 0.75 front +
// 0.6 left + 0.5 up from the centre; for the -z front (-0.6, 0.5, -0.75), facing it) at the
// nearest distance where all eight corners of the box lie inside a pinhole image of vertical
// field of view fov_deg and width / height `aspect` (with a 5% margin), looking at the centre.
Vec3d framing_position(const Framing& f, double fov_deg, double aspect);

// One frame of input. Movement keys are held states; look_dx/dy are the mouse movement in
// screen pixels accumulated over the frame (x right, y down).
struct CameraInput {
    bool forward = false, back = false, left = false, right = false;  // W S A D / arrows
    bool up = false, down = false;                                    // Space, Left Shift
    bool fast = false;                                                // Left Ctrl
    double look_dx = 0, look_dy = 0;
};

struct CameraSettings {
    double speed = 10;             // voxels per second (the dissertation's base speed)
    double fast_factor = 4;        // Left Ctrl multiplies the speed
    double sensitivity = 0.1;      // degrees per pixel of mouse movement
    double max_pitch = 89;         // |pitch| is clamped to this, in degrees
    double orbit_turn_speed = 60;  // degrees per second for the orbit keys
    double fov_deg = 60;           // vertical field of view
};

class ViewCamera {
  public:
    enum class Mode { fly, orbit };

    // Starts at the overview: outside the world, above and in front of it, looking at its
    // centre (the whole world framed for a 4:3 image).
    explicit ViewCamera(Dims world);
    // Starts at framing_position(view, settings.fov_deg, aspect), looking at view.centre,
    // which orbit mode turns around (the same view as `voxfield render`'s default camera).
    ViewCamera(Dims world, const Framing& view, double aspect);

    CameraSettings settings;

    // Back to the start view, fly mode.
    void reset();
    // The dissertation's start: (-X, Y/2, Z/2) looking along +x.
    void dissertation_start();
    // Orbit keeps the current view and turns around the world's centre at the current
    // distance (the view is first turned to face the centre); fly keeps the current view.
    void set_mode(Mode mode);
    void toggle_mode() { set_mode(mode_ == Mode::fly ? Mode::orbit : Mode::fly); }
    Mode mode() const { return mode_; }

    // Advances by dt seconds (motion is speed * dt: frame-rate independent). Fly: look
    // turns yaw/pitch; forward/back along the view direction, left/right along the image's
    // right vector, up/down along +y; diagonal moves are not faster. Orbit: look and the
    // left/right/up/down keys turn around the centre, forward/back change the distance
    // (never below 1 voxel).
    void update(const CameraInput& input, double dt_seconds);

    // Places the camera at `position` looking at `target` (fly mode keeps it; orbit
    // re-centres on the world). Throws InputError when they coincide or are not finite.
    void look_at(const Vec3d& position, const Vec3d& target);

    const Vec3d& position() const { return position_; }
    Vec3d forward() const { return direction_from_angles(yaw_, pitch_); }
    // A point one voxel ahead (for vk::Camera's target).
    Vec3d target() const;
    double yaw() const { return yaw_; }
    double pitch() const { return pitch_; }
    double orbit_distance() const { return distance_; }
    const Vec3d& centre() const { return centre_; }

  private:
    void set_angles(double yaw, double pitch);
    void place_on_orbit();

    Dims dims_;
    Vec3d centre_;
    Vec3d position_{};
    double yaw_ = 0, pitch_ = 0;
    double distance_ = 1;
    Mode mode_ = Mode::fly;
    Framing framing_;            // what reset() frames
    double aspect_ = 4.0 / 3.0;  // of the image reset() frames it for
};

}  // namespace voxfield
