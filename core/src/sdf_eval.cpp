// CPU evaluators of the implicit-surface tape (sdf_layout.hpp): one interpreter, templated on
// the number type: float, interval (Moore's interval arithmetic; every operation encloses its
// float result at every point of its operands' intervals) and forward-mode dual numbers
// (value and gradient). Distance bounds after Inigo Quilez's "distance functions" article.
#include <algorithm>
#include <cfloat>
#include <cmath>
#include <stdexcept>

#include "voxfield/core/sdf.hpp"

namespace voxfield::sdf {
namespace {

// ---- intervals: each operation bounds the float operation at every point of its operands
// (float rounding is monotone, so the endpoints computed by the same operation enclose it).
struct I {
    float lo, hi;
};
I operator+(I a, I b) {
    return {a.lo + b.lo, a.hi + b.hi};
}
I operator-(I a, I b) {
    return {a.lo - b.hi, a.hi - b.lo};
}
I operator-(I a, float s) {
    return {a.lo - s, a.hi - s};
}
I operator-(I a) {
    return {-a.hi, -a.lo};
}
I operator*(float s, I a) {
    const float x = s * a.lo, y = s * a.hi;
    return {std::min(x, y), std::max(x, y)};
}
I operator*(I a, float s) {
    return s * a;
}
I operator/(I a, float s) {
    const float x = a.lo / s, y = a.hi / s;
    return {std::min(x, y), std::max(x, y)};
}
I vabs(I a) {
    if (a.lo >= 0) {
        return a;
    }
    if (a.hi <= 0) {
        return {-a.hi, -a.lo};
    }
    return {0.0f, std::max(-a.lo, a.hi)};
}
I sq(I a) {
    const I m = vabs(a);
    return {m.lo * m.lo, m.hi * m.hi};
}
I vsqrt(I a) {
    return {std::sqrt(std::max(a.lo, 0.0f)), std::sqrt(std::max(a.hi, 0.0f))};
}
I vmin(I a, I b) {
    return {std::min(a.lo, b.lo), std::min(a.hi, b.hi)};
}
I vmax(I a, I b) {
    return {std::max(a.lo, b.lo), std::max(a.hi, b.hi)};
}
I vmin(I a, float s) {
    return {std::min(a.lo, s), std::min(a.hi, s)};
}
I vmax(I a, float s) {
    return {std::max(a.lo, s), std::max(a.hi, s)};
}
I clamp01(I a) {
    return vmin(vmax(a, 0.0f), 1.0f);
}

// ---- dual numbers: value and gradient with respect to the world point.
struct D {
    float v;
    Vec3 g;
};
Vec3 operator*(float s, Vec3 a) {
    return {s * a.x, s * a.y, s * a.z};
}
Vec3 operator+(Vec3 a, Vec3 b) {
    return {a.x + b.x, a.y + b.y, a.z + b.z};
}
Vec3 operator-(Vec3 a, Vec3 b) {
    return {a.x - b.x, a.y - b.y, a.z - b.z};
}
D operator+(D a, D b) {
    return {a.v + b.v, a.g + b.g};
}
D operator-(D a, D b) {
    return {a.v - b.v, a.g - b.g};
}
D operator-(D a, float s) {
    return {a.v - s, a.g};
}
D operator-(D a) {
    return {-a.v, -1.0f * a.g};
}
D operator*(float s, D a) {
    return {s * a.v, s * a.g};
}
D operator*(D a, float s) {
    return s * a;
}
D operator*(D a, D b) {
    return {a.v * b.v, a.v * b.g + b.v * a.g};
}
D operator/(D a, float s) {
    return {a.v / s, (1.0f / s) * a.g};
}
D vabs(D a) {
    return a.v < 0 ? -a : a;
}
D sq(D a) {
    return a * a;
}
D vsqrt(D a) {
    const float r = std::sqrt(std::max(a.v, 0.0f));
    return {r, r > 0 ? (0.5f / r) * a.g : Vec3{}};
}
D vmin(D a, D b) {
    return a.v <= b.v ? a : b;
}
D vmax(D a, D b) {
    return a.v >= b.v ? a : b;
}
D vmin(D a, float s) {
    return a.v <= s ? a : D{s, {}};
}
D vmax(D a, float s) {
    return a.v >= s ? a : D{s, {}};
}
D clamp01(D a) {
    return vmin(vmax(a, 0.0f), 1.0f);
}

// ---- floats.
float vabs(float a) {
    return std::fabs(a);
}
float sq(float a) {
    return a * a;
}
float vsqrt(float a) {
    return std::sqrt(std::max(a, 0.0f));
}
float vmin(float a, float b) {
    return std::min(a, b);
}
float vmax(float a, float b) {
    return std::max(a, b);
}
float clamp01(float a) {
    return std::min(std::max(a, 0.0f), 1.0f);
}

template <class V>
V len2(V a, V b) {
    return vsqrt(sq(a) + sq(b));
}
template <class V>
V len3(V a, V b, V c) {
    return vsqrt(sq(a) + sq(b) + sq(c));
}

// Box of half size (sx, sy, sz) around the origin, at offset (dx, dy, dz).
template <class V>
V box(V dx, V dy, V dz, float sx, float sy, float sz) {
    const V qx = vabs(dx) - sx, qy = vabs(dy) - sy, qz = vabs(dz) - sz;
    const V outside = len3(vmax(qx, 0.0f), vmax(qy, 0.0f), vmax(qz, 0.0f));
    return outside + vmin(vmax(qx, vmax(qy, qz)), 0.0f);
}

template <class V>
V primitive(const Instr& in, V x, V y, V z) {
    const auto& p = in.p;
    switch (in.op) {
        case VF_SDF_SPHERE:
            return len3(x - p[0], y - p[1], z - p[2]) - p[3];
        case VF_SDF_BOX:
            return box(x - p[0], y - p[1], z - p[2], p[3], p[4], p[5]);
        case VF_SDF_ROUND_BOX:
            return box(x - p[0], y - p[1], z - p[2], p[3] - p[6], p[4] - p[6], p[5] - p[6]) - p[6];
        case VF_SDF_CYLINDER: {
            const V dx = x - p[0], dz = z - p[2];
            const V a = len2(dx, dz) - p[3], b = vabs(y - p[1]) - p[4];
            return vmin(vmax(a, b), 0.0f) + len2(vmax(a, 0.0f), vmax(b, 0.0f));
        }
        case VF_SDF_TORUS: {
            const V a = len2(x - p[0], z - p[2]) - p[3];
            return len2(a, y - p[1]) - p[4];
        }
        case VF_SDF_CAPSULE: {
            const float bx = p[3] - p[0], by = p[4] - p[1], bz = p[5] - p[2];
            const float dd = bx * bx + by * by + bz * bz;
            const V ax = x - p[0], ay = y - p[1], az = z - p[2];
            const V dot = bx * ax + by * ay + bz * az;
            const V h = dd > 0 ? clamp01(dot / dd) : 0.0f * dot;
            return len3(ax - bx * h, ay - by * h, az - bz * h) - p[6];
        }
        case VF_SDF_PLANE:
            return p[0] * x + p[1] * y + p[2] * z - p[3];
        default:
            throw std::logic_error("sdf tape: not a primitive");
    }
}

// Polynomial smooth minimum (DESIGN §3).
float smooth_min(float a, float b, float k) {
    const float h = std::max(k - std::fabs(a - b), 0.0f) / k;
    return std::min(a, b) - h * h * k * 0.25f;
}
D smooth_min(D a, D b, float k) {
    const float h = std::max(k - std::fabs(a.v - b.v), 0.0f) / k;
    // d/da (min - h^2 k / 4) = 1 - h / 2 for the smaller operand, h / 2 for the other.
    const D& lo = a.v <= b.v ? a : b;
    const D& other = a.v <= b.v ? b : a;
    return {std::min(a.v, b.v) - h * h * k * 0.25f,
            (1.0f - 0.5f * h) * lo.g + (0.5f * h) * other.g};
}
// The smooth minimum is non-decreasing in both operands, so the endpoints bound it; widened by
// a few ulps since its float evaluation need not be exactly monotone.
I smooth_min(I a, I b, float k) {
    const float lo = smooth_min(a.lo, b.lo, k), hi = smooth_min(a.hi, b.hi, k);
    const float e = 8 * FLT_EPSILON;
    return {lo - e * (std::fabs(lo) + k), hi + e * (std::fabs(hi) + k)};
}

// Which operand of a minimum / maximum decides the material: 0 (A), 1 (B), or -1 unknown.
int pick_min(float a, float b) {
    return a <= b ? 0 : 1;
}
int pick_min(D a, D b) {
    return a.v <= b.v ? 0 : 1;
}
int pick_min(I a, I b) {
    if (a.hi <= b.lo) {
        return 0;
    }
    return b.hi < a.lo ? 1 : -1;
}
int pick_max(float a, float b) {
    return a >= b ? 0 : 1;
}
int pick_max(D a, D b) {
    return a.v >= b.v ? 0 : 1;
}
int pick_max(I a, I b) {
    if (a.lo >= b.hi) {
        return 0;
    }
    return b.lo > a.hi ? 1 : -1;
}

std::uint8_t choose(int pick, std::uint8_t a, std::uint8_t b) {
    if (pick == 0) {
        return a;
    }
    if (pick == 1) {
        return b;
    }
    return a == b ? a : 0;
}

template <class V>
struct Result {
    V value;
    std::uint8_t material;
};

template <class V>
Result<V> run(const Tape& tape, V px, V py, V pz) {
    V values[VF_SDF_STACK];
    std::uint8_t materials[VF_SDF_STACK];
    V points[VF_SDF_STACK][3];
    int nv = 0, np = 0;
    points[0][0] = px;
    points[0][1] = py;
    points[0][2] = pz;
    for (const Instr& in : tape.code) {
        const auto& p = in.p;
        if (in.op <= VF_SDF_PLANE) {
            values[nv] = primitive(in, points[np][0], points[np][1], points[np][2]);
            materials[nv++] = static_cast<std::uint8_t>(in.material);
            continue;
        }
        switch (in.op) {
            case VF_SDF_MIN:
            case VF_SDF_MAX:
            case VF_SDF_DIFF:
            case VF_SDF_SMOOTH_MIN:
            case VF_SDF_SMOOTH_DIFF: {
                const V b = values[--nv];
                const V a = values[nv - 1];
                std::uint8_t& m = materials[nv - 1];
                if (in.op == VF_SDF_MIN) {
                    m = choose(pick_min(a, b), m, materials[nv]);
                    values[nv - 1] = vmin(a, b);
                } else if (in.op == VF_SDF_MAX) {
                    m = choose(pick_max(a, b), m, materials[nv]);
                    values[nv - 1] = vmax(a, b);
                } else if (in.op == VF_SDF_DIFF) {
                    values[nv - 1] = vmax(a, -b);
                } else if (in.op == VF_SDF_SMOOTH_MIN) {
                    m = choose(pick_min(a, b), m, materials[nv]);
                    values[nv - 1] = smooth_min(a, b, p[0]);
                } else {
                    values[nv - 1] = -smooth_min(-a, b, p[0]);
                }
                break;
            }
            case VF_SDF_SHELL:
                values[nv - 1] = vabs(values[nv - 1]) - p[0];
                break;
            case VF_SDF_PUSH_POINT: {
                const V dx = points[np][0] - p[9], dy = points[np][1] - p[10],
                        dz = points[np][2] - p[11];
                for (int r = 0; r < 3; ++r) {
                    points[np + 1][r] = p[3 * r] * dx + p[3 * r + 1] * dy + p[3 * r + 2] * dz;
                }
                ++np;
                break;
            }
            case VF_SDF_POP_POINT:
                --np;
                values[nv - 1] = values[nv - 1] * p[0];
                break;
            default:
                throw std::logic_error("sdf tape: unknown opcode " + std::to_string(in.op));
        }
    }
    return {values[0], materials[0]};
}

}  // namespace

float evaluate(const Tape& tape, Vec3 p) {
    return run<float>(tape, p.x, p.y, p.z).value;
}

ValueMaterial evaluate_material(const Tape& tape, Vec3 p) {
    const auto r = run<float>(tape, p.x, p.y, p.z);
    return {r.value, r.material};
}

IntervalMaterial evaluate_interval(const Tape& tape, const Box& b) {
    const auto r = run<I>(tape, I{b.x.lo, b.x.hi}, I{b.y.lo, b.y.hi}, I{b.z.lo, b.z.hi});
    return {{r.value.lo, r.value.hi}, r.material};
}

ValueGradient evaluate_gradient(const Tape& tape, Vec3 p) {
    const auto r = run<D>(tape, D{p.x, {1, 0, 0}}, D{p.y, {0, 1, 0}}, D{p.z, {0, 0, 1}});
    return {r.value.v, r.value.g};
}

}  // namespace voxfield::sdf
