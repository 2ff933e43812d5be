/* The tape interpreted in floats and in dual numbers, written once for a value type FT
 * (float, or floatN to evaluate N points per instruction fetch, as the CPU layout does), a
 * material type MT (uint for float, intN for floatN, so that comparisons select per lane) and
 * a name suffix EV_SUF. The host prepends this file once per instance with those three
 * defined. Every lane runs exactly the scalar operations, so a floatN instance gives the
 * scalar instance's values bit for bit. */
#define EV_CAT_(a, b) a##b
#define EV_CAT(a, b) EV_CAT_(a, b)
#define FN(name) EV_CAT(name, EV_SUF)

inline FT FN(f_len2)(FT a, FT b) {
    return sqrt(fmax(a * a + b * b, 0.0f));
}
inline FT FN(f_len3)(FT a, FT b, FT c) {
    return sqrt(fmax(a * a + b * b + c * c, 0.0f));
}

inline FT FN(f_box)(FT dx, FT dy, FT dz, float sx, float sy, float sz) {
    const FT qx = fabs(dx) - sx, qy = fabs(dy) - sy, qz = fabs(dz) - sz;
    const FT outside = FN(f_len3)(fmax(qx, 0.0f), fmax(qy, 0.0f), fmax(qz, 0.0f));
    return outside + fmin(fmax(qx, fmax(qy, qz)), 0.0f);
}

inline FT FN(f_primitive)(__global const Instr* in, FT x, FT y, FT z) {
    __global const float* p = in->p;
    switch (in->op) {
        case VF_SDF_SPHERE:
            return FN(f_len3)(x - p[0], y - p[1], z - p[2]) - p[3];
        case VF_SDF_BOX:
            return FN(f_box)(x - p[0], y - p[1], z - p[2], p[3], p[4], p[5]);
        case VF_SDF_ROUND_BOX:
            return FN(f_box)(x - p[0], y - p[1], z - p[2], p[3] - p[6], p[4] - p[6],
                             p[5] - p[6]) -
                   p[6];
        case VF_SDF_CYLINDER: {
            const FT a = FN(f_len2)(x - p[0], z - p[2]) - p[3], b = fabs(y - p[1]) - p[4];
            return fmin(fmax(a, b), 0.0f) + FN(f_len2)(fmax(a, 0.0f), fmax(b, 0.0f));
        }
        case VF_SDF_TORUS: {
            const FT a = FN(f_len2)(x - p[0], z - p[2]) - p[3];
            return FN(f_len2)(a, y - p[1]) - p[4];
        }
        case VF_SDF_CAPSULE: {
            const float bx = p[3] - p[0], by = p[4] - p[1], bz = p[5] - p[2];
            const float dd = bx * bx + by * by + bz * bz;
            const FT ax = x - p[0], ay = y - p[1], az = z - p[2];
            const FT dot = bx * ax + by * ay + bz * az;
            const FT h = dd > 0 ? fmin(fmax(dot / dd, 0.0f), 1.0f) : 0.0f * dot;
            return FN(f_len3)(ax - bx * h, ay - by * h, az - bz * h) - p[6];
        }
        default: /* VF_SDF_PLANE */
            return p[0] * x + p[1] * y + p[2] * z - p[3];
    }
}

inline FT FN(f_smooth_min)(FT a, FT b, float k) {
    const FT h = fmax(k - fabs(a - b), 0.0f) / k;
    return fmin(a, b) - h * h * k * 0.25f;
}

/* The value at (x, y, z) and the material there (sdf.hpp's rules), running the instructions
 * list[0..n) (a leaf's specialised tape), or 0..n when list is 0. */
