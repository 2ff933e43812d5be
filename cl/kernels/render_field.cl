// The ray marcher's compact field (layout.h VF_COMPACT_*) from the exact field in u8 (L1
// distances saturated at 255, 0 on solids) and the world's voxels: one work-item per voxel,
// written into z-slabs of SLAB_DEPTH slices that start slab_stride elements apart, so that
// each slab is one Vulkan storage-buffer binding inside a single shared allocation.
__kernel void to_compact(__global const uchar* restrict dist, __global const uchar* restrict vox,
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
