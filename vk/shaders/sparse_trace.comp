#version 450
// Ray tracer of sparse worlds (core/sparse.hpp: a tile grid of 64-trees). Per ray one
// Amanatides & Woo walk ("A Fast Voxel Traversal Algorithm for Ray Tracing", Eurographics
// 1987) over a hierarchy of cells: blocks of 8^3 tiles (512^3 voxels), tiles (64^3), the
// 64-tree's 16^3 and 4^3 nodes, voxels. The walk keeps the exact voxel cell the plain voxel
// walk would be in; an empty node at any level is left in one step, at the first of its exit
// planes the ray crosses, and the walk continues at the coarsest level whose node changed.
// Exactness: the crossing of an exit plane is computed by the same expression as the voxel
// walk's crossing of that plane ((plane - start) / dir per axis, ties x, then y, then z), so
// the walk visits exactly the voxels the plain walk visits, minus those inside empty nodes:
// flat images equal raymarch.comp's pixel for pixel.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_buffer_reference : require
#extension GL_EXT_buffer_reference_uvec2 : require
#include "voxfield/layout.h"
#include "voxfield/vk/sparse_trace_layout.h"
#include "trace_common.glsl"

layout(local_size_x = VF_SPARSE_LOCAL_SIZE, local_size_y = VF_SPARSE_LOCAL_SIZE) in;

// Specialization constants (mirrored by vk/src/sparse_tracer.cpp): whether lit shading traces
// shadow rays and occlusion taps, whether each ray counts its node visits and exits, whether
// the world is one node chunk and one material chunk (read through their bindings).
layout(constant_id = 0) const bool kShadows = true;
layout(constant_id = 1) const bool kCount = false;
layout(constant_id = 2) const bool kOneChunk = false;

// One RGBA8 pixel per texel, r | g << 8 | b << 16 | a << 24.
layout(binding = VF_SPARSE_BINDING_IMAGE, r32ui) uniform writeonly uimage2D out_image;
layout(std430, binding = VF_SPARSE_BINDING_PALETTE) readonly buffer PaletteBuf {
    uint palette[256];
};
layout(std430, binding = VF_SPARSE_BINDING_BLOCKS) readonly buffer BlockBuf {
    uint block_table[];
};
layout(std430, binding = VF_SPARSE_BINDING_PAGES) readonly buffer PageBuf {
    uint pages[];
};
layout(std430, binding = VF_SPARSE_BINDING_RECORDS) readonly buffer RecordBuf {
    uvec4 tile_records[];
};
layout(std430, binding = VF_SPARSE_BINDING_COUNTERS) writeonly buffer CounterBuf {
    uvec2 counters[];
};
// The chunks, through the device addresses in the tile records: a tile's node masks and node
// offsets from its root on, a chunk's materials.
layout(buffer_reference, std430, buffer_reference_align = 8) readonly buffer NodeMasks {
    uvec2 masks[];
};
layout(buffer_reference, std430, buffer_reference_align = 4) readonly buffer Words {
    uint words[];
};
// kOneChunk: the chunks through their bindings.
layout(std430, binding = VF_SPARSE_BINDING_MASKS0) readonly buffer Masks0 {
    uvec2 masks0[];
};
layout(std430, binding = VF_SPARSE_BINDING_OFFSETS0) readonly buffer Offsets0 {
    uint offsets0[];
};
layout(std430, binding = VF_SPARSE_BINDING_MATERIALS0) readonly buffer Materials0 {
    uint materials0[];
};

// Mirrors SparsePushConstants in vk/src/sparse_tracer.cpp.
layout(push_constant) uniform Params {
    vec4 origin;   // camera position (xyz)
    vec4 forward;  // unit view direction
    vec4 right;    // camera right * aspect * tan(fov / 2)
    vec4 up;       // camera up * tan(fov / 2)
    uvec4 dims;    // world X, Y, Z
    uvec4 image;   // width, height, VF_RAYMARCH_FLAG_* (lit, sky gradient, BGRA), sky RGBA8
    uvec4 blocks;  // block table X, Y, Z
}
pc;

// A 64-tree child's bit (x, y, z in 0..3): z << 4 | y << 2 | x.
uint child_bit(uvec3 l) {
    return l.x | (l.y << 2) | (l.z << 4);
}

bool has_bit(uvec2 m, uint b) {
    return ((b < 32u ? m.x >> b : m.y >> (b - 32u)) & 1u) != 0u;
}

