// Sparse worlds' bounded fields (cl/src/sparse_field.cpp): scatters the transformed blocks'
// interiors (gathered by sparse_world.cl's gather from a tile grid of 64-trees, the
// implicit-surface rendering blog's contrees) into 64^3 field tiles, and takes each 16^3
// node's minimum for ray skipping.
// The tree's constants and leaf lookup are sparse_tree.cl's, compiled before this source.
// Build options: ELEM (the field's element type), KEY_KIND (how KEY(v) reads a value's
// distance to the nearest solid, comparable in ELEM: 0 the value, 1 packed32's distance
// byte, 2 a signed value's positive part), ELEM_DOUBLE (1 for f64).

#if ELEM_DOUBLE
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#endif

#if KEY_KIND == 1
#define KEY(v) ((v) >> 8)
#elif KEY_KIND == 2
#define KEY(v) ((v) > (ELEM)0 ? (v) : (ELEM)0)
#else
#define KEY(v) (v)
#endif

#define VEC_(t, n) t##n
#define VEC(t, n) VEC_(t, n)
typedef VEC(ELEM, 16) ELEM16;
typedef VEC(ELEM, 8) ELEM8;
typedef VEC(ELEM, 4) ELEM4;
typedef VEC(ELEM, 2) ELEM2;

// KEY of 16 values at once (the same values as KEY: +0 for every value not above 0).
#if KEY_KIND == 1
#define KEY16(v) ((v) >> (ELEM16)8)
#elif KEY_KIND == 2
#define KEY16(v) select((ELEM16)0, (v), (v) > (ELEM16)0)
#else
#define KEY16(v) (v)
#endif

// One work-item per row (along x) of the largest job region (sy x sz rows, stacked along z
// per job): copies the transformed block's values into the field tiles that hold them. A
// job: its region's first voxel, tile span and first entry in `slots` (per tile, x
// fastest, its field slot); `regions` holds per job the region's size and the block's first
// voxel (6 longs).
__kernel void scatter(__global const ELEM* restrict field, __global ELEM* restrict pool,
                      __global const long* restrict jobs, __global const long* restrict regions,
                      __global const uint* restrict slots, uint bx, uint by, uint bz, uint sy,
                      uint sz) {
    const uint y = (uint)get_global_id(0);
    const size_t gz = get_global_id(1);
    const size_t j = gz / sz;
    const uint z = (uint)(gz - j * sz);
    __global const long* job = jobs + 8 * j;
    __global const long* reg = regions + 6 * j;
    if (y >= sy || y >= reg[1] || z >= reg[2]) {
        return;
    }
    const long py = job[1] + y, pz = job[2] + z;
    __global const ELEM* in =
        field + ((j * bz + (size_t)(pz - reg[5])) * by + (size_t)(py - reg[4])) * bx;
    const long nt = job[6];
    const long ntx = nt & 0xFFFF, nty = (nt >> 16) & 0xFFFF;
    const long ry = (py >> 6) - job[4], rz = (pz >> 6) - job[5];
    const size_t row = (size_t)(((pz & 63) * TILE + (py & 63)) * TILE);
    for (long px = job[0]; px < job[0] + reg[0];) {
        const long end = min(job[0] + reg[0], (px | 63) + 1);
        const size_t slot = slots[job[7] + (rz * nty + ry) * ntx + ((px >> 6) - job[3])];
        __global ELEM* dst = pool + slot * TILE_VOXELS + row;
        for (; px < end; ++px) {
            dst[px & 63] = in[px - reg[3]];
        }
    }
}