FT FN(eval_f)(__global const Instr* tape, const ushort* list, uint n, FT x, FT y, FT z,
              MT* material) {
    FT v[VF_SDF_STACK];
    MT m[VF_SDF_STACK];
    FT px[VF_SDF_STACK], py[VF_SDF_STACK], pz[VF_SDF_STACK];
    int nv = 0, np = 0;
    px[0] = x;
    py[0] = y;
    pz[0] = z;
    for (uint t = 0; t < n; ++t) {
        __global const Instr* in = tape + (list ? list[t] : t);
        const uint op = in->op;
        if (op <= VF_SDF_PLANE) {
            v[nv] = FN(f_primitive)(in, px[np], py[np], pz[np]);
            m[nv++] = (MT)in->material;
        } else if (op <= VF_SDF_SMOOTH_DIFF) {
            const FT b = v[--nv], a = v[nv - 1];
            const float k = in->p[0];
            if (op == VF_SDF_MIN) {
                m[nv - 1] = a <= b ? m[nv - 1] : m[nv];
                v[nv - 1] = fmin(a, b);
            } else if (op == VF_SDF_MAX) {
                m[nv - 1] = a >= b ? m[nv - 1] : m[nv];
                v[nv - 1] = fmax(a, b);
            } else if (op == VF_SDF_DIFF) {
                v[nv - 1] = fmax(a, -b);
            } else if (op == VF_SDF_SMOOTH_MIN) {
                m[nv - 1] = a <= b ? m[nv - 1] : m[nv];
                v[nv - 1] = FN(f_smooth_min)(a, b, k);
            } else {
                v[nv - 1] = -FN(f_smooth_min)(-a, b, k);
            }
        } else if (op == VF_SDF_SHELL) {
            v[nv - 1] = fabs(v[nv - 1]) - in->p[0];
        } else if (op == VF_SDF_PUSH_POINT) {
            __global const float* p = in->p;
            const FT dx = px[np] - p[9], dy = py[np] - p[10], dz = pz[np] - p[11];
            ++np;
            px[np] = p[0] * dx + p[1] * dy + p[2] * dz;
            py[np] = p[3] * dx + p[4] * dy + p[5] * dz;
            pz[np] = p[6] * dx + p[7] * dy + p[8] * dz;
        } else { /* VF_SDF_POP_POINT */
            --np;
            v[nv - 1] = v[nv - 1] * in->p[0];
        }
    }
    *material = m[0];
    return v[0];
}

/* Forward-mode dual numbers: the gradient (x, y, z) and the value w of a function of the
 * point, per lane. */
typedef struct {
    FT x, y, z, w;
} FN(Dual);
#define DT FN(Dual)

inline DT FN(d_make)(FT x, FT y, FT z, FT w) {
    DT r = {x, y, z, w};
    return r;
}
inline DT FN(d_const)(float w) {
    return FN(d_make)((FT)0.0f, (FT)0.0f, (FT)0.0f, (FT)w);
}
inline DT FN(d_add)(DT a, DT b) {
    return FN(d_make)(a.x + b.x, a.y + b.y, a.z + b.z, a.w + b.w);
}
inline DT FN(d_sub)(DT a, DT b) {
    return FN(d_make)(a.x - b.x, a.y - b.y, a.z - b.z, a.w - b.w);
}
inline DT FN(d_neg)(DT a) {
    return FN(d_make)(-a.x, -a.y, -a.z, -a.w);
}
inline DT FN(d_scale)(float s, DT a) {
    return FN(d_make)(s * a.x, s * a.y, s * a.z, s * a.w);
}
inline DT FN(d_divs)(DT a, float s) {
    return FN(d_make)(a.x / s, a.y / s, a.z / s, a.w / s);
}
inline DT FN(d_subs)(DT a, float s) {
    return FN(d_make)(a.x, a.y, a.z, a.w - s);
}
/* a where c, else b, per lane. */
#define D_SEL(c, a, b) \
    FN(d_make)((c) ? (a).x : (b).x, (c) ? (a).y : (b).y, (c) ? (a).z : (b).z, (c) ? (a).w : (b).w)
