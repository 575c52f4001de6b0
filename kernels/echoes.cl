// Analytic echo paths of every transmitter→receiver pair (thesis §2.1.1; model in
// clsonar/echoes/reference.py and clsonar/physics.py). One work item per (surface element, pair):
// get_global_id(0) is the element (wall sequence, diffractor, circle, curve interval) and
// get_global_id(1) the pair. Each item writes one fixed output slot, pair·width + element:
// time of flight, amplitude (0 = no echo), the last reflection point before the receiver and
// the carrier phase against a mirror's (radians; 0 but for an edge's diffraction).
// The host keeps the slots with amplitude > 0. It launches a fixed work-group size and pads
// dimension 0 to a multiple of it (PoCL compiles a kernel anew for every new work-group
// size), so items with element ≥ width do nothing.
//
// Compile-time constants from the host: MAX_ORDER (longest wall sequence), EPS_M (occlusion
// tolerance), BEAM_TERMS and BEAM_SERIES (beam series), MAX_FOCUS_GAIN, FRESNEL_SWITCH
// (physics.fresnel_auxiliary), and REAL_DOUBLE for float64.

#include "common.h"

#define PAIR_ARGS \
    int width, __global const int2 *pairs, __global const real2 *pos, __global const real2 *axis
#define OCCLUDER_ARGS \
    __global const real4 *occ, int n_occ, __global const real4 *circles, int n_circles
#define OUTPUT_ARGS \
    __global const real *k, __global real *tof, __global real *amp, __global real2 *point, \
    __global real *phase

// Clear this work item's slot; return its index.
inline size_t clear_slot(int width, __global real *tof, __global real *amp,
                         __global real2 *point, __global real *phase) {
    size_t slot = get_global_id(1) * (size_t)width + get_global_id(0);
    tof[slot] = R(0.0);
    amp[slot] = R(0.0);
    point[slot] = (real2)(R(0.0), R(0.0));
    phase[slot] = R(0.0);
    return slot;
}