// scatter with one work-item per voxel (global ids x, y and job * sz + z of the largest region,
// sx x sy x sz): the GPU layout's, where neighbouring work-items copy neighbouring values.
__kernel void scatter_voxels(__global const ELEM* restrict field, __global ELEM* restrict pool,
                             __global const long* restrict jobs,
                             __global const long* restrict regions,
                             __global const uint* restrict slots, uint bx, uint by, uint bz,
                             uint sx, uint sy, uint sz) {
    const uint x = (uint)get_global_id(0), y = (uint)get_global_id(1);
    const size_t gz = get_global_id(2);
    const size_t j = gz / sz;
    const uint z = (uint)(gz - j * sz);
    __global const long* job = jobs + 8 * j;
    __global const long* reg = regions + 6 * j;
    if (x >= sx || y >= sy || x >= reg[0] || y >= reg[1] || z >= reg[2]) {
        return;
    }
    const long px = job[0] + x, py = job[1] + y, pz = job[2] + z;
    const long nt = job[6];
    const long ntx = nt & 0xFFFF, nty = (nt >> 16) & 0xFFFF;
    const size_t slot = slots[job[7] + (((pz >> 6) - job[5]) * nty + ((py >> 6) - job[4])) * ntx +
                              ((px >> 6) - job[3])];
    pool[slot * TILE_VOXELS + (size_t)(((pz & 63) * TILE + (py & 63)) * TILE + (px & 63))] =
        field[((j * bz + (size_t)(pz - reg[5])) * by + (size_t)(py - reg[4])) * bx +
              (size_t)(px - reg[3])];
}

// A work-item per voxel (global ids x, y, z): field tile `slot` set to `value`. A kernel, not
// clEnqueueFillBuffer: NVIDIA's driver (580) faults filling a pool at offsets past 2 GiB.
__kernel void fill_slot(__global ELEM* restrict pool, ulong slot, ELEM value) {
    pool[slot * TILE_VOXELS +
         (get_global_id(2) * TILE + get_global_id(1)) * TILE + get_global_id(0)] = value;
}

// The least KEY of a row of 16 values, by halves.
inline ELEM row_least(ELEM16 v) {
    const ELEM16 k16 = KEY16(v);
    const ELEM8 k8 = min(k16.lo, k16.hi);
    const ELEM4 k4 = min(k8.lo, k8.hi);
    const ELEM2 k2 = min(k4.lo, k4.hi);
    return min(k2.x, k2.y);
}

// The least of the 64 work-items' `best` (a work-group of 64), written to minima[at] by the first.
inline void store_group_least(__local ELEM* least, ELEM best, __global ELEM* minima, size_t at) {
    const uint lid = (uint)get_local_id(0);
    least[lid] = best;
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint step = 32; step > 0; step >>= 1) {
        if (lid < step) {
            least[lid] = least[lid + step] < least[lid] ? least[lid + step] : least[lid];
        }
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    if (lid == 0) {
        minima[at] = least[0];
    }
}

// The listed node of a work-group of node_minima or scatter_minima (global id 1: list index *
// 64 + node): its slot, its first voxel (tile-local x0, y0, z0; world ox, oy, oz) and its voxels
// inside the world, [0, n) along each axis (a tile cut by the world's edge holds no values
// beyond it). False where the group has nothing to do (past the list, or a node not set in
// `nodes`).
typedef struct {
    size_t slot;
    uint node, x0, y0, z0, nx, ny, nz;
    long ox, oy, oz;
} ListedNode;

inline bool listed_node(__global const uint* restrict slots, __global const uint* restrict tiles,
                        uint count, __global const ulong* restrict nodes, uint wx, uint wy,
                        uint wz, ListedNode* n) {
    const size_t i = get_global_id(1);
    if (i >= (size_t)count * 64) {
        return false;
    }
    n->node = (uint)(i % 64);
    if ((nodes[i / 64] >> n->node & 1ul) == 0) {
        return false;
    }
    __global const uint* t = tiles + 3 * (i / 64);
    n->slot = slots[i / 64];
    n->x0 = (n->node & 3) * 16;
    n->y0 = ((n->node >> 2) & 3) * 16;
    n->z0 = (n->node >> 4) * 16;
    n->ox = (long)t[0] * TILE + n->x0;
    n->oy = (long)t[1] * TILE + n->y0;
    n->oz = (long)t[2] * TILE + n->z0;
    n->nx = (uint)clamp((long)wx - n->ox, 0l, 16l);
    n->ny = (uint)clamp((long)wy - n->oy, 0l, 16l);
    n->nz = (uint)clamp((long)wz - n->oz, 0l, 16l);
    return true;
}