inline DT FN(d_mul)(DT a, DT b) {
    return FN(d_make)(a.w * b.x + b.w * a.x, a.w * b.y + b.w * a.y, a.w * b.z + b.w * a.z,
                      a.w * b.w);
}
inline DT FN(d_abs)(DT a) {
    return D_SEL(a.w < 0, FN(d_neg)(a), a);
}
inline DT FN(d_sq)(DT a) {
    return FN(d_mul)(a, a);
}
inline DT FN(d_sqrt)(DT a) {
    const FT r = sqrt(fmax(a.w, 0.0f));
    const FT s = 0.5f / r;
    const FT zero = (FT)0.0f;
    return FN(d_make)(r > 0 ? s * a.x : zero, r > 0 ? s * a.y : zero, r > 0 ? s * a.z : zero, r);
}
inline DT FN(d_min)(DT a, DT b) {
    return D_SEL(a.w <= b.w, a, b);
}
inline DT FN(d_max)(DT a, DT b) {
    return D_SEL(a.w >= b.w, a, b);
}
inline DT FN(d_mins)(DT a, float s) {
    return D_SEL(a.w <= s, a, FN(d_const)(s));
}
inline DT FN(d_maxs)(DT a, float s) {
    return D_SEL(a.w >= s, a, FN(d_const)(s));
}
inline DT FN(d_len2)(DT a, DT b) {
    return FN(d_sqrt)(FN(d_add)(FN(d_sq)(a), FN(d_sq)(b)));
}
inline DT FN(d_len3)(DT a, DT b, DT c) {
    return FN(d_sqrt)(FN(d_add)(FN(d_add)(FN(d_sq)(a), FN(d_sq)(b)), FN(d_sq)(c)));
}

inline DT FN(d_box)(DT dx, DT dy, DT dz, float sx, float sy, float sz) {
    const DT qx = FN(d_subs)(FN(d_abs)(dx), sx), qy = FN(d_subs)(FN(d_abs)(dy), sy),
             qz = FN(d_subs)(FN(d_abs)(dz), sz);
    const DT outside =
        FN(d_len3)(FN(d_maxs)(qx, 0.0f), FN(d_maxs)(qy, 0.0f), FN(d_maxs)(qz, 0.0f));
    return FN(d_add)(outside, FN(d_mins)(FN(d_max)(qx, FN(d_max)(qy, qz)), 0.0f));
}

/* s0 a + s1 b + s2 c */
inline DT FN(d_dot3)(float s0, DT a, float s1, DT b, float s2, DT c) {
    return FN(d_add)(FN(d_add)(FN(d_scale)(s0, a), FN(d_scale)(s1, b)), FN(d_scale)(s2, c));
}

inline DT FN(d_primitive)(__global const Instr* in, DT x, DT y, DT z) {
    __global const float* p = in->p;
    switch (in->op) {
        case VF_SDF_SPHERE:
            return FN(d_subs)(
                FN(d_len3)(FN(d_subs)(x, p[0]), FN(d_subs)(y, p[1]), FN(d_subs)(z, p[2])), p[3]);
        case VF_SDF_BOX:
            return FN(d_box)(FN(d_subs)(x, p[0]), FN(d_subs)(y, p[1]), FN(d_subs)(z, p[2]), p[3],
                             p[4], p[5]);
        case VF_SDF_ROUND_BOX:
            return FN(d_subs)(FN(d_box)(FN(d_subs)(x, p[0]), FN(d_subs)(y, p[1]),
                                        FN(d_subs)(z, p[2]), p[3] - p[6], p[4] - p[6],
                                        p[5] - p[6]),
                              p[6]);
        case VF_SDF_CYLINDER: {
            const DT a = FN(d_subs)(FN(d_len2)(FN(d_subs)(x, p[0]), FN(d_subs)(z, p[2])), p[3]);
            const DT b = FN(d_subs)(FN(d_abs)(FN(d_subs)(y, p[1])), p[4]);
            return FN(d_add)(FN(d_mins)(FN(d_max)(a, b), 0.0f),
                             FN(d_len2)(FN(d_maxs)(a, 0.0f), FN(d_maxs)(b, 0.0f)));
        }
        case VF_SDF_TORUS: {
            const DT a = FN(d_subs)(FN(d_len2)(FN(d_subs)(x, p[0]), FN(d_subs)(z, p[2])), p[3]);
            return FN(d_subs)(FN(d_len2)(a, FN(d_subs)(y, p[1])), p[4]);
        }
        case VF_SDF_CAPSULE: {
            const float bx = p[3] - p[0], by = p[4] - p[1], bz = p[5] - p[2];
            const float dd = bx * bx + by * by + bz * bz;
            const DT ax = FN(d_subs)(x, p[0]), ay = FN(d_subs)(y, p[1]), az = FN(d_subs)(z, p[2]);
            const DT dot = FN(d_dot3)(bx, ax, by, ay, bz, az);
            const DT h = dd > 0 ? FN(d_mins)(FN(d_maxs)(FN(d_divs)(dot, dd), 0.0f), 1.0f)
                                : FN(d_scale)(0.0f, dot);
            return FN(d_subs)(FN(d_len3)(FN(d_sub)(ax, FN(d_scale)(bx, h)),
                                         FN(d_sub)(ay, FN(d_scale)(by, h)),
                                         FN(d_sub)(az, FN(d_scale)(bz, h))),
                              p[6]);
        }
        default:
            return FN(d_subs)(FN(d_dot3)(p[0], x, p[1], y, p[2], z), p[3]);
    }
}

