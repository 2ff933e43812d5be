#version 450
// DDA ray marcher over a packed32 or compact Manhattan, Chebyshev or Euclidean distance field.
// Traversal: Amanatides & Woo, "A Fast Voxel Traversal Algorithm for Ray Tracing" (Eurographics
// 1987); empty-space skipping by the distance field as in the dissertation's viewer (chapter 5),
// without its step cap. Implicit surfaces: in a voxel the surface crosses, the first root of the
// trilinear interpolant of its corner values along the ray (a cubic in the ray parameter, split
// into monotone pieces at the roots of its derivative, each bracketed and bisected: Marmitt et
// al., "Fast and Accurate Ray-Voxel Intersection Techniques for Iso-Surface Ray Tracing", VMV
// 2004), shaded with the interpolated gradient.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#include "voxfield/core/sdf_layout.hpp"
#include "voxfield/layout.h"
#include "voxfield/vk/trace_layout.h"

layout(local_size_x = VF_RAYMARCH_LOCAL_SIZE, local_size_y = VF_RAYMARCH_LOCAL_SIZE) in;

// Specialization constants (mirrored by vk/src/raymarcher.cpp): the metric of the field's
// distances and of the block minima, whether each ray records its counts, and whether lit
// shading marches shadow rays and takes occlusion taps (the pipelines for flat shading leave
// them out: their mere presence slows the primary walk on CPU Vulkan drivers such as
// lavapipe).
const uint kManhattan = 0u, kChebyshev = 1u, kEuclidean = 2u;
layout(constant_id = 0) const uint kMetric = kManhattan;
layout(constant_id = 1) const bool kCount = false;
layout(constant_id = 2) const bool kShadows = true;
// Whether the field lies in one binding (slab 0): then a fetch needs neither the division that
// finds a cell's slab nor the switch over the bindings, which CPU drivers run lane by lane.
layout(constant_id = 3) const bool kOneSlab = false;
// Whether the field is compact (16 bits per cell) rather than packed32 with material bytes at
// VF_RAYMARCH_BINDING_MATERIAL.
layout(constant_id = 4) const bool kCompact = true;
// Whether an implicit surface is traced (its grid at VF_TRACE_BINDING_*): a solid cell the
// surface crosses is hit where the trilinear interpolant of its corners first reaches f < 0.
layout(constant_id = 5) const bool kImplicit = false;
// Whether each primary ray records its hit point and normal (VF_TRACE_BINDING_SURFACE).
layout(constant_id = 6) const bool kSurface = false;

// One RGBA8 pixel per texel, r | g << 8 | b << 16 | a << 24 (bytes R, G, B, A in memory), so
// flat colours are written bit-exactly (no float -> unorm rounding).
layout(binding = VF_RAYMARCH_BINDING_IMAGE, r32ui) uniform writeonly uimage2D out_image;
// Palette entry m as r | g << 8 | b << 16 | a << 24.
layout(std430, binding = VF_RAYMARCH_BINDING_PALETTE) readonly buffer PaletteBuf {
    uint palette[256];
};
// With VF_RAYMARCH_FLAG_BLOCK_MIN: the per-block minimum distances (layout.h
// VF_RAYMARCH_BLOCK), copied or written in place by OpenCL; never read otherwise.
layout(std430, binding = VF_RAYMARCH_BINDING_BLOCK_MIN) readonly buffer BlockMinBuf {
    uint block_min[];
};

