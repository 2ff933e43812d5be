// The ray marcher's compact field (layout.h VF_COMPACT_*) from the exact field in u16 (L1
// distances saturated at 65535, 0 on solids) and the world's voxels: one work-item per voxel,
// written into z-slabs of SLAB_DEPTH slices that start slab_stride elements apart, so that
// each slab is one Vulkan storage-buffer binding inside a single shared allocation.
__kernel void to_compact(__global const ushort* restrict dist, __global const uchar* restrict vox,
                         __global ushort* restrict out, ulong plane, uint slab_depth,
                         ulong slab_stride, ulong n) {
    const ulong i = get_global_id(0);
    if (i >= n) {
        return;
    }
    const ulong slab = i / plane / slab_depth;
    const ulong local_i = i - slab * slab_depth * plane;
    const uint d = min((uint)dist[i], VF_COMPACT_DISTANCE_MAX);
    out[slab * slab_stride + local_i] =
        (ushort)((d << VF_COMPACT_DISTANCE_SHIFT) | (vox[i] & VF_COMPACT_MATERIAL_MASK));
}

// The ray marcher's coarse table (layout.h VF_RAYMARCH_BLOCK): per block, the minimum of the
// u16 distances over its voxels, a lower bound of every voxel's true distance in the block.
__kernel void block_min(__global const ushort* restrict dist, __global uint* restrict out,
                        uint4 d) {
    const uint3 b = (uint3)(get_global_id(0), get_global_id(1), get_global_id(2));
    const uint3 nb = (d.xyz + (uint3)(VF_RAYMARCH_BLOCK - 1)) / (uint3)(VF_RAYMARCH_BLOCK);
    if (b.x >= nb.x || b.y >= nb.y || b.z >= nb.z) {
        return;
    }
    const uint3 lo = b * (uint3)(VF_RAYMARCH_BLOCK);
    const uint3 hi = min(lo + (uint3)(VF_RAYMARCH_BLOCK), d.xyz);
    uint m = 0xFFFFFFFFu;
    for (uint z = lo.z; z < hi.z; ++z) {
        for (uint y = lo.y; y < hi.y; ++y) {
            const ulong row = ((ulong)z * d.y + y) * d.x;
            for (uint x = lo.x; x < hi.x; ++x) {
                m = min(m, (uint)dist[row + x]);
            }
        }
    }
    out[(b.z * nb.y + b.y) * nb.x + b.x] = m;
}