// ----------------------------------------------------------------------------------------
// Specular and multi-bounce (corner) paths on flat walls by the image method (thesis
// fig. 2.2: the echo comes from a virtual transducer mirrored behind the wall).
//
// seq[MAX_ORDER] per element lists the walls hit in order, padded with -1. Images I0 = T,
// Ij = mirror of I(j−1) across wall sj; tracing back from R, Pk is where R→Ik crosses sk,
// P(k−1) where Pk→I(k−1) crosses s(k−1), and so on. Valid iff each crossing is strictly
// between its two points and on the wall (u in [0, 1]), and each bounce's incoming and
// outgoing points are strictly on the wall's front (two-sided walls: strictly on one side),
// and every leg is longer than EPS_M (as in all kernels here). Path length |R − Ik|,
// amplitude factor ρ^k. (The receiver is R_ in code: R() is the literal macro.)
__kernel void mirror_paths(PAIR_ARGS,
                           __global const real4 *walls, __global const real2 *normals,
                           __global const int *two_sided, __global const int *seq,
                           OCCLUDER_ARGS, OUTPUT_ARGS) {
    if (get_global_id(0) >= (size_t)width) return;
    size_t slot = clear_slot(width, tof, amp, point, phase);
    int2 pr = pairs[get_global_id(1)];
    __global const int *s = seq + get_global_id(0) * MAX_ORDER;
    real2 T = pos[pr.x], R_ = pos[pr.y];

    int order = 0;
    real2 img[MAX_ORDER + 1];
    img[0] = T;
    for (int j = 0; j < MAX_ORDER && s[j] >= 0; ++j) {
        real4 w = walls[s[j]];
        img[j + 1] = mirror(img[j], (real2)(w.x, w.y), normals[s[j]]);
        order = j + 1;
    }

    // pts[0] = T, pts[1..order] = reflection points, pts[order + 1] = R.
    real2 pts[MAX_ORDER + 2];
    pts[0] = T;
    pts[order + 1] = R_;
    real2 x = R_;
    for (int j = order; j >= 1; --j) {
        real4 w = walls[s[j - 1]];
        real2 q = (real2)(w.x, w.y);
        real2 e = (real2)(w.z, w.w) - q;
        real2 n = normals[s[j - 1]];
        // Signed distances of x and of the image to the wall's line: opposite signs mean
        // the segment x→image crosses the line strictly between them, at t = hx/(hx − hi).
        real hx = dot2(x - q, n);
        real hi = dot2(img[j] - q, n);
        if (!((hx > R(0.0) && hi < R(0.0)) || (hx < R(0.0) && hi > R(0.0)))) return;
        real t = hx / (hx - hi);
        real2 p = x + t * (img[j] - x);
        real u = dot2(p - q, e) / dot2(e, e);
        if (u < R(0.0) || u > R(1.0)) return;
        pts[j] = p;
        x = p;
    }
    for (int j = 1; j <= order; ++j) {
        real4 w = walls[s[j - 1]];
        real2 q = (real2)(w.x, w.y);
        real2 n = normals[s[j - 1]];
        real h_in = dot2(pts[j - 1] - q, n);
        real h_out = dot2(pts[j + 1] - q, n);
        bool ok = two_sided[s[j - 1]] ? (h_in > R(0.0) && h_out > R(0.0)) ||
                                            (h_in < R(0.0) && h_out < R(0.0))
                                      : (h_in > R(0.0) && h_out > R(0.0));
        if (!ok) return;
    }
    // Every leg must be longer than EPS_M: this excludes a transducer on a wall and the
    // degenerate double bounce through the vertex of a corner (T = R at a right angle), whose
    // zero-length middle leg rounding would otherwise turn into an echo or not at random;
    // vertex_paths computes those paths exactly.
    for (int j = 0; j <= order; ++j)
        if (!(norm2(pts[j + 1] - pts[j]) > R(EPS_M))) return;

    real path = norm2(R_ - img[order]);
    real a = k[K_AMPLITUDE] * beam(axis[pr.x], pts[1] - T, k) *
             beam(axis[pr.y], pts[order] - R_, k);
    if (!(a > R(0.0))) return;
    real rho_n = R(1.0);
    for (int j = 0; j < order; ++j) rho_n *= k[K_RHO];
    a = a * rho_n * absorption(path, k);
    if (!(a > R(0.0))) return;
    for (int j = 0; j <= order; ++j)
        if (leg_blocked(pts[j], pts[j + 1], occ, n_occ, -1, -1, circles, n_circles, -1)) return;

    tof[slot] = path * k[K_INV_C];
    amp[slot] = a;
    point[slot] = pts[order];
}

// Write the echo T→V→R through the point V (a corner's vertex or a convex edge) whose
// amplitude factor before the beams is `factor` and carrier phase `ph`, unless a beam or an
// occluder stops it.
inline void emit_via_point(size_t slot, int2 pr, real2 T, real2 R_, real2 V, real factor,
                           real ph, __global const real2 *axis, OCCLUDER_ARGS, OUTPUT_ARGS) {
    real path = norm2(V - T) + norm2(R_ - V);
    real a = k[K_AMPLITUDE] * beam(axis[pr.x], V - T, k) * beam(axis[pr.y], V - R_, k);
    a = a * factor * absorption(path, k);
    if (!(a > R(0.0))) return;
    if (leg_blocked(T, V, occ, n_occ, -1, -1, circles, n_circles, -1) ||
        leg_blocked(V, R_, occ, n_occ, -1, -1, circles, n_circles, -1))
        return;
    tof[slot] = path * k[K_INV_C];
    amp[slot] = a;
    point[slot] = V;
    phase[slot] = ph;
}

// ----------------------------------------------------------------------------------------
// Double bounce through the vertex V of a concave corner. The image method's path T→P1→P2→R
// degenerates to T→V→R when it runs through the vertex: a right-angled corner reflects every
// ray back parallel to itself (the strong corner echo of sonar), so for T = R the only double
// bounce is T→V→T, whose zero-length middle leg mirror_paths rejects. Valid iff T and R are
// strictly on the concave side of both walls and R lies within EPS_M of the ray from V away
// from T's second-order image (for either order of the walls). Amplitude factor ρ², as for
// any double bounce.
inline bool on_return_ray(real2 r, real2 image) {
    // r and image relative to V: r must point away from the image, within EPS_M of its line.
    return dot2(r, image) < R(0.0) && fabs(cross2(r, image)) <= R(EPS_M) * norm2(image);
}

