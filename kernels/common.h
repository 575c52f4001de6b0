// Shared types and 2-D geometry helpers of clsonar's kernels.
//
// Precision: the host builds every kernel either in float32 (default) or, with -DREAL_DOUBLE=1
// on a device with cl_khr_fp64, in float64. Kernels use `real`/`real2`/`real4` throughout and
// write literals as R(1.5) so both builds see the same code. Coordinates arrive relative to a
// local origin (the scene extent's centre), so float32 keeps ~1e-6 m resolution in a 20 m scene.
//
// FP_CONTRACT is off (real.h) so the float64 build rounds exactly like the NumPy reference
// (clsonar/echoes/reference.py); helpers below avoid the dot()/length() builtins for the same reason.

#include "real.h"

// Bisection steps of the curved-surface searches: below each type's resolution.
#ifndef BISECT_ITERATIONS
#ifdef REAL_DOUBLE
#define BISECT_ITERATIONS 40
#else
#define BISECT_ITERATIONS 32
#endif
#endif

// Legs shorter than EPS_M at either end of an occluder crossing do not count as blocked, so a
// path that ends on a surface is not blocked by that surface (or its neighbour at a vertex).
// The host passes the value (clsonar.echoes.OCCLUSION_EPS_M, 1e-4 m); this is the fallback.
#ifndef EPS_M
#define EPS_M 1e-4
#endif

// Indices into the per-scene constants buffer `k` (clsonar.echoes.host._constants writes it).
#define K_AMPLITUDE 0    // A0, transmitted amplitude (5 units in the thesis, §2.1)
#define K_BEAM_U 1       // (k·a / j1)²: u = K_BEAM_U · sin²θ, u = 1 at the first null
#define K_CUT_SIN2 2     // sin² of the hard beam cut (min of half_beam_deg and the null)
#define K_RHO 3          // wall reflection coefficient ρ
#define K_ABSORPTION 4   // α·ln(10)/20 per metre: amplitude factor exp(−K_ABSORPTION·L)
#define K_EDGE 5         // edge_coefficient, see physics.edge_gain and edge_gain_estimate
#define K_INV_C 6        // 1 / speed of sound (eq. 2.1 unless the scene overrides it)
#define K_CURVATURE 7    // 1, or 0 where curved surfaces reflect like flat ones (the thesis)
#define K_WAVENUMBER 8   // k = 2πf/c, rad/m
#define K_EDGE_UTD 9     // 1: edges diffract by the uniform theory (echo.edge_model "utd")
#define K_COUNT 10

// Coefficients c_k of the beam series (physics.beam_series_coefficients), from the host:
// -DBEAM_TERMS=14 -DBEAM_SERIES={c0,c1,...}.
__constant real beam_series[BEAM_TERMS] = BEAM_SERIES;

inline real dot2(real2 a, real2 b) { return a.x * b.x + a.y * b.y; }

// z component of the 3-D cross product: > 0 when b is counter-clockwise from a.
inline real cross2(real2 a, real2 b) { return a.x * b.y - a.y * b.x; }

inline real norm2(real2 a) { return sqrt(dot2(a, a)); }

// p mirrored across the line through q with unit normal n (the image method, thesis fig. 2.2).
inline real2 mirror(real2 p, real2 q, real2 n) {
    real h = dot2(p - q, n);
    return p - (R(2.0) * h) * n;
}

// Circular-piston sensitivity b(θ) of a transducer with unit axis `axis` towards direction d
// (thesis §2.1, eq. 2.2; physics.beam_pattern). 0 behind the transducer or outside the hard
// cut; inside, 2·J1(x)/x with x = ka·sinθ, evaluated as (1 − u)·Σ c_k u^k, u = (x/j1)², by
// Horner's rule with the host's coefficients (physics.beam_series_coefficients). sin²θ comes
// from the cross product, so no acos/asin is needed and small angles keep full precision.
inline real beam(real2 axis, real2 d, __global const real *k) {
    real c = dot2(axis, d);
    if (c <= R(0.0)) return R(0.0);
    real s = cross2(axis, d);
    real sin2 = (s * s) / dot2(d, d);
    if (sin2 > k[K_CUT_SIN2]) return R(0.0);
    real u = k[K_BEAM_U] * sin2;
    real sum = R(0.0);
    for (int i = BEAM_TERMS - 1; i >= 0; --i) sum = sum * u + beam_series[i];
    return (R(1.0) - u) * sum;
}

// Amplitude left after absorption over a path of length L (physics.absorption_factor).
inline real absorption(real path, __global const real *k) {
    return exp(-k[K_ABSORPTION] * path);
}

// Gain of a curved reflector of convexity kappa over a flat mirror (physics.curved_gain):
// the reflected ray tube spreads as if the path were d1 + d2 + 2κ·d1·d2/cosθi long; the
// focusing of a concave surface is capped at MAX_FOCUS_GAIN.
inline real curved_gain(real d1, real d2, real kappa, real cos_incidence,
                        __global const real *k) {
    kappa *= k[K_CURVATURE];
    real path = d1 + d2;
    real l_eff = fabs(path + R(2.0) * kappa * d1 * d2 / cos_incidence);
    real floor_ = path / (R(MAX_FOCUS_GAIN) * R(MAX_FOCUS_GAIN));
    return sqrt(path / fmax(l_eff, floor_));
}

// Does the leg a→b cross an occluder segment or pass through a circle?
//
// A crossing at leg parameter t counts only when it is more than EPS_M from both ends
// (t·|leg| > EPS_M and (1 − t)·|leg| > EPS_M), so legs that start or end on a surface are
// not blocked by it. Segments parallel to the leg never block (a grazing leg along a wall is
// not blocked by that wall). Occluders skip_lo..skip_hi (inclusive) and circle skip_circle
// are ignored: the chords next to a specular point on a curve, the reflecting cylinder.
// A circle blocks when the leg's closest approach to its centre, over the leg's interior
// t·|leg| in [EPS_M, |leg| − EPS_M], is less than its radius.
inline bool leg_blocked(real2 a, real2 b,
                        __global const real4 *occ, int n_occ, int skip_lo, int skip_hi,
                        __global const real4 *circles, int n_circles, int skip_circle) {
    real2 d = b - a;
    real len2 = dot2(d, d);
    real len = sqrt(len2);
    for (int i = 0; i < n_occ; ++i) {
        if (i >= skip_lo && i <= skip_hi) continue;
        real4 o = occ[i];
        real2 q = (real2)(o.x, o.y);
        real2 e = (real2)(o.z, o.w) - q;
        real den = cross2(d, e);
        if (den == R(0.0)) continue;
        // a + t·d = q + u·e: crossing both sides with e and with d gives t and u.
        real2 w = q - a;
        real t = cross2(w, e) / den;
        real u = cross2(w, d) / den;
        if (u >= R(0.0) && u <= R(1.0) && t * len > R(EPS_M) && (R(1.0) - t) * len > R(EPS_M))
            return true;
    }
    if (len <= R(2.0) * R(EPS_M)) return false;
    real t_lo = R(EPS_M) / len;
    real t_hi = R(1.0) - t_lo;
    for (int i = 0; i < n_circles; ++i) {
        if (i == skip_circle) continue;
        real4 c = circles[i];
        real2 w = (real2)(c.x, c.y) - a;
        real t = clamp(dot2(w, d) / len2, t_lo, t_hi);
        real2 gap = w - t * d;
        if (dot2(gap, gap) < c.z * c.z) return true;
    }
    return false;
}
