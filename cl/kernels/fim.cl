// Fast Iterative Method: dissertation section 4.3 (Algorithms 4 and 5) and 4.7.2 (Algorithm 9).

// Algorithm 4: solids 0, air unreached.
kernel void fim_init(global const uchar* vox, global uint* dist, uint n) {
    const uint i = get_global_id(0);
    if (i < n) {
        dist[i] = vox[i] != 0 ? 0u : VF_INF;
    }
}

// One relaxation of voxel p (Algorithm 5): the smallest face neighbour + 1, a neighbour
// outside the chunk counting as solid (chunk-local) or as absent (global). Updates in
// place and returns whether the value dropped. Values only ever decrease and every value
// is the length of a real path to a solid, so concurrent readers see either the old or the
// new value, both upper bounds: the fixed point (exact distance) is unique.
inline bool fim_relax(global uint* dist, uint3 p, uint4 d, uint c) {
    const uint i = vf_index(p, d);
    const uint v = dist[i];
    if (v == 0) {
        return false;
    }
    const uint3 lo = vf_chunk_lo(p, c);
    const uint3 hi = vf_chunk_hi(p, d, c);
    const uint outside = c == 0 ? VF_INF : 1u;
    const uint plane = d.x * d.y;
    uint best = v;
    best = min(best, p.x > lo.x ? dist[i - 1] + 1u : outside);
    best = min(best, p.x + 1 < hi.x ? dist[i + 1] + 1u : outside);
    best = min(best, p.y > lo.y ? dist[i - d.x] + 1u : outside);
    best = min(best, p.y + 1 < hi.y ? dist[i + d.x] + 1u : outside);
    best = min(best, p.z > lo.z ? dist[i - plane] + 1u : outside);
    best = min(best, p.z + 1 < hi.z ? dist[i + plane] + 1u : outside);
    if (best < v) {
        dist[i] = best;
        return true;
    }
    return false;
}

// One FIM pass over the box [box_lo, box_lo + box_size) (the whole world, or the focus
// chunks of `lod`), work-items striding over it so that the launch size stays small.
// changes[it] counts the work-groups that lowered some voxel in pass `it`. The host may
// enqueue every pass up front (one submission): a pass whose predecessor changed nothing
// returns at once, so the chain stops doing work as soon as the field has converged. That
// test is uniform across the launch (the previous kernel has completed: in-order queue).
kernel void fim_step(global uint* dist, uint4 d, uint c, uint4 box_lo, uint4 box_size,
                     volatile global uint* changes, uint it) {
    if (it > 0 && changes[it - 1] == 0) {
        return;
    }
    local int group_changed;
    if (get_local_id(0) == 0) {
        group_changed = 0;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    const uint n = box_size.x * box_size.y * box_size.z;
    bool changed = false;
    for (uint k = get_global_id(0); k < n; k += get_global_size(0)) {
        const uint3 p = box_lo.xyz + vf_coords(k, box_size);
        changed |= fim_relax(dist, p, d, c);
    }
    if (changed) {
        atomic_or(&group_changed, 1);
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    if (get_local_id(0) == 0 && group_changed != 0) {
        atomic_inc(&changes[it]);
    }
}