// The set bits of m below bit b: a child's position among its siblings.
uint rank_below(uvec2 m, uint b) {
    return b < 32u ? uint(bitCount(m.x & ((1u << b) - 1u)))
                   : uint(bitCount(m.x)) + uint(bitCount(m.y & ((1u << (b - 32u)) - 1u)));
}

// The levels of the walk: 0 block (2^9 voxels per edge), 1 tile (2^6), 2 the 64-tree's 16^3
// nodes, 3 its 4^3 nodes, 4 voxels.
const uint kVoxelLevel = 4u;

int level_shift(uint level) {
    return level == 0u ? 9 : (level == 1u ? 6 : (level == 2u ? 4 : (level == 3u ? 2 : 0)));
}

// What the walk knows of the nodes above its level (valid for the node holding its cell at
// every level above the current one).
uint g_page;    // level 0 occupied: the block's page
// Level 1 occupied: the tile's record (its first uvec4; through the device addresses, its
// node masks and node offsets from its root on and its material chunk) and its root mask.
struct Tile {
    uvec4 record;
    NodeMasks masks;
    Words offsets;
    Words materials;
    uvec2 mask0;
};
Tile g_tile;
uint g_node1;   // level 2 occupied: the 16^3 node's index (from the tile's root)
uvec2 g_mask1;
uint g_node2;   // level 3 occupied: the 4^3 node's index
uvec2 g_mask2;
uint g_bit;     // level 4 occupied: the voxel's bit in g_mask2

// Node i of the walk's tile (0: its root): its mask and its offset (its first child's index).
uvec2 node_mask(uint i) {
    return kOneChunk ? masks0[g_tile.record.x + i] : g_tile.masks.masks[i];
}

uint node_offset(uint i) {
    return kOneChunk ? offsets0[g_tile.record.x + i] : g_tile.offsets.words[i];
}

// Whether the node at `level` holding cell u is occupied (stored, or a set bit of its parent's
// mask); if so, loads what the next level needs.
bool enter(uint level, uvec3 u) {
    if (level == 0u) {
        uvec3 b = u >> 9;
        g_page = block_table[(b.z * pc.blocks.y + b.y) * pc.blocks.x + b.x];
        return g_page != VF_SPARSE_NONE;
    }
    if (level == 1u) {
        uvec3 t = (u >> 6) & uvec3(VF_SPARSE_BLOCK_TILES - 1);
        uint tile = pages[g_page * uint(VF_SPARSE_BLOCK_TILES * VF_SPARSE_BLOCK_TILES *
                                        VF_SPARSE_BLOCK_TILES) +
                          (t.z * uint(VF_SPARSE_BLOCK_TILES) + t.y) * uint(VF_SPARSE_BLOCK_TILES) +
                          t.x];
        if (tile == VF_SPARSE_NONE) {
            return false;
        }
        g_tile.record = tile_records[VF_SPARSE_RECORD_UVEC4S * tile];
        if (!kOneChunk) {
            uvec4 more = tile_records[VF_SPARSE_RECORD_UVEC4S * tile + 1u];
            g_tile.masks = NodeMasks(g_tile.record.zw);
            g_tile.offsets = Words(more.xy);
            g_tile.materials = Words(more.zw);
        }
        g_tile.mask0 = node_mask(0u);
        return true;
    }
    if (level == 2u) {
        uint b = child_bit((u >> 4) & 3u);
        if (!has_bit(g_tile.mask0, b)) {
            return false;
        }
        g_node1 = node_offset(0u) + rank_below(g_tile.mask0, b);
        g_mask1 = node_mask(g_node1);
        return true;
    }
    if (level == 3u) {
        uint b = child_bit((u >> 2) & 3u);
        if (!has_bit(g_mask1, b)) {
            return false;
        }
        g_node2 = node_offset(g_node1) + rank_below(g_mask1, b);
        g_mask2 = node_mask(g_node2);
        return true;
    }
    g_bit = child_bit(u & 3u);
    return has_bit(g_mask2, g_bit);
}

// The material of the voxel the walk's last successful enter(kVoxelLevel, ...) found.
uint hit_material() {
    uint i = g_tile.record.y + node_offset(g_node2) + rank_below(g_mask2, g_bit);
    uint word = kOneChunk ? materials0[i >> 2] : g_tile.materials.words[i >> 2];
    return (word >> ((i & 3u) * 8u)) & 0xFFu;
}