inline DT FN(d_smooth_min)(DT a, DT b, float k) {
    const FT h = fmax(k - fabs(a.w - b.w), 0.0f) / k;
    const DT lo = D_SEL(a.w <= b.w, a, b);
    const DT other = D_SEL(a.w <= b.w, b, a);
    const FT wl = 1.0f - 0.5f * h, wo = 0.5f * h;
    return FN(d_make)(wl * lo.x + wo * other.x, wl * lo.y + wo * other.y,
                      wl * lo.z + wo * other.z, fmin(a.w, b.w) - h * h * k * 0.25f);
}

/* The value and its gradient at (x, y, z) (list as for eval_f). */
DT FN(eval_d)(__global const Instr* tape, const ushort* list, uint n, FT x, FT y, FT z) {
    DT v[VF_SDF_STACK];
    DT px[VF_SDF_STACK], py[VF_SDF_STACK], pz[VF_SDF_STACK];
    int nv = 0, np = 0;
    const FT zero = (FT)0.0f, one = (FT)1.0f;
    px[0] = FN(d_make)(one, zero, zero, x);
    py[0] = FN(d_make)(zero, one, zero, y);
    pz[0] = FN(d_make)(zero, zero, one, z);
    for (uint t = 0; t < n; ++t) {
        __global const Instr* in = tape + (list ? list[t] : t);
        const uint op = in->op;
        if (op <= VF_SDF_PLANE) {
            v[nv++] = FN(d_primitive)(in, px[np], py[np], pz[np]);
        } else if (op <= VF_SDF_SMOOTH_DIFF) {
            const DT b = v[--nv], a = v[nv - 1];
            const float k = in->p[0];
            if (op == VF_SDF_MIN) {
                v[nv - 1] = FN(d_min)(a, b);
            } else if (op == VF_SDF_MAX) {
                v[nv - 1] = FN(d_max)(a, b);
            } else if (op == VF_SDF_DIFF) {
                v[nv - 1] = FN(d_max)(a, FN(d_neg)(b));
            } else if (op == VF_SDF_SMOOTH_MIN) {
                v[nv - 1] = FN(d_smooth_min)(a, b, k);
            } else {
                v[nv - 1] = FN(d_neg)(FN(d_smooth_min)(FN(d_neg)(a), b, k));
            }
        } else if (op == VF_SDF_SHELL) {
            v[nv - 1] = FN(d_subs)(FN(d_abs)(v[nv - 1]), in->p[0]);
        } else if (op == VF_SDF_PUSH_POINT) {
            __global const float* p = in->p;
            const DT dx = FN(d_subs)(px[np], p[9]), dy = FN(d_subs)(py[np], p[10]),
                     dz = FN(d_subs)(pz[np], p[11]);
            ++np;
            px[np] = FN(d_dot3)(p[0], dx, p[1], dy, p[2], dz);
            py[np] = FN(d_dot3)(p[3], dx, p[4], dy, p[5], dz);
            pz[np] = FN(d_dot3)(p[6], dx, p[7], dy, p[8], dz);
        } else {
            --np;
            v[nv - 1] = FN(d_scale)(in->p[0], v[nv - 1]);
        }
    }
    return v[0];
}

#undef D_SEL
#undef DT

#undef FN
#undef EV_CAT
#undef EV_CAT_