// A work-group of 64 work-items per 16^3 node of the listed slots (global ids 0: 0..63, 1: list
// index * 64 + node; listed_node): the least KEY over its voxels inside the world, starting from
// the far value, which no value exceeds; each
// work-item takes 4 rows of 16, then the group's least. `tiles`: per listed slot its tile's
// coordinates (3 uints). Written per slot into `minima`, which stays on the device. Only the
// nodes set in `nodes` (per listed slot, bit z << 4 | y << 2 | x) are computed; the others keep
// their minima.
__kernel void node_minima(__global const ELEM* restrict pool, __global const uint* restrict slots,
                          __global const uint* restrict tiles, uint count,
                          __global ELEM* restrict minima, ELEM far, uint wx, uint wy, uint wz,
                          __global const ulong* restrict nodes) {
    __local ELEM least[64];
    const uint lid = (uint)get_local_id(0);
    ListedNode n;
    if (!listed_node(slots, tiles, count, nodes, wx, wy, wz, &n)) {
        return;  // the whole group
    }
    __global const ELEM* tile = pool + n.slot * TILE_VOXELS;
    ELEM best = KEY(far);
    // Rows lid, lid + 64, lid + 128, lid + 192 of the node's 256 (y fastest).
    for (uint r = lid; r < 256; r += 64) {
        const uint y = r & 15, z = r >> 4;
        if (y < n.ny && z < n.nz) {
            __global const ELEM* row = tile + ((n.z0 + z) * TILE + n.y0 + y) * TILE + n.x0;
            if (n.nx == 16) {
                // A whole row in one aligned load (x0 is a multiple of 16).
                const ELEM k = row_least(*(__global const ELEM16*)row);
                best = k < best ? k : best;
            } else {
                for (uint x = 0; x < n.nx; ++x) {
                    const ELEM k = KEY(row[x]);
                    best = k < best ? k : best;
                }
            }
        }
    }
    store_group_least(least, best, minima, n.slot * 64 + n.node);
}

// scatter and node_minima in one pass, for one block's region whose every voxel lies in a
// listed node (an edit's single block: the host lists the nodes the region overlaps). Work-groups
// as node_minima's; a voxel of the region is copied from the transformed block `field` (bx x by
// voxels a slice) into the pool and taken from there, every other voxel of the node read from
// the pool. `region`: its first voxel, its size and the block's first voxel (3 longs each).
__kernel void scatter_minima(__global const ELEM* restrict field, __global ELEM* restrict pool,
                             __global const long* restrict region, uint bx, uint by,
                             __global const uint* restrict slots,
                             __global const uint* restrict tiles, uint count,
                             __global ELEM* restrict minima, ELEM far, uint wx, uint wy, uint wz,
                             __global const ulong* restrict nodes) {
    __local ELEM least[64];
    const uint lid = (uint)get_local_id(0);
    ListedNode n;
    if (!listed_node(slots, tiles, count, nodes, wx, wy, wz, &n)) {
        return;  // the whole group
    }
    // The region's voxels of this node along x: [ax, ex) of the node's [0, nx).
    const uint ax = (uint)clamp(region[0] - n.ox, 0l, (long)n.nx);
    const uint ex = (uint)clamp(region[0] + region[3] - n.ox, (long)ax, (long)n.nx);
    __global ELEM* tile = pool + n.slot * TILE_VOXELS;
    ELEM best = KEY(far);
#pragma unroll
    for (uint j = 0; j < 4; ++j) {
        const uint r = lid + 64 * j;  // rows lid, lid + 64, lid + 128, lid + 192 (y fastest)
        const uint y = r & 15, z = r >> 4;
        if (y < n.ny && z < n.nz) {
            __global ELEM* row = tile + ((n.z0 + z) * TILE + n.y0 + y) * TILE + n.x0;
            const long py = n.oy + y, pz = n.oz + z;
            const bool inside = py >= region[1] && py < region[1] + region[4] &&
                                pz >= region[2] && pz < region[2] + region[5] && ax < ex;
            // This row's first voxel in the block (where inside).
            __global const ELEM* in =
                inside ? field + ((size_t)(pz - region[8]) * by + (size_t)(py - region[7])) * bx +
                             (size_t)(n.ox - region[6])
                       : field;
            if (n.nx == 16) {
                // A whole row (x0 is a multiple of 16): from the block (unaligned loads), the
                // pool (one aligned load) or both, blended, and stored as one aligned vector.
                // The loads are independent (unrolled), not one voxel's after another's store.
                ELEM16 v;
                if (inside && ax == 0 && ex == 16) {
                    v = vload16(0, in);
                } else {
                    v = *(__global const ELEM16*)row;
                    if (inside) {
                        ELEM part[16];
                        vstore16(v, 0, part);
#pragma unroll
                        for (uint x = 0; x < 16; ++x) {
                            if (x >= ax && x < ex) {
                                part[x] = in[x];
                            }
                        }
                        v = vload16(0, part);
                    }
                }
                if (inside) {
                    *(__global ELEM16*)row = v;
                }
                const ELEM k = row_least(v);
                best = k < best ? k : best;
            } else {
                // A row cut by the world's edge.
                for (uint x = 0; x < n.nx; ++x) {
                    ELEM v;
                    if (inside && x >= ax && x < ex) {
                        v = in[x];
                        row[x] = v;
                    } else {
                        v = row[x];
                    }
                    const ELEM k = KEY(v);
                    best = k < best ? k : best;
                }
            }
        }
    }
    store_group_least(least, best, minima, n.slot * 64 + n.node);
}