__kernel void vertex_paths(PAIR_ARGS, __global const real *corners, OCCLUDER_ARGS,
                           OUTPUT_ARGS) {
    if (get_global_id(0) >= (size_t)width) return;
    size_t slot = clear_slot(width, tof, amp, point, phase);
    int2 pr = pairs[get_global_id(1)];
    __global const real *cv = corners + 6 * get_global_id(0);
    real2 V = (real2)(cv[0], cv[1]);
    real2 na = (real2)(cv[2], cv[3]);
    real2 nb = (real2)(cv[4], cv[5]);
    real2 T = pos[pr.x], R_ = pos[pr.y];
    real2 t = T - V, r = R_ - V;
    if (!(dot2(t, na) > R(0.0) && dot2(t, nb) > R(0.0) && dot2(r, na) > R(0.0) &&
          dot2(r, nb) > R(0.0)))
        return;
    if (!(norm2(t) > R(EPS_M) && norm2(r) > R(EPS_M))) return;
    real2 origin = (real2)(R(0.0), R(0.0));
    real2 image_ab = mirror(mirror(t, origin, na), origin, nb);
    real2 image_ba = mirror(mirror(t, origin, nb), origin, na);
    if (!(on_return_ray(r, image_ab) || on_return_ray(r, image_ba))) return;
    emit_via_point(slot, pr, T, R_, V, k[K_RHO] * k[K_RHO], R(0.0), axis, occ, n_occ, circles,
                   n_circles, k, tof, amp, point, phase);
}

// ----------------------------------------------------------------------------------------
// Diffraction at a convex edge V (a polyline vertex that a free side sees as convex): path
// T→V→R, valid iff neither T nor R is strictly inside the solid cone (the convex angle
// between the unit vectors va, vb to the neighbouring points). Amplitude factor |G| and
// carrier phase arg G of physics.edge_diffraction: the uniform theory of diffraction for a
// rigid wedge, no ρ.
inline bool in_solid_cone(real2 x, real2 v, real2 va, real2 vb) {
    real cab = cross2(va, vb);
    if (cab == R(0.0)) return false;
    // x − v = α·va + β·vb with α = cross(w, vb)/cab, β = cross(va, w)/cab; inside iff both > 0.
    real2 w = x - v;
    real alpha = cross2(w, vb) / cab;
    real beta = cross2(va, w) / cab;
    return alpha > R(0.0) && beta > R(0.0);
}

// Angle of x about the edge, from face a through the free region (physics.wedge_angles).
inline real wedge_angle(real2 x, real2 v, real2 va, real s) {
    real2 w = x - v;
    real phi = atan2(-s * cross2(va, w), dot2(va, w));
    return phi < R(0.0) ? phi + R(2.0) * M_PI_R : phi;
}

// One term q·(f(z) + i·g(z)) of the diffraction coefficient for π ± β
// (physics.edge_diffraction):
// ε the distance of x from its nearest multiple of 2πn, f and g the Fresnel auxiliary
// functions (A&S 7.3.32–33 below z = FRESNEL_SWITCH, from the host, the asymptotic series
// 7.3.27–28 above).
inline real2 edge_term(real x, real n, real kl) {
    real eps = x - R(2.0) * M_PI_R * n * floor(x / (R(2.0) * M_PI_R * n) + R(0.5));
    real sh = fabs(sin(R(0.5) * eps));  // |sin(ε/2)|
    real sn = sin(eps / (R(2.0) * n));
    real q = fabs(sn) < R(1e-12) ? n : cos(eps / (R(2.0) * n)) * sh / sn;
    real z = R(2.0) * sh * sqrt(kl / M_PI_R);
    real f, g;
    if (z >= R(FRESNEL_SWITCH)) {
        real x2 = R(1.0) / (M_PI_R * z * z * M_PI_R * z * z);
        f = (R(1.0) - R(3.0) * x2 + R(105.0) * x2 * x2) / (M_PI_R * z);
        g = (R(1.0) - R(15.0) * x2 + R(945.0) * x2 * x2) / (M_PI_R * M_PI_R * z * z * z);
    } else {
        f = (R(1.0) + R(0.926) * z) / (R(2.0) + R(1.792) * z + R(3.104) * z * z);
        g = R(1.0) / (R(2.0) + R(4.142) * z + R(3.492) * z * z + R(6.670) * z * z * z);
    }
    return (real2)(q * f, q * g);
}