// The material of cell c (0: empty or outside the world), looked up from the top, or from the
// 16^3 level when c lies in `tile` at tile coordinates `tile_at` (the hit's: most occlusion
// taps are there).
uint material_of(ivec3 c, ivec3 tile_at, Tile tile) {
    if (any(lessThan(c, ivec3(0))) || any(greaterThanEqual(c, ivec3(pc.dims.xyz)))) {
        return 0u;
    }
    uvec3 u = uvec3(c);
    uint level = 0u;
    if ((c >> 6) == tile_at) {
        g_tile = tile;
        level = 2u;
    }
    for (; level <= kVoxelLevel; ++level) {
        if (!enter(level, u)) {
            return 0u;
        }
    }
    return hit_material();
}

// The walk's crossing of the plane between cell c and c + s along one axis (s = +-1): the
// voxel walk's t_next of cell c, (c + max(s, 0) - start) / dir.
float crossing(int c, int s, float start, float inv) {
    return (float(c + max(s, 0)) - start) * inv;
}

// Whether a crossing at t on an axis that comes before the exit axis in the tie order
// (`first`) happens before the exit crossing at t_exit.
bool before(float t, float t_exit, bool first) {
    return t < t_exit || (t == t_exit && first);
}

// The cell along one axis stepped with s (+-1, not 0) where the voxel walk is when it makes the
// crossing at t_exit on another axis: c is where it is now, last the farthest cell it can have
// reached (the node's last along s). All crossings of this axis before t_exit are taken, in
// the tie order (first: this axis precedes the exit axis).
int advance(int c, int last, int s, float start, float dir, float inv, float t_exit, bool first) {
    int e = int(floor(start + dir * t_exit));  // a guess, off by a cell at most near a tie
    e = s > 0 ? clamp(e, c, last) : clamp(e, last, c);
    while (e != c && !before(crossing(e - s, s, start, inv), t_exit, first)) {
        e -= s;
    }
    while (e != last && before(crossing(e, s, start, inv), t_exit, first)) {
        e += s;
    }
    return e;
}

// Walks the ray o + t dir from where it enters the world until it hits a solid voxel (true:
// `cell`, the step `face` that entered it (0 when the ray started in it), the entry point
// `point` on that face, its material) or leaves the world (false). Counts node visits and
// exits.
bool trace(vec3 o, vec3 dir, out ivec3 cell, out ivec3 face, out vec3 point, out uint material,
           inout uint visits, inout uint exits) {
    ivec3 dims = ivec3(pc.dims.xyz);
    RayStart r;
    material = 0u;
    point = o;
    bool entered = clip_ray(o, dir, dims, r);
    cell = r.cell;
    face = r.face;
    if (!entered) {
        return false;
    }
    vec3 start = r.start, inv = r.inv;
    ivec3 stp = r.stp;
    bool stepped = false;
    uint level = 0u;
    for (;;) {
        if (kCount) {
            ++visits;
        }
        if (enter(level, uvec3(cell))) {
            if (level == kVoxelLevel) {
                break;
            }
            ++level;
            continue;
        }
        // Leave the empty node at `level` holding cell: the first of its exit planes crossed.
        int shift = level_shift(level);
        int size = 1 << shift;
        ivec3 lo = (cell >> shift) << shift;
        ivec3 last = lo + mix(ivec3(0), ivec3(size - 1), greaterThan(stp, ivec3(0)));
        vec3 t_exit = vec3(crossing(last.x, stp.x, start.x, inv.x),
                           crossing(last.y, stp.y, start.y, inv.y),
                           crossing(last.z, stp.z, start.z, inv.z));
        t_exit = mix(t_exit, vec3(kFar), equal(stp, ivec3(0)));
        bool bx = t_exit.x <= t_exit.y && t_exit.x <= t_exit.z;
        bool by = !bx && t_exit.y <= t_exit.z;
        ivec3 m = ivec3(bx, by, !bx && !by);
        ivec3 old = cell;
        if (size > 1) {
            float t = bx ? t_exit.x : (by ? t_exit.y : t_exit.z);
            if (!bx && stp.x != 0) {
                cell.x = advance(cell.x, last.x, stp.x, start.x, dir.x, inv.x, t, true);
            }
            if (!by && stp.y != 0) {
                cell.y = advance(cell.y, last.y, stp.y, start.y, dir.y, inv.y, t, bx ? false : true);
            }
            if ((bx || by) && stp.z != 0) {
                cell.z = advance(cell.z, last.z, stp.z, start.z, dir.z, inv.z, t, false);
            }
        }
        face = m * stp;
        cell = mix(cell, last + stp, bvec3(m));
        stepped = true;
        if (kCount) {
            ++exits;
        }
        if (any(lessThan(cell, ivec3(0))) || any(greaterThanEqual(cell, dims))) {
            return false;
        }
        // Continue at the coarsest level whose node differs from the one just left's.
        ivec3 changed = cell ^ old;
        int top = max(max(findMSB(changed.x), findMSB(changed.y)), findMSB(changed.z));
        level = top >= 9 ? 0u : (top >= 6 ? 1u : (top >= 4 ? 2u : (top >= 2 ? 3u : 4u)));
    }
    material = hit_material();
    if (stepped) {
        // Entered through the face it crossed: that plane's t.
        vec3 t_face = (vec3(cell + max(-stp, ivec3(0))) - start) * inv;
        float t_in = face.x != 0 ? t_face.x : (face.y != 0 ? t_face.y : t_face.z);
        point = start + dir * t_in;
    } else {
        point = start;
    }
    return true;
}