// The Manhattan sweep: a whole bounded L1 field of unit spacing computed in the field tiles
// themselves, with no dense blocks. Values are small integers in ELEM: an empty voxel's
// distance to the nearest solid (CAP = halo + 1 for "farther than the halo"), a solid voxel's
// 0 (unsigned fields) or minus its distance to the nearest empty voxel (signed fields, the
// world surrounded by empty space; -CAP for farther). `first` is the first slot of a launch,
// whose global id 2 counts slots (times 64 where a work-item takes voxels). A tile's neighbours
// (nbrs, 6 per slot: x-, x+, y-, y+, z-, z+) are a slot, NB_EMPTY (empty, no solid voxel within
// the halo) or NB_INSIDE (all solid, no empty voxel within the halo when signed).
#define NB_EMPTY 0xFFFFFFFFu
#define NB_INSIDE 0xFFFFFFFEu

// A work-item per 16 voxels along x (global ids x / 16, y, and slot - first) * 64 + z) of tile slot
// first + gid2 / 64: `solid` where the world's tree (refs: per slot the tile's node base, SLOT_REF
// in the slot buffers, NO_TILE not stored) holds a solid voxel (0, or -CAP when signed), CAP
// elsewhere.
__kernel void sweep_init(__global const ulong* restrict masks, __global const uint* restrict offsets,
                         __global const ulong* restrict slot_masks,
                         __global const uint* restrict slot_offsets,
                         __global const ulong* restrict refs, __global ELEM* restrict pool,
                         uint first, int cap, int solid) {
    const uint x0 = (uint)get_global_id(0) * 16, y = (uint)get_global_id(1);
    const size_t slot = first + get_global_id(2) / TILE;
    const uint z = (uint)(get_global_id(2) % TILE);
    ELEM v[16];
    for (uint k = 0; k < 16; ++k) {
        v[k] = (ELEM)cap;
    }
    ulong base = refs[slot];
    if (base != NO_TILE) {
        const bool in_slot = (base & SLOT_REF) != 0;
        base &= ~SLOT_REF;
        __global const ulong* m = in_slot ? slot_masks : masks;
        __global const uint* o = in_slot ? slot_offsets : offsets;
        const ulong root = m[base];
        for (uint leaf = 0; leaf < 4; ++leaf) {
            const ulong n4 = leaf_node(m, o, base, root, x0 + 4 * leaf, y, z);
            if (n4 == NO_TILE) {
                continue;
            }
            const uint row = (uint)(m[n4] >> ((z & 3) << 4 | (y & 3) << 2)) & 15u;
            for (uint k = 0; k < 4; ++k) {
                if ((row >> k & 1u) != 0) {
                    v[4 * leaf + k] = (ELEM)solid;
                }
            }
        }
    }
    // An aligned 16-element store (x0 is a multiple of 16): one wide store on GPUs.
    *(__global ELEM16*)(pool + slot * TILE_VOXELS + ((size_t)z * TILE + y) * TILE + x0) =
        vload16(0, v);
}