// G = D/sqrt(L) of a wedge (physics.edge_diffraction, time dependence e^{+iωt}) as
// (Re G, Im G): −e^{−iπ/4}·(Σ of the four terms)/(n·sqrt 2), times edge_coefficient; with
// echo.edge_model "estimate", (coefficient·sqrt((d1+d2)/(d1·d2))/(2·sqrt(2πk)), 0).
inline real2 edge_diffraction(real2 T, real2 R_, real2 V, real2 va, real2 vb, real d1,
                              real d2, __global const real *k) {
    if (!(k[K_EDGE_UTD] > R(0.0)))
        return (real2)(k[K_EDGE] * sqrt((d1 + d2) / (d1 * d2))
                       / (R(2.0) * sqrt(R(2.0) * M_PI_R * k[K_WAVENUMBER])), R(0.0));
    real cab = cross2(va, vb);
    real s = cab >= R(0.0) ? R(1.0) : R(-1.0);
    real n = (R(2.0) * M_PI_R - atan2(fabs(cab), dot2(va, vb))) / M_PI_R;
    real pt = wedge_angle(T, V, va, s), pr = wedge_angle(R_, V, va, s);
    real kl = k[K_WAVENUMBER] * d1 * d2 / (d1 + d2);
    // the reflection-boundary terms (φ_R + φ_T) weighted by the faces' ρ (Luebbers 1984)
    real2 sum = edge_term(M_PI_R + (pr - pt), n, kl) + edge_term(M_PI_R - (pr - pt), n, kl)
              + k[K_RHO] * (edge_term(M_PI_R + (pr + pt), n, kl)
                            + edge_term(M_PI_R - (pr + pt), n, kl));
    // −e^{−iπ/4}·(x + iy) = (−(x + y) + i·(x − y))/sqrt 2
    real scale = k[K_EDGE] / (R(2.0) * n);
    return (real2)(-(sum.x + sum.y) * scale, (sum.x - sum.y) * scale);
}

__kernel void edge_paths(PAIR_ARGS, __global const real *diffractors, OCCLUDER_ARGS,
                         OUTPUT_ARGS) {
    if (get_global_id(0) >= (size_t)width) return;
    size_t slot = clear_slot(width, tof, amp, point, phase);
    int2 pr = pairs[get_global_id(1)];
    __global const real *dv = diffractors + 6 * get_global_id(0);
    real2 V = (real2)(dv[0], dv[1]);
    real2 va = (real2)(dv[2], dv[3]);
    real2 vb = (real2)(dv[4], dv[5]);
    real2 T = pos[pr.x], R_ = pos[pr.y];
    if (in_solid_cone(T, V, va, vb) || in_solid_cone(R_, V, va, vb)) return;
    real d1 = norm2(V - T);
    real d2 = norm2(R_ - V);
    if (!(d1 > R(EPS_M) && d2 > R(EPS_M))) return;
    real2 g = edge_diffraction(T, R_, V, va, vb, d1, d2, k);
    emit_via_point(slot, pr, T, R_, V, norm2(g), atan2(g.y, g.x), axis, occ, n_occ, circles,
                   n_circles, k, tof, amp, point, phase);
}

// ----------------------------------------------------------------------------------------
// Specular point on a cylinder (circle centre C, radius r). In the circle's frame a = T − C,
// b = R − C; the point is P = C + r·n with n on the shorter arc between â and b̂:
// n(δ) = m̂ rotated by δ, m̂ = (â + b̂)/|â + b̂|, δ in [−α/2, α/2], n(−α/2) = â. The reflection
// law holds where g(δ) = cross(n, û_T + û_R) = 0 (û_X the unit vector from P to X): the
// bisector of the two legs is the normal. g changes sign over the bracket; a fixed number of
// bisection steps finds the root (uniform control flow). T = R gives δ = 0, the radial point.
inline real circle_residual(real2 a, real2 b, real r, real2 n) {
    real2 ut = a - r * n;
    real2 ur = b - r * n;
    return cross2(n, ut / norm2(ut) + ur / norm2(ur));
}

