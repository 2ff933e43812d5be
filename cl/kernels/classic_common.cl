// Shared pieces of the dissertation's generators (brute.cl, fim.cl, jfa.cl, monolithic.cl).
//
// Domain: `d` is the world (x, y, z; w unused); `c` is the chunk size, a power of two, or 0
// for global semantics. Chunk-local (c > 0, dissertation section 4.2.1): each voxel sees only
// its chunk (clipped to the world) and everything outside the chunk counts as solid.
// Global (c == 0): the whole world, outside it empty (DESIGN §3).
//
// Distances are uint, VF_INF for "no solid reached"; VF_INF + 1 does not overflow and never
// wins a min against VF_INF. Build options: OUT_T (uchar, ushort or uint), OUT_MAX (its
// maximum distance) and PACKED (1 for packed32: (min(d,255) << 8) | rgb332).

#define VF_INF 0x7FFFFFFFu
#define VF_NO_SEED 0xFFFFFFFFu

inline uint3 vf_coords(uint i, uint4 d) {
    const uint row = i / d.x;
    return (uint3)(i - row * d.x, row % d.y, row / d.y);
}

inline uint vf_index(uint3 p, uint4 d) {
    return (p.z * d.y + p.y) * d.x + p.x;
}

// First voxel of the chunk holding p, and one past its last (clipped to the world).
inline uint3 vf_chunk_lo(uint3 p, uint c) {
    return c == 0 ? (uint3)(0) : p & (uint3)(~(c - 1u));
}

inline uint3 vf_chunk_hi(uint3 p, uint4 d, uint c) {
    return c == 0 ? d.xyz : min(vf_chunk_lo(p, c) + (uint3)(c), d.xyz);
}

inline uint vf_l1(uint3 a, uint3 b) {
    const uint3 diff = abs_diff(a, b);
    return diff.x + diff.y + diff.z;
}

// Distance to the nearest voxel of the chunk's solid padding shell (VF_INF when global).
inline uint vf_shell_distance(uint3 p, uint3 lo, uint3 hi, uint c) {
    if (c == 0) {
        return VF_INF;
    }
    const uint3 below = p - lo + (uint3)(1);
    const uint3 above = hi - p;
    const uint3 m = min(below, above);
    return min(m.x, min(m.y, m.z));
}

inline bool vf_inside(int3 q, uint3 lo, uint3 hi) {
    return q.x >= (int)lo.x && q.y >= (int)lo.y && q.z >= (int)lo.z && q.x < (int)hi.x &&
           q.y < (int)hi.y && q.z < (int)hi.z;
}

inline OUT_T vf_encode(uint dist, uchar voxel, global const uchar* rgb) {
#if PACKED
    return (min(dist, VF_PACKED_DISTANCE_MAX) << VF_PACKED_DISTANCE_SHIFT) |
           (voxel != 0 ? (uint)rgb[voxel] : 0u);
#else
    return (OUT_T)(dist >= VF_INF ? OUT_MAX : min(dist, (uint)OUT_MAX));
#endif
}

// Distances to the output format: saturate, never wrap.
kernel void encode(global const uint* dist, global const uchar* vox, global const uchar* rgb,
                   global OUT_T* out, uint n) {
    const uint i = get_global_id(0);
    if (i < n) {
        out[i] = vf_encode(dist[i], vox[i], rgb);
    }
}
