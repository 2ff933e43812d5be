// Monolithic kernel: dissertation section 4.7.3 (Algorithm 10), with correct synchronisation.
// The same per-chunk batch kernel regenerates the dirty chunks of the other chunk-local
// algorithms after edits (`mode`: brute force, FIM alone, JFA alone, JFA + FIM).
//
// One work-group owns one chunk of the batch `chunks` (chunk indices, x fastest over the
// chunk grid). Chunk-local semantics make chunks independent, so the passes of JFA and FIM
// only need the group's own barrier: barrier(CLK_GLOBAL_MEM_FENCE) makes the group's global
// writes visible to the whole group, which is exactly the scope that must agree. (The
// dissertation's version synchronised 8x8x8 sub-blocks of a chunk that read each other's
// voxels.) Seeds ping-pong between seed_a and seed_b; FIM then relaxes in place in chunks
// inside the focus box [focus_lo, focus_hi] (inclusive, chunk coordinates) until a pass
// changes nothing; iterations[chunk] records the passes that changed something.
#define VF_MODE_JFA 1u        // seeds by JFA (else Algorithm 4's 0 / unreached)
#define VF_MODE_FIM_ALL 2u    // FIM in every chunk
#define VF_MODE_FIM_FOCUS 4u  // FIM in the focus chunks
#define VF_MODE_BRUTE 8u      // Algorithm 3 instead of all of the above

kernel void monolithic(global const uchar* vox, global uint* seed_a, global uint* seed_b,
                       global uint* dist, global const uchar* rgb, global OUT_T* out, uint4 d,
                       uint c, global const uint* chunks, uint4 focus_lo, uint4 focus_hi,
                       uint first_step, uint extra_passes, global uint* iterations, uint mode) {
    const uint chunk = chunks[get_group_id(0)];
    const uint4 grid = (d + (uint4)(c - 1u)) / (uint4)(c);
    const uint3 cc = vf_coords(chunk, grid);
    const uint3 lo = cc * (uint3)(c);
    const uint3 size = min(lo + (uint3)(c), d.xyz) - lo;
    const uint4 size4 = (uint4)(size, 1u);
    const uint m = size.x * size.y * size.z;
    const uint lid = get_local_id(0), lsize = get_local_size(0);

    if ((mode & VF_MODE_BRUTE) != 0) {
        // Algorithm 3: each voxel scans the chunk; the shell in closed form (brute.cl).
        for (uint k = lid; k < m; k += lsize) {
            const uint3 p = lo + vf_coords(k, size4);
            const uint i = vf_index(p, d);
            uint best = vox[i] != 0 ? 0u : vf_shell_distance(p, lo, lo + size, c);
            for (uint j = 0; j < m && best != 0; ++j) {
                const uint3 q = lo + vf_coords(j, size4);
                if (vox[vf_index(q, d)] != 0) {
                    best = min(best, vf_l1(p, q));
                }
            }
            dist[i] = best;
        }
    } else if ((mode & VF_MODE_JFA) != 0) {
        // Algorithm 4 (as seeds).
        for (uint k = lid; k < m; k += lsize) {
            const uint i = vf_index(lo + vf_coords(k, size4), d);
            seed_a[i] = vox[i] != 0 ? i : VF_NO_SEED;
        }
        barrier(CLK_GLOBAL_MEM_FENCE);

        // Algorithm 8: steps first_step ... 1, then JFA+1 / JFA+2 extra passes at 2 and 1.
        global uint* src = seed_a;
        global uint* dst = seed_b;
        const uint passes = (first_step == 0 ? 0u : 32u - clz(first_step)) + extra_passes;
        for (uint pass = 0; pass < passes; ++pass) {
            const uint regular = passes - extra_passes;
            const int step = pass < regular ? (int)(first_step >> pass)
                                            : (int)(1u << (passes - 1u - pass));
            for (uint k = lid; k < m; k += lsize) {
                const uint3 p = lo + vf_coords(k, size4);
                dst[vf_index(p, d)] = jfa_update(src, p, d, c, step);
            }
            barrier(CLK_GLOBAL_MEM_FENCE);
            global uint* t = src;
            src = dst;
            dst = t;
        }
        for (uint k = lid; k < m; k += lsize) {
            const uint3 p = lo + vf_coords(k, size4);
            const uint i = vf_index(p, d);
            dist[i] = jfa_distance(src[i], p, d, c);
        }
    } else {
        // Algorithm 4.
        for (uint k = lid; k < m; k += lsize) {
            const uint i = vf_index(lo + vf_coords(k, size4), d);
            dist[i] = vox[i] != 0 ? 0u : VF_INF;
        }
    }
    barrier(CLK_GLOBAL_MEM_FENCE);

    // Algorithm 9 (inside the focus). Three change flags in rotation: pass t sets flag t % 3,
    // all read it after the pass's barrier, and flag (t + 2) % 3 (last read in pass t - 1,
    // next set in pass t + 2) is cleared in between, so no clear can race a set or a read.
    local int flags[3];
    uint changed_passes = 0;
    const bool in_focus = all(cc >= focus_lo.xyz) && all(cc <= focus_hi.xyz);
    if ((mode & VF_MODE_FIM_ALL) != 0 || ((mode & VF_MODE_FIM_FOCUS) != 0 && in_focus)) {
        if (lid < 3) {
            flags[lid] = 0;
        }
        barrier(CLK_LOCAL_MEM_FENCE);
        const uint bound = size.x + size.y + size.z;  // > the largest distance in the chunk
        for (uint t = 0; t < bound; ++t) {
            bool changed = false;
            for (uint k = lid; k < m; k += lsize) {
                changed |= fim_relax(dist, lo + vf_coords(k, size4), d, c);
            }
            if (changed) {
                atomic_or(&flags[t % 3], 1);
            }
            barrier(CLK_LOCAL_MEM_FENCE | CLK_GLOBAL_MEM_FENCE);
            const bool again = flags[t % 3] != 0;
            if (lid == 0) {
                flags[(t + 2) % 3] = 0;
            }
            if (!again) {
                break;
            }
            ++changed_passes;
        }
    }
    for (uint k = lid; k < m; k += lsize) {
        const uint i = vf_index(lo + vf_coords(k, size4), d);
        out[i] = vf_encode(dist[i], vox[i], rgb);
    }
    if (lid == 0) {
        iterations[chunk] = changed_passes;
    }
}
