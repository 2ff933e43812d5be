/* The implicit-surface tape and grid as implicit.cl's evaluators see them (after
 * sdf_layout.hpp). */
#pragma OPENCL FP_CONTRACT OFF

typedef struct {
    uint op;
    uint material;
    float p[VF_SDF_INSTR_PARAMS];
} Instr;

/* The grid: x0 + i h per axis, dims voxels. */
typedef struct {
    float x0, y0, z0, h;
    uint nx, ny, nz, pad;
} Grid;

inline float corner_at(float x0, float h, uint i) {
    return x0 + (float)i * h;
}
inline float centre_at(float x0, float h, uint i) {
    return x0 + ((float)i + 0.5f) * h;
}