// One scan step over value v: `out` carries the distance to the nearest solid (a solid voxel,
// v <= 0, is one), `in` the distance to the nearest empty voxel (v > 0); returns what the voxel
// takes.
inline int sweep_step(int v, int* out, int* in) {
    *out = min(max(v, 0), *out + 1);
    *in = min(max(-v, 0), *in + 1);
    return v < 0 ? -*in : *out;
}

// The running values a scan toward a line carries in from its neighbour tile nb: over the
// neighbour's `halo` voxels nearest the line (stride apart from `at`; dir -1: the line's start).
inline void sweep_carry(__global const ELEM* restrict pool, uint nb, size_t at, size_t stride,
                        int dir, uint halo, int cap, int* out, int* in) {
    *out = nb == NB_INSIDE ? 0 : cap;
    *in = nb == NB_INSIDE ? cap : 0;
    if (nb == NB_INSIDE || nb == NB_EMPTY) {
        return;
    }
    __global const ELEM* t = pool + (size_t)nb * TILE_VOXELS + at;
    // Toward the line: from the farthest of the halo voxels to the nearest.
    for (uint k = halo; k-- > 0;) {
        const uint p = dir < 0 ? TILE - 1 - k : k;
        sweep_step((int)t[p * stride], out, in);
    }
}

// The offset within a tile of its line along `axis` (0 x, 1 y, 2 z) at (u, w), the two other
// axes' coordinates lowest first, and the line's element stride.
inline size_t tile_line(uint axis, size_t u, size_t w, size_t* stride) {
    *stride = axis == 0 ? 1 : axis == 1 ? TILE : TILE * TILE;
    return axis == 0 ? (w * TILE + u) * TILE : axis == 1 ? w * TILE * TILE + u : w * TILE + u;
}

// One 1-D pass of the exact L1 transform along `axis` (0 x, 1 y, 2 z), in place: a work-item per
// line of a tile (global ids 0 and 1 the two other axes, lowest first), a forward and a backward
// scan over the line and `halo` voxels of each neighbour. Neighbours are read while their own
// lines are rewritten: a value read is then this pass's result or the previous one, both at
// least the exact one and at most the previous one, and the 1-D L1 kernel's triangle
// inequality makes either give the same exact result.
__kernel void sweep_l1(__global ELEM* restrict pool, __global const uint* restrict nbrs, uint first,
                       uint axis, uint halo, int cap) {
    const size_t u = get_global_id(0), w = get_global_id(1);
    const size_t slot = first + get_global_id(2);
    size_t stride;
    const size_t at = tile_line(axis, u, w, &stride);
    __global ELEM* line = pool + slot * TILE_VOXELS + at;
    for (int dir = -1; dir <= 1; dir += 2) {
        int out, in;
        sweep_carry(pool, nbrs[6 * slot + 2 * axis + (dir > 0)], at, stride, dir, halo, cap, &out,
                    &in);
        for (uint step = 0; step < TILE; ++step) {
            const uint p = dir < 0 ? step : TILE - 1 - step;
            const int v = (int)line[p * stride];
            const int r = sweep_step(v, &out, &in);
            if (r != v) {
                line[p * stride] = (ELEM)r;
            }
        }
    }
}