// The field is split along z into slabs of pc.dims.w slices, one binding each, so that no
// binding exceeds maxStorageBufferRange. Unused bindings alias slab 0 and are never read.
// packed32: materials (the world's voxel bytes, four per word, same slabs) sit beside the
// field. compact (kCompact): 16 bits per voxel, two per word, distance and
// material together; the material bindings alias field slab 0 and are never read.
layout(std430, binding = VF_RAYMARCH_BINDING_FIELD + 0) readonly buffer F0 {
    uint f0[];
};
layout(std430, binding = VF_RAYMARCH_BINDING_FIELD + 1) readonly buffer F1 {
    uint f1[];
};
layout(std430, binding = VF_RAYMARCH_BINDING_FIELD + 2) readonly buffer F2 {
    uint f2[];
};
layout(std430, binding = VF_RAYMARCH_BINDING_FIELD + 3) readonly buffer F3 {
    uint f3[];
};
layout(std430, binding = VF_RAYMARCH_BINDING_FIELD + 4) readonly buffer F4 {
    uint f4[];
};
layout(std430, binding = VF_RAYMARCH_BINDING_FIELD + 5) readonly buffer F5 {
    uint f5[];
};
layout(std430, binding = VF_RAYMARCH_BINDING_FIELD + 6) readonly buffer F6 {
    uint f6[];
};
layout(std430, binding = VF_RAYMARCH_BINDING_FIELD + 7) readonly buffer F7 {
    uint f7[];
};
layout(std430, binding = VF_RAYMARCH_BINDING_MATERIAL + 0) readonly buffer M0 {
    uint m0[];
};
layout(std430, binding = VF_RAYMARCH_BINDING_MATERIAL + 1) readonly buffer M1 {
    uint m1[];
};
layout(std430, binding = VF_RAYMARCH_BINDING_MATERIAL + 2) readonly buffer M2 {
    uint m2[];
};
layout(std430, binding = VF_RAYMARCH_BINDING_MATERIAL + 3) readonly buffer M3 {
    uint m3[];
};
layout(std430, binding = VF_RAYMARCH_BINDING_MATERIAL + 4) readonly buffer M4 {
    uint m4[];
};
layout(std430, binding = VF_RAYMARCH_BINDING_MATERIAL + 5) readonly buffer M5 {
    uint m5[];
};
layout(std430, binding = VF_RAYMARCH_BINDING_MATERIAL + 6) readonly buffer M6 {
    uint m6[];
};
layout(std430, binding = VF_RAYMARCH_BINDING_MATERIAL + 7) readonly buffer M7 {
    uint m7[];
};
// With kCount: per pixel (row by row) the ray's field fetches and DDA steps. The binding after
// the material slabs (kCounterBinding in vk/src/raymarcher.cpp); never written otherwise.
layout(std430, binding = VF_RAYMARCH_BINDING_MATERIAL + VF_RAYMARCH_MAX_SLABS) writeonly buffer C {
    uvec2 counters[];
};

// With kImplicit: an ocl::ImplicitGrid's arrays (core/sdf_layout.hpp); placeholders otherwise.
layout(std430, binding = VF_TRACE_BINDING_TILES) readonly buffer TileBuf {
    uint tile_table[];
};
layout(std430, binding = VF_TRACE_BINDING_NODES) readonly buffer NodeBuf {
    uint nodes[];
};
layout(std430, binding = VF_TRACE_BINDING_VOXELS) readonly buffer VoxelBuf {
    uint voxel_records[];
};
layout(std430, binding = VF_TRACE_BINDING_VERTICES) readonly buffer VertexBuf {
    vec4 vertices[];  // grad f (x, y, z), f
};
// With kSurface: per pixel (row by row) (point, kind), (normal, t) (trace_layout.h).
layout(std430, binding = VF_TRACE_BINDING_SURFACE) writeonly buffer SurfaceBuf {
    vec4 surface_hits[];
};

// Mirrors PushConstants in vk/src/march_params.hpp (static_asserts there).
layout(push_constant) uniform Params {
    vec4 origin;     // camera position (xyz)
    vec4 forward;    // unit view direction
    vec4 right;      // camera right * aspect * tan(fov / 2)
    vec4 up;         // camera up * tan(fov / 2)
    uvec4 dims;      // world X, Y, Z; z-slices per slab
    uvec4 image;     // width, height, VF_RAYMARCH_FLAG_*, flat sky colour (packed RGBA8)
    uvec4 implicit;  // kImplicit: the surface's tiles X, Y, Z and tile depth
}
pc;

const float kFar = 1e30;
// Direction components smaller than this are treated as 0 (never stepped along), so that
// no 1 / tiny overflows or flushes differently in the clip and in the walk.
const float kTinyDirection = 1e-20;

uint read_field(uint slab, uint i) {
    if (kOneSlab) {
        return f0[i];
    }
    switch (slab) {
        case 0u:
            return f0[i];
        case 1u:
            return f1[i];
        case 2u:
            return f2[i];
        case 3u:
            return f3[i];
        case 4u:
            return f4[i];
        case 5u:
            return f5[i];
        case 6u:
            return f6[i];
        default:
            return f7[i];
    }
}

uint read_material_word(uint slab, uint i) {
    if (kOneSlab) {
        return m0[i];
    }
    switch (slab) {
        case 0u:
            return m0[i];
        case 1u:
            return m1[i];
        case 2u:
            return m2[i];
        case 3u:
            return m3[i];
        case 4u:
            return m4[i];
        case 5u:
            return m5[i];
        case 6u:
            return m6[i];
        default:
            return m7[i];
    }
}

// Slab and index inside the slab of cell c (all coordinates inside the world).
uvec2 locate(ivec3 c) {
    if (kOneSlab) {
        return uvec2(0u, (uint(c.z) * pc.dims.y + uint(c.y)) * pc.dims.x + uint(c.x));
    }
    uint z = uint(c.z);
    uint slab = z / pc.dims.w;
    uint i = ((z - slab * pc.dims.w) * pc.dims.y + uint(c.y)) * pc.dims.x + uint(c.x);
    return uvec2(slab, i);
}