__kernel void circle_paths(PAIR_ARGS, OCCLUDER_ARGS, OUTPUT_ARGS) {
    if (get_global_id(0) >= (size_t)width) return;
    size_t slot = clear_slot(width, tof, amp, point, phase);
    int ci = get_global_id(0);
    int2 pr = pairs[get_global_id(1)];
    real4 c = circles[ci];
    real2 C = (real2)(c.x, c.y);
    real r = c.z;
    real2 T = pos[pr.x], R_ = pos[pr.y];
    real2 a = T - C, b = R_ - C;
    real la = norm2(a), lb = norm2(b);
    if (!(la > r && lb > r)) return;  // a transducer inside or on the cylinder
    real2 ah = a / la, bh = b / lb;
    real2 m = ah + bh;
    real lm = norm2(m);
    if (!(lm > R(1e-6))) return;  // T and R opposite: no shorter arc
    real2 mh = m / lm;
    real2 mp = (real2)(-mh.y, mh.x);  // m̂ rotated by +90°
    real side = cross2(ah, bh) < R(0.0) ? R(-1.0) : R(1.0);
    // Half the angle between â and b̂ from |â − b̂| and |â + b̂| (no acos near 0).
    real half_arc = atan2(norm2(ah - bh), lm);
    real lo = -half_arc, hi = half_arc;
    real g_lo = circle_residual(a, b, r, ah);
    if (g_lo == R(0.0)) hi = lo;
    for (int it = 0; it < BISECT_ITERATIONS; ++it) {
        real mid = R(0.5) * (lo + hi);
        real2 n = cos(mid) * mh + (side * sin(mid)) * mp;
        real g = circle_residual(a, b, r, n);
        if (g != R(0.0) && ((g < R(0.0)) == (g_lo < R(0.0)))) lo = mid;
        else hi = mid;
    }
    real delta = R(0.5) * (lo + hi);
    real2 n = cos(delta) * mh + (side * sin(delta)) * mp;
    real2 P = r * n;  // in the circle's frame
    real2 vt = a - P, vr = b - P;
    real d1 = norm2(vt), d2 = norm2(vr);
    real cos_t = dot2(n, vt) / d1;
    real cos_r = dot2(n, vr) / d2;
    if (!(cos_t > R(0.0) && cos_r > R(0.0) && d1 > R(EPS_M) && d2 > R(EPS_M))) return;
    real path = d1 + d2;
    real2 Pw = C + P;
    real amp0 = k[K_AMPLITUDE] * beam(axis[pr.x], Pw - T, k) * beam(axis[pr.y], Pw - R_, k);
    if (!(amp0 > R(0.0))) return;
    real a_out = amp0 * k[K_RHO] * curved_gain(d1, d2, R(1.0) / r, cos_t, k) * absorption(path, k);
    if (!(a_out > R(0.0))) return;
    if (leg_blocked(T, Pw, occ, n_occ, -1, -1, circles, n_circles, ci)) return;
    if (leg_blocked(Pw, R_, occ, n_occ, -1, -1, circles, n_circles, ci)) return;
    tof[slot] = path * k[K_INV_C];
    amp[slot] = a_out;
    point[slot] = Pw;
}

// ----------------------------------------------------------------------------------------
// Specular points on sinusoids P(s) = F + s·t + A·sin(ωs)·ν (ν the base line's left normal),
// one work item per sampling interval [s0, s1]. The path length |T − P| + |R − P| is
// stationary where f(s) = dot(P'(s), û_T + û_R) = 0. The interval is half-open [s0, s1) (the
// curve's last one closed) so a root on a shared sample is found once; a fixed number of
// bisection steps refines it. Valid iff T and R are strictly on the same side of the tangent.
// Curvature k = cross(P', P'')/|P'|³; seen from the sensors' side σ (+1: left of P') the
// convexity is κ = −σ·k; cosθi = |dot(unit normal, û_T)|. Amplitude factor ρ·curved_gain.

