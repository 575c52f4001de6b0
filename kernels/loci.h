// One pixel seen from one transmitter–receiver row, VEC pixels of a row at a time: the vector
// types of VEC lanes and view_pixel(), shared by the map's kernels (accumulate.cl: loci,
// back-projection, occupancy; directional.cl: the directional maximum, built with VEC = 1).
// The including file includes real.h (or common.h) first and defines VEC (1, 2, 4, 8 or 16).

#define CAT(a, b) a##b
#define XCAT(a, b) CAT(a, b)

#ifdef REAL_DOUBLE
#define REAL_NAME double
#define MASK_NAME long
#else
#define REAL_NAME float
#define MASK_NAME int
#endif

#if VEC == 1
#define ANY(m) (m)
typedef real realv;
typedef int maskv;
typedef int intv;
#define LANES R(0.0)
#define LOADV(p) (*(p))
#define STOREV(v, p) (*(p) = (v))
#define GATHER(b, i) ((b)[i])
#define CONVERT_INTV convert_int
#else
#define ANY(m) any(m)
typedef XCAT(REAL_NAME, VEC) realv;
typedef XCAT(MASK_NAME, VEC) maskv;
typedef XCAT(int, VEC) intv;
#define LOADV(p) XCAT(vload, VEC)(0, p)
#define STOREV(v, p) XCAT(vstore, VEC)(v, 0, p)
#define CONVERT_INTV XCAT(convert_int, VEC)
#if VEC == 2
#define LANES ((realv)(0, 1))
#define GATHER(b, i) ((realv)((b)[(i).s0], (b)[(i).s1]))
#elif VEC == 4
#define LANES ((realv)(0, 1, 2, 3))
#define GATHER(b, i) ((realv)((b)[(i).s0], (b)[(i).s1], (b)[(i).s2], (b)[(i).s3]))
#elif VEC == 8
#define LANES ((realv)(0, 1, 2, 3, 4, 5, 6, 7))
#define GATHER(b, i) ((realv)((b)[(i).s0], (b)[(i).s1], (b)[(i).s2], (b)[(i).s3], \
                              (b)[(i).s4], (b)[(i).s5], (b)[(i).s6], (b)[(i).s7]))
#elif VEC == 16
#define LANES ((realv)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15))
#define GATHER(b, i) ((realv)((b)[(i).s0], (b)[(i).s1], (b)[(i).s2], (b)[(i).s3], \
                              (b)[(i).s4], (b)[(i).s5], (b)[(i).s6], (b)[(i).s7], \
                              (b)[(i).s8], (b)[(i).s9], (b)[(i).sa], (b)[(i).sb], \
                              (b)[(i).sc], (b)[(i).sd], (b)[(i).se], (b)[(i).sf]))
#else
#error "VEC must be 1, 2, 4, 8 or 16"
#endif
#endif

#ifndef WEIGHT_BEAM
#define WEIGHT_BEAM 0
#endif

// What every kernel here needs of one pixel and one transmitter–receiver row: T, R relative
// to the origin pixel and their unit axes. The joint beam test is the echo engine's hard cut
// (common.h, beam()): inside T's beam iff cosθ_T > 0 and sin²θ_T ≤ cut, with cosθ ∝ c =
// axis·d, sinθ ∝ s = axis×d for d = p − T; sin²θ = s²/|d|² ≤ cut is tested multiplied out,
// s² ≤ cut·|d|² (no division; the same decision but for rounding). The same for R.
typedef struct {
    realv dd_t, s_t, dd_r, s_r;  // |p − T|², axis_T × (p − T); the same for R
    realv path;                  // |p − T| + |p − R|
    maskv inside;                // inside both beams
} pixel_view;

inline pixel_view view_pixel(realv px, real py, real4 tr, real4 axes, real cut_sin2) {
    pixel_view v;
    realv tx = px - tr.x;
    real ty = py - tr.y;
    realv rx = px - tr.z;
    real ry = py - tr.w;
    v.dd_t = tx * tx + ty * ty;
    v.dd_r = rx * rx + ry * ry;
    realv c_t = axes.x * tx + axes.y * ty;
    realv c_r = axes.z * rx + axes.w * ry;
    v.s_t = axes.x * ty - axes.y * tx;
    v.s_r = axes.z * ry - axes.w * rx;
    v.path = sqrt(v.dd_t) + sqrt(v.dd_r);
    v.inside = (c_t > R(0.0)) & (v.s_t * v.s_t <= cut_sin2 * v.dd_t) &
               (c_r > R(0.0)) & (v.s_r * v.s_r <= cut_sin2 * v.dd_r);
    return v;
}
