// Jump Flooding (Rong & Tan 2006): dissertation section 4.4 (Algorithm 6) and 4.7.1
// (Algorithm 8), propagating nearest-solid coordinates over 26 neighbours, not distances.

// Seeds are linear voxel indices of solid voxels (VF_NO_SEED: none yet).
kernel void jfa_init(global const uchar* vox, global uint* seeds, uint n) {
    const uint i = get_global_id(0);
    if (i < n) {
        seeds[i] = vox[i] != 0 ? i : VF_NO_SEED;
    }
}

// Keeps (best, best_d) the nearer seed of the two; ties go to the smaller index, so the
// result does not depend on the order candidates are seen (deterministic output).
inline void jfa_consider(uint s, uint3 p, uint4 d, uint* best, uint* best_d) {
    if (s == VF_NO_SEED) {
        return;
    }
    const uint dist = vf_l1(p, vf_coords(s, d));
    if (dist < *best_d || (dist == *best_d && s < *best)) {
        *best = s;
        *best_d = dist;
    }
}

// The nearest seed among p's own and those of its 26 neighbours `step` voxels away inside
// p's chunk (or the world).
inline uint jfa_update(global const uint* in, uint3 p, uint4 d, uint c, int step) {
    const uint i = vf_index(p, d);
    uint best = in[i];
    if (best == i) {
        return best;  // a solid voxel is its own nearest solid
    }
    uint best_d = best == VF_NO_SEED ? VF_INF : vf_l1(p, vf_coords(best, d));
    const uint3 lo = vf_chunk_lo(p, c);
    const uint3 hi = vf_chunk_hi(p, d, c);
    const int3 pi = convert_int3(p);
    for (int dz = -1; dz <= 1; ++dz) {
        for (int dy = -1; dy <= 1; ++dy) {
            for (int dx = -1; dx <= 1; ++dx) {
                const int3 q = pi + (int3)(dx, dy, dz) * step;
                if ((dx | dy | dz) != 0 && vf_inside(q, lo, hi)) {
                    jfa_consider(in[vf_index(convert_uint3(q), d)], p, d, &best, &best_d);
                }
            }
        }
    }
    return best;
}

// Algorithm 6: one pass at `step`, ping-pong buffers.
kernel void jfa_step(global const uint* in, global uint* out, uint4 d, uint c, int step) {
    const uint3 p = (uint3)(get_global_id(0), get_global_id(1), get_global_id(2));
    if (p.x < d.x && p.y < d.y && p.z < d.z) {
        out[vf_index(p, d)] = jfa_update(in, p, d, c, step);
    }
}

// The distance to the seed found, or to the chunk's padding shell when nearer.
inline uint jfa_distance(uint seed, uint3 p, uint4 d, uint c) {
    const uint to_seed = seed == VF_NO_SEED ? VF_INF : vf_l1(p, vf_coords(seed, d));
    return min(to_seed, vf_shell_distance(p, vf_chunk_lo(p, c), vf_chunk_hi(p, d, c), c));
}

kernel void jfa_dist(global const uint* seeds, global uint* dist, uint4 d, uint c) {
    const uint3 p = (uint3)(get_global_id(0), get_global_id(1), get_global_id(2));
    if (p.x < d.x && p.y < d.y && p.z < d.z) {
        const uint i = vf_index(p, d);
        dist[i] = jfa_distance(seeds[i], p, d, c);
    }
}
