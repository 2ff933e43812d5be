// The ray marcher's compact field (layout.h VF_COMPACT_*) from a distance field and the
// world's voxels, and its coarse table. The field's element type and how its distance is read
// come from the build options: VF_SRC_T (uchar, ushort, uint) and VF_SRC_SHIFT / VF_SRC_MASK
// (packed32: bits 15..8). Distances are saturated at the source format's maximum, 0 on solids.
#define SRC_DISTANCE(v) (((uint)(v) >> VF_SRC_SHIFT) & VF_SRC_MASK)

// The field's distance d (in the units of its voxel spacing) as a lower bound of the distance in
// voxels, which the ray marcher steps by: with s the largest spacing, every metric of the scaled
// offset is at most s times the metric of the voxel offset, so floor(d / s) never over-states it.
// inv_step is 1 / s rounded down (exactly 1 for unit spacing).
inline uint voxel_steps(uint d, float inv_step) {
    return inv_step == 1.0f ? d : (uint)floor((float)d * inv_step);
}

// One work-item per voxel of the box at `lo` of `size` voxels (count = its volume; x fastest),
// written into z-slabs of slab_depth slices that start slab_stride elements apart, so that each
// slab is one Vulkan storage-buffer binding inside a single shared allocation.
__kernel void to_compact(__global const VF_SRC_T* restrict dist, __global const uchar* restrict vox,
                         __global ushort* restrict out, uint4 d, uint slab_depth, ulong slab_stride,
                         uint4 lo, uint4 size, float inv_step) {
    // One work-item per voxel of the box at `lo` of `size` voxels: (x, y, z) from the 3-D
    // range (no divisions), x padded to the work-group size.
    const uint gx = (uint)get_global_id(0);
    if (gx >= size.x) {
        return;
    }
    const uint x = lo.x + gx, y = lo.y + (uint)get_global_id(1), z = lo.z + (uint)get_global_id(2);
    const ulong i = ((ulong)z * d.y + y) * d.x + x;
    const uint slab = z / slab_depth;
    const ulong local_i = ((ulong)(z - slab * slab_depth) * d.y + y) * d.x + x;
    // An empty voxel is at least one voxel from every solid, whatever its scaled distance
    // rounded to (0 would read as solid).
    const uint steps = voxel_steps(SRC_DISTANCE(dist[i]), inv_step);
    const uint dd = min(vox[i] == 0 ? max(steps, 1u) : steps, (uint)VF_COMPACT_DISTANCE_MAX);
    out[slab * slab_stride + local_i] =
        (ushort)((dd << VF_COMPACT_DISTANCE_SHIFT) | (vox[i] & VF_COMPACT_MATERIAL_MASK));
}

// The ray marcher's coarse table (layout.h VF_RAYMARCH_BLOCK), which starts `base` words into
// `out`: one work-item per block of the block box at `lo` of `size` blocks (count = its
// volume), the minimum of the distances over the block's voxels, a lower bound of every
// voxel's true distance in the block.
__kernel void block_min(__global const VF_SRC_T* restrict dist, __global uint* restrict out,
                        uint4 d, uint4 lo, uint4 size, ulong count, float inv_step, ulong base) {
    const ulong k = get_global_id(0);
    if (k >= count) {
        return;
    }
    const ulong row = k / size.x;
    const uint3 b = (uint3)(lo.x + (uint)(k - row * size.x), lo.y + (uint)(row % size.y),
                            lo.z + (uint)(row / size.y));
    const uint3 nb = (d.xyz + (uint3)(VF_RAYMARCH_BLOCK - 1)) / (uint3)(VF_RAYMARCH_BLOCK);
    const uint3 first = b * (uint3)(VF_RAYMARCH_BLOCK);
    const uint3 last = min(first + (uint3)(VF_RAYMARCH_BLOCK), d.xyz);
    uint m = 0xFFFFFFFFu;
    for (uint z = first.z; z < last.z; ++z) {
        for (uint y = first.y; y < last.y; ++y) {
            const ulong r = ((ulong)z * d.y + y) * d.x;
            for (uint x = first.x; x < last.x; ++x) {
                m = min(m, voxel_steps(SRC_DISTANCE(dist[r + x]), inv_step));
            }
        }
    }
    out[base + (b.z * nb.y + b.y) * nb.x + b.x] = m;
}