// The running values a scan toward a line carries in from its neighbour tile nb, as
// sweep_carry, for GPUs: the halo voxels are loaded before any is scanned (along x, stride 1, in
// aligned 16-element loads), in code unrolled over the tile's 64 places. w holds them in scan
// order, so that every index into it is a constant once unrolled, whatever dir (a private array
// indexed at run time would live in memory).
inline void sweep_carry_loaded(__global const ELEM* restrict pool, uint nb, size_t at,
                               size_t stride, int dir, uint halo, int cap, int* out, int* in) {
    *out = nb == NB_INSIDE ? 0 : cap;
    *in = nb == NB_INSIDE ? cap : 0;
    if (nb == NB_INSIDE || nb == NB_EMPTY) {
        return;
    }
    __global const ELEM* t = pool + (size_t)nb * TILE_VOXELS + at;
    int w[TILE];  // w[k]: the value at place dir < 0 ? k : TILE - 1 - k
    if (stride == 1) {
#pragma unroll
        for (uint i = 0; i < TILE / 16; ++i) {
            const uint q = dir < 0 ? i : TILE / 16 - 1 - i;
            if (dir < 0 ? 16 * q + 16 > TILE - halo : 16 * q < halo) {
                ELEM e[16];
                vstore16(*(__global const ELEM16*)(t + 16 * q), 0, e);
#pragma unroll
                for (uint j = 0; j < 16; ++j) {
                    w[16 * i + j] = (int)(dir < 0 ? e[j] : e[15 - j]);
                }
            }
        }
    } else {
#pragma unroll
        for (uint k = 0; k < TILE; ++k) {
            const uint p = dir < 0 ? k : TILE - 1 - k;
            if (dir < 0 ? p >= TILE - halo : p < halo) {
                w[k] = (int)t[p * stride];
            }
        }
    }
    // Toward the line: from the farthest of the halo voxels to the nearest.
#pragma unroll
    for (uint k = 0; k < TILE; ++k) {
        const uint p = dir < 0 ? k : TILE - 1 - k;
        if (dir < 0 ? p >= TILE - halo : p < halo) {
            sweep_step(w[k], out, in);
        }
    }
}

// sweep_finish's value for a voxel's final distance v: up to `most` it stays, above it `far`,
// below -most `near` (signed).
inline ELEM sweep_finished(int v, int most, ELEM far, ELEM near) {
#if KEY_KIND == 2
    if (v < -most) {
        return near;
    }
#endif
    return v > most ? far : (ELEM)v;
}

// sweep_l1 for GPUs (the same arguments first, and global ids): the line is loaded whole before
// it is scanned (along x in four aligned 16-element loads, along y and z 64 independent loads),
// both scans run in registers, and only the changed values are written back (along x per 16).
// The z pass, the last, writes sweep_finish's values (most, far, near as there), so that no
// finishing pass follows on GPUs: a neighbour that reads a finished value instead of the pass's
// reads far (or near) only where the exact value lies beyond `most`, and far + 1 > most, so what
// it carries on from it lies beyond `most` as well and ends as far too.
__kernel void sweep_l1_loaded(__global ELEM* restrict pool, __global const uint* restrict nbrs,
                              uint first, uint axis, uint halo, int cap, int most, ELEM far,
                              ELEM near) {
    const size_t u = get_global_id(0), w = get_global_id(1);
    const size_t slot = first + get_global_id(2);
    size_t stride;
    const size_t at = tile_line(axis, u, w, &stride);
    __global ELEM* line = pool + slot * TILE_VOXELS + at;
    int v[TILE];
    if (axis == 0) {
#pragma unroll
        for (uint q = 0; q < TILE / 16; ++q) {
            ELEM e[16];
            vstore16(*(__global const ELEM16*)(line + 16 * q), 0, e);
#pragma unroll
            for (uint k = 0; k < 16; ++k) {
                v[16 * q + k] = (int)e[k];
            }
        }
    } else {
#pragma unroll
        for (uint p = 0; p < TILE; ++p) {
            v[p] = (int)line[p * stride];
        }
    }
    // The two scans written out, so that every index into v is a constant once unrolled.
    ulong changed = 0;
    int out, in;
    sweep_carry_loaded(pool, nbrs[6 * slot + 2 * axis], at, stride, -1, halo, cap, &out, &in);
#pragma unroll
    for (uint p = 0; p < TILE; ++p) {
        const int r = sweep_step(v[p], &out, &in);
        changed |= (ulong)(r != v[p]) << p;
        v[p] = r;
    }
    sweep_carry_loaded(pool, nbrs[6 * slot + 2 * axis + 1], at, stride, 1, halo, cap, &out, &in);
#pragma unroll
    for (uint k = 0; k < TILE; ++k) {
        const uint p = TILE - 1 - k;
        const int r = sweep_step(v[p], &out, &in);
        changed |= (ulong)(r != v[p]) << p;
        v[p] = r;
    }
    if (axis == 0) {
#pragma unroll
        for (uint q = 0; q < TILE / 16; ++q) {
            if ((changed >> (16 * q) & 0xFFFFul) != 0) {
                ELEM e[16];
#pragma unroll
                for (uint k = 0; k < 16; ++k) {
                    e[k] = (ELEM)v[16 * q + k];
                }
                *(__global ELEM16*)(line + 16 * q) = vload16(0, e);
            }
        }
    } else if (axis == 1) {
#pragma unroll
        for (uint p = 0; p < TILE; ++p) {
            if ((changed >> p & 1ul) != 0) {
                line[p * stride] = (ELEM)v[p];
            }
        }
    } else {
        // Unchanged values are the loaded ones: written when finishing changes them.
#pragma unroll
        for (uint p = 0; p < TILE; ++p) {
            const ELEM f = sweep_finished(v[p], most, far, near);
            if ((changed >> p & 1ul) != 0 || f != (ELEM)v[p]) {
                line[p * stride] = f;
            }
        }
    }
}

