// Brute force: dissertation section 4.1 (Algorithm 1) and section 4.2 (Algorithm 3, chunks).

// Algorithm 1, global semantics: every empty voxel scans every voxel of the world. The group
// stages whole x rows of occupancy in local memory (`tile`, `rows` rows at a time) so that
// each voxel is read from global memory once per group, not once per work-item.
kernel void brute_global(global const uchar* vox, global uint* dist, uint4 d, uint rows,
                         local uchar* tile) {
    const uint n = d.x * d.y * d.z;
    const uint i = get_global_id(0);
    const bool valid = i < n;
    const uint3 p = vf_coords(valid ? i : 0, d);
    uint best = valid && vox[i] != 0 ? 0u : VF_INF;
    const uint total_rows = d.y * d.z;
    for (uint r0 = 0; r0 < total_rows; r0 += rows) {
        const uint count = min(rows, total_rows - r0) * d.x;
        barrier(CLK_LOCAL_MEM_FENCE);
        for (uint j = get_local_id(0); j < count; j += get_local_size(0)) {
            tile[j] = vox[r0 * d.x + j];
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        if (best != 0) {
            for (uint r = 0; r < count / d.x; ++r) {
                const uint row = r0 + r;
                const uint yz = abs_diff(row % d.y, p.y) + abs_diff(row / d.y, p.z);
                const local uchar* line = tile + r * d.x;
                for (uint x = 0; x < d.x; ++x) {
                    if (line[x] != 0) {
                        best = min(best, yz + abs_diff(x, p.x));
                    }
                }
            }
        }
    }
    if (valid) {
        dist[i] = best;
    }
}

// Algorithm 3, chunk-local semantics: every empty voxel scans its chunk. Algorithm 2 counts
// the one-voxel padding shell as solid; its nearest shell voxel is at the closed-form
// vf_shell_distance, which is exactly what scanning the shell would find.
kernel void brute_chunked(global const uchar* vox, global uint* dist, uint4 d, uint c) {
    const uint3 p = (uint3)(get_global_id(0), get_global_id(1), get_global_id(2));
    if (p.x >= d.x || p.y >= d.y || p.z >= d.z) {
        return;
    }
    const uint i = vf_index(p, d);
    if (vox[i] != 0) {
        dist[i] = 0;
        return;
    }
    const uint3 lo = vf_chunk_lo(p, c);
    const uint3 hi = vf_chunk_hi(p, d, c);
    uint best = vf_shell_distance(p, lo, hi, c);
    for (uint z = lo.z; z < hi.z; ++z) {
        for (uint y = lo.y; y < hi.y; ++y) {
            const uint yz = abs_diff(y, p.y) + abs_diff(z, p.z);
            const uint row = (z * d.y + y) * d.x;
            for (uint x = lo.x; x < hi.x; ++x) {
                if (vox[row + x] != 0) {
                    best = min(best, yz + abs_diff(x, p.x));
                }
            }
        }
    }
    dist[i] = best;
}
