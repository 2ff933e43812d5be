// Ray set-up and colours of a voxel tracer (sparse_trace.comp): the pinhole pixel ray of
// DESIGN §4, the clip of a ray to the world box with the Amanatides & Woo start state, and the
// sRGB / palette / sky colour helpers. The same arithmetic as raymarch.comp's (so that both
// walk a ray through the same cells and colour a hit alike); raymarch.comp could include this
// file instead of its own copies.
#ifndef VOXFIELD_TRACE_COMMON_GLSL
#define VOXFIELD_TRACE_COMMON_GLSL

const float kFar = 1e30;
// Direction components smaller than this are treated as 0 (never stepped along).
const float kTinyDirection = 1e-20;
const vec3 kSun = vec3(0.57735027, 0.57735027, 0.57735027);  // normalize(1, 1, 1)

// The unit direction of pixel `pix` of a width x height image (forward unit; right, up scaled by
// the aspect and tan(fov / 2)), tiny components zeroed.
vec3 pixel_ray(uvec2 pix, uint width, uint height, vec3 forward, vec3 right, vec3 up) {
    float sx = (float(pix.x) + 0.5) / float(width) * 2.0 - 1.0;
    float sy = 1.0 - (float(pix.y) + 0.5) / float(height) * 2.0;
    vec3 dir = normalize(forward + sx * right + sy * up);
    return mix(dir, vec3(0.0), lessThan(abs(dir), vec3(kTinyDirection)));
}

// A ray o + t dir clipped to the box [0, dims): where the walk starts (`start`, the entry point
// or o when o is inside), the cell it starts in, the face it entered through (0 when it started
// inside; ties of the entry planes: x, then y, then z), the step per axis and 1 / dir (0 on
// axes not stepped). False when the ray misses the box.
struct RayStart {
    vec3 start, inv;
    ivec3 cell, face, stp;
};

bool clip_ray(vec3 o, vec3 dir, ivec3 dims, out RayStart r) {
    vec3 dimsf = vec3(dims);
    r.stp = ivec3(sign(dir));
    r.inv = vec3(r.stp.x != 0 ? 1.0 / dir.x : 0.0, r.stp.y != 0 ? 1.0 / dir.y : 0.0,
                 r.stp.z != 0 ? 1.0 / dir.z : 0.0);
    vec3 near_t = -o * r.inv, far_t = (dimsf - o) * r.inv;
    bvec3 still = equal(r.stp, ivec3(0));
    vec3 lo = mix(min(near_t, far_t), vec3(-kFar), still);
    vec3 hi = mix(max(near_t, far_t), vec3(kFar), still);
    bool outside = false;
    for (int a = 0; a < 3; ++a) {
        outside = outside || (r.stp[a] == 0 && (o[a] < 0.0 || o[a] >= dimsf[a]));
    }
    float t_enter = max(max(max(lo.x, lo.y), lo.z), 0.0);
    float t_exit = min(min(hi.x, hi.y), hi.z);
    r.face = ivec3(0);
    r.start = o;
    r.cell = ivec3(0);
    if (outside || !(t_enter < t_exit)) {
        return false;
    }
    if (t_enter > 0.0) {
        bvec3 e = bvec3(lo.x == t_enter, lo.x != t_enter && lo.y == t_enter,
                        lo.x != t_enter && lo.y != t_enter);
        r.face = ivec3(e) * r.stp;
    }
    r.start = o + dir * t_enter;
    r.cell = clamp(ivec3(floor(r.start)), ivec3(0), dims - 1);
    return true;
}

vec3 unpack_rgb(uint c) {
    return vec3(float(c & 0xFFu), float((c >> 8) & 0xFFu), float((c >> 16) & 0xFFu)) / 255.0;
}

vec3 srgb_to_linear(vec3 c) {
    return mix(c / 12.92, pow((c + 0.055) / 1.055, vec3(2.4)), greaterThan(c, vec3(0.04045)));
}

vec3 linear_to_srgb(vec3 c) {
    c = clamp(c, 0.0, 1.0);
    return mix(c * 12.92, 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055, greaterThan(c, vec3(0.0031308)));
}

uint pack_rgb(vec3 srgb) {
    uvec3 b = uvec3(round(clamp(srgb, 0.0, 1.0) * 255.0));
    return b.r | (b.g << 8) | (b.b << 16) | 0xFF000000u;
}

// The dissertation's sky: a gradient by elevation plus a sun disc (sRGB display colours).
vec3 sky_srgb(vec3 dir) {
    vec3 sky = mix(vec3(0.714, 1.0, 1.0), vec3(0.286, 0.714, 1.0), smoothstep(-0.1, 0.0, dir.y));
    return dot(dir, kSun) > 0.9995 ? vec3(1.0, 0.98, 0.9) : sky;
}

// Bytes R, G, B, A to B, G, R, A.
uint swap_red_blue(uint c) {
    return (c & 0xFF00FF00u) | ((c & 0xFFu) << 16) | ((c >> 16) & 0xFFu);
}

#endif