// sweep_l1 along y or z (axis 1 or 2) for CPUs: a work-item per plane (global id 0: z for y,
// y for z; global id 1: slot - first) carries its 64 lines along x together, in four 16-wide
// vectors, so each step reads and writes whole rows. Unsigned fields only (`in` not carried).
__kernel void sweep_l1_rows(__global ELEM* restrict pool, __global const uint* restrict nbrs,
                            uint first, uint axis, uint halo, int cap) {
    const size_t w = get_global_id(0);
    const size_t slot = first + get_global_id(1);
    const size_t stride = axis == 1 ? TILE : TILE * TILE;
    const size_t at = axis == 1 ? w * TILE * TILE : w * TILE;
    __global ELEM* line = pool + slot * TILE_VOXELS + at;
    const ELEM16 one = (ELEM16)((ELEM)1);
    for (uint dir = 0; dir < 2; ++dir) {
        const uint nb = nbrs[6 * slot + 2 * axis + dir];
        ELEM16 r[4];
        for (uint q = 0; q < 4; ++q) {
            r[q] = (ELEM16)((ELEM)(nb == NB_INSIDE ? 0 : cap));
        }
        if (nb != NB_INSIDE && nb != NB_EMPTY) {
            __global const ELEM* t = pool + (size_t)nb * TILE_VOXELS + at;
            for (uint k = halo; k-- > 0;) {
                const uint p = dir == 0 ? TILE - 1 - k : k;
                for (uint q = 0; q < 4; ++q) {
                    r[q] = min(vload16(q, t + p * stride), r[q] + one);
                }
            }
        }
        for (uint step = 0; step < TILE; ++step) {
            const uint p = dir == 0 ? step : TILE - 1 - step;
            for (uint q = 0; q < 4; ++q) {
                r[q] = min(vload16(q, line + p * stride), r[q] + one);
                vstore16(r[q], q, line + p * stride);
            }
        }
    }
}

// A work-item per 16 voxels, as sweep_init: distances up to `most` (D rounded down) stay, the
// others become `far` (D encoded), or `near` (-D encoded) below -most.
__kernel void sweep_finish(__global ELEM* restrict pool, uint first, int most, ELEM far, ELEM near) {
    __global ELEM* p = pool + (first + get_global_id(2) / TILE) * TILE_VOXELS +
                       ((get_global_id(2) % TILE) * TILE + get_global_id(1)) * TILE +
                       get_global_id(0) * 16;
    // Aligned 16-element loads and stores (a multiple of 16 elements in): wide on GPUs.
    ELEM16 v = *(__global ELEM16*)p;
    v = v > (ELEM16)((ELEM)most) ? (ELEM16)far : v;
#if KEY_KIND == 2
    v = v < (ELEM16)((ELEM)(-most)) ? (ELEM16)near : v;
#endif
    *(__global ELEM16*)p = v;
}