// The field element of cell c: (distance << 8) | colour or material, in its low 16 bits.
uint read_cell(ivec3 c) {
    uvec2 at = locate(c);
    if (kCompact) {
        return (read_field(at.x, at.y >> 1u) >> ((at.y & 1u) * 16u)) & 0xFFFFu;
    }
    return read_field(at.x, at.y);
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

const vec3 kSun = vec3(0.57735027, 0.57735027, 0.57735027);  // normalize(1, 1, 1)

// The dissertation's sky (seed-code-notes.md): a gradient by elevation plus a sun disc, taken
// as sRGB display colours.
vec3 sky_srgb(vec3 dir) {
    vec3 sky = mix(vec3(0.714, 1.0, 1.0), vec3(0.286, 0.714, 1.0), smoothstep(-0.1, 0.0, dir.y));
    float s = dot(dir, kSun);
    return s > 0.9995 ? vec3(1.0, 0.98, 0.9) : sky;
}

bool g_coarse;
uvec3 g_blocks;

// kImplicit: the latest march's hit was on the trilinear interpolant (g_smooth), with the
// normalised interpolated gradient g_normal.
bool g_smooth;
vec3 g_normal;

const uint kNoRecord = 0xFFFFFFFFu;

// The record of cell c among the crossed voxels, and its leaf's first vertex, when the surface
// crosses c; kNoRecord otherwise (an empty or full tile, cell, or a voxel of a leaf that the
// surface does not cross). Walks the tile's contree: a child's rank among the occupied bits
// gives its position among its siblings.
uint crossed_record(ivec3 c, out uint vertex_base) {
    vertex_base = 0u;
    uvec3 u = uvec3(c);
    uint depth = pc.implicit.w;
    uvec3 t = u >> (2u * (depth + 1u));
    uint node = tile_table[(t.z * pc.implicit.y + t.y) * pc.implicit.x + t.x];
    if (node == VF_SDF_TILE_EMPTY || node == VF_SDF_TILE_FULL) {
        return kNoRecord;
    }
    for (uint shift = 2u * depth;; shift -= 2u) {
        uvec3 l = (u >> shift) & 3u;
        uint child = l.x + 4u * l.y + 16u * l.z;
        uint base = node * uint(VF_SDF_NODE_WORDS);
        uint lo = nodes[base + 2u], hi = nodes[base + 3u];
        uint rank;
        if (child < 32u) {
            if (((lo >> child) & 1u) == 0u) {
                return kNoRecord;
            }
            rank = uint(bitCount(lo & ((1u << child) - 1u)));
        } else {
            if (((hi >> (child - 32u)) & 1u) == 0u) {
                return kNoRecord;
            }
            rank = uint(bitCount(lo)) + uint(bitCount(hi & ((1u << (child - 32u)) - 1u)));
        }
        uint first = nodes[base];
        uint leaf_vertex = nodes[base + 1u];
        if (leaf_vertex != VF_SDF_NOT_LEAF) {
            vertex_base = leaf_vertex;
            return first + rank;
        }
        if (shift == 0u) {
            return kNoRecord;  // a tree deeper than its tiles: never built
        }
        node = first + rank;
    }
}

// A crossed voxel whose corner gradients differ by more than 60 degrees (some pair's cosine
// below kSharpCos) and whose f is convex or concave there holds a kink of f: a CAD edge or
// vertex. There the trilinear interpolant of the corner values rounds the solid's edge off (by
// up to 0.37 voxel on a box), so the cell is traced on its corners' tangent planes
// f_i + g_i . (x - c_i) instead (g_i: h grad f, the change per voxel): their maximum where f
// is convex (every plane at or below the values at the other corners, as at an edge of a
// convex solid, whose planes are supporting planes: the faces' own planes meet in the exact
// edge), their minimum where it is concave (every plane at or above them). Elsewhere (smooth
// surfaces: a sphere of 12 voxels' radius turns 8 degrees across a voxel; saddles) the
// interpolant stays.
const float kSharpCos = 0.5;

// Whether the corners' planes are all below (+1) or all above (-1) the values at the other
// corners, within 1% of a voxel's change; 0 when neither.
int corner_convexity(vec4 corner[8]) {
    float lo = 0.0, hi = 0.0, scale = 0.0;
    [[unroll]] for (uint i = 0u; i < 8u; ++i) {
        vec3 ci = vec3(float(i & 1u), float((i >> 1) & 1u), float(i >> 2));
        scale = max(scale, length(corner[i].xyz));
        [[unroll]] for (uint j = 0u; j < 8u; ++j) {
            vec3 cj = vec3(float(j & 1u), float((j >> 1) & 1u), float(j >> 2));
            float e = corner[j].w + dot(corner[j].xyz, ci - cj) - corner[i].w;
            lo = min(lo, e);
            hi = max(hi, e);
        }
    }
    float tol = 0.01 * scale;
    return hi <= tol ? 1 : (lo >= -tol ? -1 : 0);
}

// The first s in [0, len] where the sharp model of the cell (corners `corner`, convex or not)
// along p + s dir is < 0, and the gradient of the plane that is active there; false when it
// stays >= 0.
bool sharp_root(vec4 corner[8], bool convex, vec3 p, vec3 dir, float len, out float s_hit,
                out vec3 grad) {
    s_hit = 0.0;
    grad = vec3(0.0);
    // Along the ray plane i is a_i + b_i s. Convex: inside where every plane is < 0, the
    // interval [lo, hi]; concave: where any is, from the earliest plane's entry.
    float lo = 0.0, hi = len;
    float first = len + 1.0;
    float best_a = -kFar;
    int arg = -1, arg0 = -1;
    [[unroll]] for (uint i = 0u; i < 8u; ++i) {
        vec3 g = corner[i].xyz;
        if (dot(g, g) < 1e-12) {
            continue;  // no direction: no plane
        }
        vec3 ci = vec3(float(i & 1u), float((i >> 1) & 1u), float(i >> 2));
        float a = corner[i].w + dot(g, p - ci), b = dot(g, dir);
        if (convex) {
            if (a > best_a) {
                best_a = a;
                arg0 = int(i);
            }
            if (b < 0.0) {
                float t = -a / b;
                if (t > lo) {
                    lo = t;
                    arg = int(i);
                }
            } else if (b > 0.0) {
                hi = min(hi, -a / b);
            } else if (a >= 0.0) {
                hi = -1.0;
            }
        } else {
            float t = a < 0.0 ? 0.0 : (b < 0.0 ? -a / b : kFar);
            if (t < first) {
                first = t;
                arg = int(i);
            }
        }
    }
    if (convex) {
        if (!(lo < hi) || arg0 < 0) {
            return false;
        }
        s_hit = lo;
        arg = arg < 0 ? arg0 : arg;  // inside where the ray enters: the highest plane there
    } else {
        if (!(first <= len) || arg < 0) {
            return false;
        }
        s_hit = first;
    }
    // Component selects: the plane's gradient without a dynamic index.
    [[unroll]] for (uint i = 0u; i < 8u; ++i) {
        grad = int(i) == arg ? corner[i].xyz : grad;
    }
    return true;
}

// The first s in [0, len] where the trilinear interpolant of crossed voxel `record`'s corners
// (its leaf's vertices from vertex_base) along p + s dir (p in the unit cell) is < 0, refined
// to where it reaches 0 (within len / 2^10, then a secant step), and the interpolated gradient
// there; false when it stays >= 0. Along the ray the interpolant is a
// cubic k0 + k1 s + k2 s^2 + k3 s^3; between consecutive roots of its derivative it is
// monotone, so each such piece holds a root exactly when its ends differ in sign (a thin
// crossing between two samples is never stepped over), and bisection keeps it bracketed.
bool cell_root(uint record, uint vertex_base, vec3 p, vec3 dir, float len, out float s_hit,
               out vec3 grad) {
    s_hit = 0.0;
    grad = vec3(0.0);
    // The corners (c = x + 2 y + 4 z: grad f, f), in a local array that unrolled loops index by
    // constants only (a CPU driver keeps it in registers).
    vec4 corner[8];
    uint base = record * uint(VF_SDF_VOXEL_WORDS);
    uint w0 = voxel_records[base], w1 = voxel_records[base + 1u];
    [[unroll]] for (uint c = 0u; c < 8u; ++c) {
        uint local = ((c < 4u ? w0 : w1) >> (8u * (c & 3u))) & 0xFFu;
        corner[c] = vertices[vertex_base + local];
    }
    p = clamp(p, 0.0, 1.0);
    float min_cos = 1.0;
    [[unroll]] for (uint i = 0u; i < 8u; ++i) {
        [[unroll]] for (uint j = i + 1u; j < 8u; ++j) {
            vec3 a = corner[i].xyz, b = corner[j].xyz;
            float ab = dot(a, a) * dot(b, b);
            min_cos = ab > 0.0 ? min(min_cos, dot(a, b) * inversesqrt(ab)) : min_cos;
        }
    }
    if (min_cos < kSharpCos) {
        int convexity = corner_convexity(corner);
        if (convexity != 0) {
            return sharp_root(corner, convexity > 0, p, dir, len, s_hit, grad);
        }
    }
    vec4 k = vec4(0.0);  // k0..k3
    [[unroll]] for (uint c = 0u; c < 8u; ++c) {
        // Each axis' weight is linear in s: (a, b) = a + b s.
        vec2 wx = (c & 1u) != 0u ? vec2(p.x, dir.x) : vec2(1.0 - p.x, -dir.x);
        vec2 wy = (c & 2u) != 0u ? vec2(p.y, dir.y) : vec2(1.0 - p.y, -dir.y);
        vec2 wz = (c & 4u) != 0u ? vec2(p.z, dir.z) : vec2(1.0 - p.z, -dir.z);
        vec4 prod = vec4(wx.x * wy.x * wz.x,
                         wx.y * wy.x * wz.x + wx.x * wy.y * wz.x + wx.x * wy.x * wz.y,
                         wx.y * wy.y * wz.x + wx.y * wy.x * wz.y + wx.x * wy.y * wz.y,
                         wx.y * wy.y * wz.y);
        k += corner[c].w * prod;
    }
    bool found = k.x < 0.0;  // already inside where the ray enters the cell
    // Roots of the derivative 3 k3 s^2 + 2 k2 s + k1 inside (0, len), in order.
    float a = 3.0 * k.w, b = 2.0 * k.z, cc = k.y;
    float split0 = len, split1 = len;
    if (a != 0.0) {
        float disc = b * b - 4.0 * a * cc;
        if (disc >= 0.0) {
            float q = -0.5 * (b + (b >= 0.0 ? sqrt(disc) : -sqrt(disc)));
            float r0 = q / a, r1 = q != 0.0 ? cc / q : r0;
            split0 = min(r0, r1);
            split1 = max(r0, r1);
        }
    } else if (b != 0.0) {
        split0 = -cc / b;
    }
    split0 = split0 > 0.0 && split0 < len ? split0 : len;
    split1 = split1 > split0 && split1 < len ? split1 : len;
    float lo = 0.0;
    for (int i = 0; i < 3 && !found; ++i) {
        float hi = i == 0 ? split0 : (i == 1 ? split1 : len);
        if (hi > lo && ((k.w * hi + k.z) * hi + k.y) * hi + k.x < 0.0) {
            // f(lo) >= 0 > f(hi): bisect, then one secant step between the bracket's ends.
            float flo = ((k.w * lo + k.z) * lo + k.y) * lo + k.x;
            float fhi = ((k.w * hi + k.z) * hi + k.y) * hi + k.x;
            for (int it = 0; it < 10; ++it) {
                float mid = 0.5 * (lo + hi);
                float fm = ((k.w * mid + k.z) * mid + k.y) * mid + k.x;
                if (fm < 0.0) {
                    hi = mid;
                    fhi = fm;
                } else {
                    lo = mid;
                    flo = fm;
                }
            }
            s_hit = flo > fhi ? lo + (hi - lo) * flo / (flo - fhi) : hi;
            found = true;
        }
        lo = max(lo, hi);
    }
    if (found) {
        vec3 q = clamp(p + dir * s_hit, 0.0, 1.0);
        vec4 x00 = mix(corner[0], corner[1], q.x), x10 = mix(corner[2], corner[3], q.x);
        vec4 x01 = mix(corner[4], corner[5], q.x), x11 = mix(corner[6], corner[7], q.x);
        grad = mix(mix(x00, x10, q.y), mix(x01, x11, q.y), q.z).xyz;
    }
    return found;
}

// Marches the ray o + t dir (dir normalised, tiny components zeroed) from where it enters the
// world until it hits a solid cell (true: `cell`, the step `face` that entered it, 0 when the
// ray started in it, and the entry point `point` on that face) or leaves the world (false).
// Counts field fetches and DDA steps.
bool march(vec3 o, vec3 dir, out ivec3 cell, out ivec3 face, out vec3 point, inout uint fetches,
           inout uint steps) {
    ivec3 dims = ivec3(pc.dims.xyz);
    vec3 dimsf = vec3(pc.dims.xyz);
    bool coarse = g_coarse;
    uvec3 blocks = g_blocks;
    // Clip the ray to the world box [0, dims]: t_enter is 0 when the camera is inside.
    ivec3 stp = ivec3(sign(dir));
    vec3 inv = vec3(stp.x != 0 ? 1.0 / dir.x : 0.0, stp.y != 0 ? 1.0 / dir.y : 0.0,
                    stp.z != 0 ? 1.0 / dir.z : 0.0);
    vec3 ta = -o * inv, tb = (dimsf - o) * inv;
    vec3 tnear = mix(min(ta, tb), vec3(-kFar), equal(stp, ivec3(0)));
    vec3 tfar = mix(max(ta, tb), vec3(kFar), equal(stp, ivec3(0)));
    // A ray parallel to an axis misses unless it lies inside the world's slab on that axis.
    bool parallel_outside = false;
    for (int a = 0; a < 3; ++a) {
        parallel_outside = parallel_outside || (stp[a] == 0 && (o[a] < 0.0 || o[a] >= dimsf[a]));
    }
    float t_enter = max(max(max(tnear.x, tnear.y), tnear.z), 0.0);
    float t_exit = min(min(tfar.x, tfar.y), tfar.z);

    bool hit = false;
    face = ivec3(0);
    cell = ivec3(0);
    point = o;
    if (kImplicit) {
        g_smooth = false;
    }
    if (!parallel_outside && t_enter < t_exit) {
        if (t_enter > 0.0) {
            // Entered through the face of the largest tnear (ties: x, then y, then z).
            bvec3 e = bvec3(tnear.x == t_enter, tnear.x != t_enter && tnear.y == t_enter,
                            tnear.x != t_enter && tnear.y != t_enter);
            face = ivec3(e) * stp;
        }
        // Clamping puts the entry cell inside the world even when rounding lands the entry
        // point a hair outside the face it crossed.
        // The walk measures t from the entry point, whose coordinates are small even for a
        // distant camera, so float keeps sub-voxel precision along the whole walk.
        vec3 start = o + dir * t_enter;
        cell = clamp(ivec3(floor(start)), ivec3(0), dims - 1);
        // Parametric distance to the next cell boundary per axis, recomputed from the
        // integer cell after each step (no accumulated error); axes not stepped: never.
        vec3 t_next =
            mix((vec3(cell + max(stp, ivec3(0))) - start) * inv, vec3(kFar), equal(stp, ivec3(0)));
        ivec3 entry = cell;
        // Safe skipping rule. The field holds d, a lower bound of the metric distance from
        // this cell to the nearest solid cell (0 = solid): the exact distance rounded down
        // (an integer already for L1 and L-inf, the floor of it for L2) and saturated at 255,
        // which only under-states it. A solid cell at metric distance r from this one makes
        // the true distance at most r, so r >= d: every cell whose integer offset o from this
        // one has metric(o) < d is empty, where the empty region is
        //   L1:    |ox| + |oy| + |oz| < d   (the octahedron of radius d-1),
        //   L-inf: max |o_i| < d            (the cube of half-width d-1),
        //   L2:    ox^2 + oy^2 + oz^2 < d^2 (integers; strict, since floor(true) <= true: a
        //          solid may lie at exactly d).
        // A DDA step moves to a face neighbour and the walk is monotone along every axis, so
        // |o_i| is the number of steps taken along axis i since the fetch. The walk keeps
        // stepping without a fetch while o stays inside the region and fetches the first cell
        // outside it, which may be solid. Per fetch that is
        //   L1:    exactly d steps (the cell after k steps is at L1 distance k),
        //   L-inf: until one |o_i| reaches d: d steps along an axis, up to 3(d-1)+1 along a
        //          diagonal,
        //   L2:    until the squared offset reaches d^2: d steps along an axis, up to about
        //          sqrt(3) d along a diagonal.
        // Hence no solid cell is ever skipped. (For one offset L-inf <= L2 <= L1, so each
        // region holds the L1 one: the L1 rule is safe for every metric's field, only slower.)
        // The offsets are integer counters, the squared offset updated exactly (a step along
        // axis a adds 2 |o_a| + 1), so no float error accumulates. For L2 d is clamped to
        // 65535, still a lower bound, so that d^2 and the squared offset (< d^2 + 2 * 65535)
        // fit in 32 bits. The walk ends only when the ray hits a solid or leaves the world (at
        // most X+Y+Z steps), never by a step cap. Coarse skipping: a saturated 255 only says
        // d >= 255; the minimum distance over the cell's 8^3 block (same metric, unsaturated)
        // is also a lower bound of the cell's distance, so the rule applies to
        // d = max(255, that minimum).
        // kImplicit: the walk stops at every cell of distance 0; a cell the surface crosses is
        // then tested for a root of its interpolant outside the walk's loop (which stays as
        // small as it is for voxel worlds), and the walk resumes one step on when there is
        // none. Voxel worlds run the outer loop once.
        bool resume = false;
        for (;;) {
            for (;;) {
                uint d = 1u;
                if (!(kImplicit && resume)) {
                    // VF_PACKED_DISTANCE_* and VF_COMPACT_DISTANCE_* agree (static_assert'ed
                    // on the host).
                    d = (read_cell(cell) >> VF_PACKED_DISTANCE_SHIFT) & VF_PACKED_DISTANCE_MAX;
                    if (kCount) {
                        ++fetches;
                    }
                    if (d == 0u) {
                        hit = true;
                        break;
                    }
                    if (coarse && d == VF_PACKED_DISTANCE_MAX) {
                        uvec3 b = uvec3(cell) / uvec3(VF_RAYMARCH_BLOCK);
                        d = max(d, block_min[(b.z * blocks.y + b.y) * blocks.x + b.x]);
                    }
                }
                resume = false;
                uvec3 off = uvec3(0u);  // L-inf, L2: |o_i|, steps along each axis since the fetch
                uint off1 = 0u;         // L1: |o|_1, the steps since the fetch
                uint off2 = 0u;         // L2: |o|^2
                uint clamped = min(d, 65535u);
                uint d2 = clamped * clamped;
                bool inside = true;
                for (;;) {
                    // The axis whose boundary comes first (ties: x, then y, then z).
                    bool bx = t_next.x <= t_next.y && t_next.x <= t_next.z;
                    bool by = !bx && t_next.y <= t_next.z;
                    ivec3 m = ivec3(bx, by, !bx && !by);
                    face = m * stp;
                    cell += face;
                    if (kCount) {
                        ++steps;
                    }
                    if (any(lessThan(cell, ivec3(0))) || any(greaterThanEqual(cell, dims))) {
                        inside = false;
                        break;
                    }
                    t_next =
                        mix(t_next, (vec3(cell + max(stp, ivec3(0))) - start) * inv, bvec3(m));
                    bool beyond;
                    if (kMetric == kChebyshev || kMetric == kEuclidean) {
                        uint along = bx ? off.x : (by ? off.y : off.z);
                        off += uvec3(m);
                        if (kMetric == kChebyshev) {
                            beyond = along + 1u >= d;
                        } else {
                            off2 += 2u * along + 1u;
                            beyond = off2 >= d2;
                        }
                    } else {
                        beyond = ++off1 >= d;
                    }
                    if (beyond) {
                        break;  // the first cell outside the empty region: fetch it
                    }
                }
                if (!inside) {
                    break;
                }
            }
            if (!hit) {
                break;
            }
            float t_in = 0.0;
            if (cell != entry) {
                // Entered through the face it stepped across: that boundary plane's t, from
                // the same expression t_next held for it.
                // (Component selects, not a dynamic index: GPUs keep vectors in registers.)
                vec3 t_face = (vec3(cell + max(-stp, ivec3(0))) - start) * inv;
                t_in = face.x != 0 ? t_face.x : (face.y != 0 ? t_face.y : t_face.z);
            }
            if (kImplicit) {
                uint vertex_base;
                uint record = crossed_record(cell, vertex_base);
                if (record != kNoRecord) {
                    // The ray's segment inside the cell, from t_in to the next boundary.
                    float t_out = min(min(t_next.x, t_next.y), t_next.z);
                    vec3 p = start + dir * t_in - vec3(cell);
                    float s;
                    vec3 grad;
                    if (cell_root(record, vertex_base, p, dir, max(t_out - t_in, 0.0), s, grad)) {
                        point = start + dir * (t_in + s);
                        float len = length(grad);
                        g_smooth = true;
                        g_normal = len > 0.0 ? grad / len : -dir;
                        break;
                    }
                    hit = false;  // no root: on to the next cell
                    resume = true;
                    continue;
                }
            }
            point = cell != entry ? start + dir * t_in : start;
            break;
        }
    }
    return hit;
}

// The metric distance stored for cell c (saturated), or `open` for cells outside the world.
uint distance_at(ivec3 c, uint open) {
    if (any(lessThan(c, ivec3(0))) || any(greaterThanEqual(c, ivec3(pc.dims.xyz)))) {
        return open;
    }
    return (read_cell(c) >> VF_PACKED_DISTANCE_SHIFT) & VF_PACKED_DISTANCE_MAX;
}

// Ambient occlusion of the face of solid cell `cell` whose outward normal is n, from the field:
// the cells k = 2..5 steps out along n are at most k away from the face's cell in every metric
// (an axis offset of k); the less room they have (k - d), the more the face is enclosed. The
// first cell out (k = 1) has d >= 1 = k whenever it is empty, so it is skipped.
float ambient_occlusion(ivec3 cell, ivec3 n) {
    const float weights[4] = float[4](0.4, 0.3, 0.2, 0.1);
    float occlusion = 0.0;
    for (int k = 2; k <= 5; ++k) {
        uint d = min(distance_at(cell + n * k, uint(k)), uint(k));
        occlusion += weights[k - 2] * float(uint(k) - d) / float(k);
    }
    return 1.0 - 0.7 * occlusion;
}

// ambient_occlusion for a point on an implicit surface with unit normal n: the taps are the
// cells k = 2..5 voxels out along n from the point, one voxel further than a face's (the
// crossed voxels around the surface are solid in the field).
float smooth_occlusion(vec3 point, vec3 n) {
    const float weights[4] = float[4](0.4, 0.3, 0.2, 0.1);
    float occlusion = 0.0;
    for (int k = 2; k <= 5; ++k) {
        uint d = min(distance_at(ivec3(floor(point + n * float(k + 1))), uint(k)), uint(k));
        occlusion += weights[k - 2] * float(uint(k) - d) / float(k);
    }
    return 1.0 - 0.7 * occlusion;
}

void main() {
    uvec2 pix = gl_GlobalInvocationID.xy;
    uint width = pc.image.x, height = pc.image.y;
    if (pix.x >= width || pix.y >= height) {
        return;
    }
    bool lit = (pc.image.z & VF_RAYMARCH_FLAG_LIT) != 0u;
    bool gradient = (pc.image.z & VF_RAYMARCH_FLAG_SKY_GRADIENT) != 0u;
    bool coarse = (pc.image.z & VF_RAYMARCH_FLAG_BLOCK_MIN) != 0u;
    uvec3 blocks = (pc.dims.xyz + uvec3(VF_RAYMARCH_BLOCK - 1)) / uvec3(VF_RAYMARCH_BLOCK);

    // Pinhole camera, DESIGN §4.
    float sx = (float(pix.x) + 0.5) / float(width) * 2.0 - 1.0;
    float sy = 1.0 - (float(pix.y) + 0.5) / float(height) * 2.0;
    vec3 dir = normalize(pc.forward.xyz + sx * pc.right.xyz + sy * pc.up.xyz);
    dir = mix(dir, vec3(0.0), lessThan(abs(dir), vec3(kTinyDirection)));
    g_coarse = coarse;
    g_blocks = blocks;
    ivec3 cell, face;
    vec3 point;
    uint fetches = 0u, steps = 0u;  // for kCount
    bool hit = march(pc.origin.xyz, dir, cell, face, point, fetches, steps);
    if (kCount) {
        counters[pix.y * width + pix.x] = uvec2(fetches, steps);
    }

    bool smooth_hit = kImplicit && hit && g_smooth;
    vec3 smooth_normal = kImplicit ? g_normal : vec3(0.0);
    if (kSurface) {
        vec3 n = smooth_hit ? smooth_normal : (face != ivec3(0) ? -vec3(face) : -dir);
        uint kind = !hit ? VF_TRACE_MISS : (smooth_hit ? VF_TRACE_SMOOTH : VF_TRACE_CUBE);
        uint at = 2u * (pix.y * width + pix.x);
        surface_hits[at] = vec4(point, float(kind));
        surface_hits[at + 1u] = vec4(n, hit ? dot(point - pc.origin.xyz, dir) : 0.0);
    }

    uint colour;
    if (hit) {
        uint material;
        if (kCompact) {
            material = read_cell(cell) & VF_COMPACT_MATERIAL_MASK;
        } else {
            uvec2 at = locate(cell);
            material = (read_material_word(at.x, at.y >> 2) >> ((at.y & 3u) * 8u)) & 0xFFu;
        }
        uint rgba = palette[material];
        if (!lit) {
            colour = (rgba & 0x00FFFFFFu) | 0xFF000000u;
        } else {
            vec3 n = smooth_hit ? smooth_normal : (face != ivec3(0) ? -vec3(face) : -dir);
            vec3 base = srgb_to_linear(unpack_rgb(rgba));
            float diffuse = max(dot(n, kSun), 0.0);
            float ambient = 0.18 + 0.12 * n.y;
            if (smooth_hit) {
                // As for a face below, from just above the surface along its normal.
                if (kShadows && diffuse > 0.0) {
                    ivec3 c2, f2;
                    vec3 p2;
                    uint fetches2 = 0u, steps2 = 0u;
                    if (march(point + n * 0.05, kSun, c2, f2, p2, fetches2, steps2)) {
                        diffuse = 0.0;
                    }
                }
                if (kShadows) {
                    ambient *= smooth_occlusion(point, n);
                }
            } else if (face != ivec3(0)) {
                // The sun's light reaches the face unless the ray from just outside it
                // toward the sun hits a solid (the sun is a direction: no distance limit).
                ivec3 out_n = -face;
                if (kShadows && diffuse > 0.0) {
                    ivec3 c2, f2;
                    vec3 p2;
                    uint fetches2 = 0u, steps2 = 0u;
                    if (march(point + vec3(out_n) * 0.01, kSun, c2, f2, p2, fetches2, steps2)) {
                        diffuse = 0.0;
                    }
                }
                if (kShadows) {
                    ambient *= ambient_occlusion(cell, out_n);
                }
            }
            colour = pack_rgb(linear_to_srgb(base * (ambient + 0.8 * diffuse)));
        }
    } else if (lit && gradient) {
        colour = pack_rgb(sky_srgb(dir));
    } else {
        colour = (pc.image.w & 0x00FFFFFFu) | 0xFF000000u;
    }
    if ((pc.image.z & VF_RAYMARCH_FLAG_BGRA) != 0u) {
        colour = (colour & 0xFF00FF00u) | ((colour & 0xFFu) << 16) | ((colour >> 16) & 0xFFu);
    }
    imageStore(out_image, ivec2(pix), uvec4(colour, 0u, 0u, 0u));
}