// Ambient occlusion of the face of solid `cell` with outward normal n, from the 64-trees: at
// heights k = 1..4 along n, the cell straight out and the four k cells aside along the face's
// axes (a 45 degree cone); the more of them are solid, the more the face is enclosed (nearer
// heights weigh more, as the dense ray marcher's taps). Call it right after the trace that hit
// `cell` (its tile is still the walk's).
float occlusion(ivec3 cell, ivec3 n) {
    const float weights[4] = float[4](0.4, 0.3, 0.2, 0.1);
    ivec3 t1 = n.x != 0 ? ivec3(0, 1, 0) : ivec3(1, 0, 0);
    ivec3 t2 = n.z != 0 ? ivec3(0, 1, 0) : ivec3(0, 0, 1);
    ivec3 tile_at = cell >> 6;
    Tile tile = g_tile;
    float sum = 0.0;
    for (int k = 1; k <= 4; ++k) {
        ivec3 c = cell + n * k;
        uint solid = uint(material_of(c, tile_at, tile) != 0u) +
                     uint(material_of(c + t1 * k, tile_at, tile) != 0u) +
                     uint(material_of(c - t1 * k, tile_at, tile) != 0u) +
                     uint(material_of(c + t2 * k, tile_at, tile) != 0u) +
                     uint(material_of(c - t2 * k, tile_at, tile) != 0u);
        sum += weights[k - 1] * float(solid) / 5.0;
    }
    return 1.0 - 0.7 * sum;
}

void main() {
    uvec2 pix = gl_GlobalInvocationID.xy;
    uint width = pc.image.x, height = pc.image.y;
    if (pix.x >= width || pix.y >= height) {
        return;
    }
    bool lit = (pc.image.z & VF_RAYMARCH_FLAG_LIT) != 0u;
    bool gradient = (pc.image.z & VF_RAYMARCH_FLAG_SKY_GRADIENT) != 0u;
    vec3 dir = pixel_ray(pix, width, height, pc.forward.xyz, pc.right.xyz, pc.up.xyz);
    ivec3 cell, face;
    vec3 point;
    uint material;
    uint visits = 0u, exits = 0u;
    bool hit = trace(pc.origin.xyz, dir, cell, face, point, material, visits, exits);
    if (kCount) {
        counters[pix.y * width + pix.x] = uvec2(visits, exits);
    }
    uint colour;
    if (hit) {
        uint rgba = palette[material];
        if (!lit) {
            colour = (rgba & 0x00FFFFFFu) | 0xFF000000u;
        } else {
            vec3 n = face != ivec3(0) ? -vec3(face) : -dir;
            vec3 base = srgb_to_linear(unpack_rgb(rgba));
            float diffuse = max(dot(n, kSun), 0.0);
            float ambient = 0.18 + 0.12 * n.y;
            if (face != ivec3(0)) {
                ivec3 out_n = -face;
                if (kShadows) {
                    ambient *= occlusion(cell, out_n);
                }
                // Sunlit unless the ray from just outside the face toward the sun hits a solid.
                if (kShadows && diffuse > 0.0) {
                    ivec3 c2, f2;
                    vec3 p2;
                    uint m2, v2 = 0u, e2 = 0u;
                    if (trace(point + vec3(out_n) * 0.01, kSun, c2, f2, p2, m2, v2, e2)) {
                        diffuse = 0.0;
                    }
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
        colour = swap_red_blue(colour);
    }
    imageStore(out_image, ivec2(pix), uvec4(colour, 0u, 0u, 0u));
}