// curve row: Fx, Fy, tx, ty, amplitude, omega, length (geometry.curve_point).
inline real2 curve_at(__global const real *cv, real s) {
    real h = cv[4] * sin(cv[5] * s);
    return (real2)(cv[0] + s * cv[2] - h * cv[3], cv[1] + s * cv[3] + h * cv[2]);
}

inline real2 curve_d1(__global const real *cv, real s) {
    real h1 = cv[4] * cv[5] * cos(cv[5] * s);
    return (real2)(cv[2] - h1 * cv[3], cv[3] + h1 * cv[2]);
}

inline real2 curve_d2(__global const real *cv, real s) {
    real h2 = -(cv[4] * cv[5] * cv[5]) * sin(cv[5] * s);
    return (real2)(-h2 * cv[3], h2 * cv[2]);
}

inline real curve_residual(__global const real *cv, real s, real2 T, real2 R_) {
    real2 p = curve_at(cv, s);
    real2 ut = T - p;
    real2 ur = R_ - p;
    return dot2(curve_d1(cv, s), ut / norm2(ut) + ur / norm2(ur));
}

__kernel void curve_paths(PAIR_ARGS, __global const real *curves,
                          __global const int *interval_curve, __global const real2 *interval_s,
                          __global const int2 *interval_skip, __global const int *interval_last,
                          OCCLUDER_ARGS, OUTPUT_ARGS) {
    if (get_global_id(0) >= (size_t)width) return;
    size_t slot = clear_slot(width, tof, amp, point, phase);
    int iv = get_global_id(0);
    int2 pr = pairs[get_global_id(1)];
    __global const real *cv = curves + 7 * interval_curve[iv];
    real2 T = pos[pr.x], R_ = pos[pr.y];
    real2 span = interval_s[iv];
    real f0 = curve_residual(cv, span.x, T, R_);
    real f1 = curve_residual(cv, span.y, T, R_);
    bool bracket = f0 == R(0.0) || (f1 != R(0.0) && ((f0 < R(0.0)) != (f1 < R(0.0)))) ||
                   (interval_last[iv] && f1 == R(0.0));
    if (!bracket) return;
    real lo = span.x, hi = span.y;
    if (f0 == R(0.0)) hi = lo;
    else if (f1 == R(0.0)) lo = hi;
    for (int it = 0; it < BISECT_ITERATIONS; ++it) {
        real mid = R(0.5) * (lo + hi);
        real f = curve_residual(cv, mid, T, R_);
        if (f != R(0.0) && ((f < R(0.0)) == (f0 < R(0.0)))) lo = mid;
        else hi = mid;
    }
    real s = R(0.5) * (lo + hi);
    real2 P = curve_at(cv, s);
    real2 d1v = curve_d1(cv, s);
    real2 vt = T - P, vr = R_ - P;
    real side_t = cross2(d1v, vt), side_r = cross2(d1v, vr);
    if (!((side_t > R(0.0) && side_r > R(0.0)) || (side_t < R(0.0) && side_r < R(0.0)))) return;
    real d1 = norm2(vt), d2 = norm2(vr);
    if (!(d1 > R(EPS_M) && d2 > R(EPS_M))) return;
    real path = d1 + d2;
    real amp0 = k[K_AMPLITUDE] * beam(axis[pr.x], P - T, k) * beam(axis[pr.y], P - R_, k);
    if (!(amp0 > R(0.0))) return;
    real speed = norm2(d1v);
    real curvature = cross2(d1v, curve_d2(cv, s)) / (speed * speed * speed);
    real kappa = side_t > R(0.0) ? -curvature : curvature;
    real cos_i = fabs(cross2(d1v, vt)) / (speed * d1);  // |dot(unit normal, û_T)|
    real a_out = amp0 * k[K_RHO] * curved_gain(d1, d2, kappa, cos_i, k) * absorption(path, k);
    if (!(a_out > R(0.0))) return;
    int2 skip = interval_skip[iv];
    if (leg_blocked(T, P, occ, n_occ, skip.x, skip.y, circles, n_circles, -1)) return;
    if (leg_blocked(P, R_, occ, n_occ, skip.x, skip.y, circles, n_circles, -1)) return;
    tof[slot] = path * k[K_INV_C];
    amp[slot] = a_out;
    point[slot] = P;
}
