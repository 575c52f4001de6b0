// Directional maximum (Barshan 2007, "Directional processing of ultrasonic arc maps and its
// comparison with existing techniques", IJRR 26(8)): along each arc, the cells where the
// accumulated arc map is largest (host code and NumPy float64 reference in
// clsonar/mapping/directional.py).
//
// One work item per arc (locus row i, the rows of loci_map: T, R, axes, L = c·τ). It visits
// the pixels of box[i] = (x0, y0, x1, y1) (map pixel indices, inclusive; the bounding box of
// its band, from the host) and keeps those on the arc: the pixels loci_map gives a vote,
// | |p − T| + |p − R| − L | ≤ half_band inside both beams, decided by the same view_pixel on
// the same pixel centres (col0 + x, row0 + y)·cell. arc_maxima finds the largest value of
// `acc` (the accumulated map, [ny, nx]) on the arc, best[i] (0 if none), and how many of
// its pixels hold it, kept[i] (0 when best[i] = 0); arc_maxima_cells writes those pixels'
// indices y·nx + x, in row-major order, from cells[offset[i]] on. Both scan the box in
// the same order; no atomics, so the result does not depend on the work-group layout.

#define VEC 1
#include "real.h"
#include "loci.h"

// Whether pixel (x, y) of the map is on arc (tr, axes, L).
inline bool on_arc(int x, int y, real4 tr, real4 axes, real L, real cell, real half_band,
                   real cut_sin2, int col0, int row0) {
    real px = ((real)(col0 + x) + LANES) * cell;  // as loci_map's pixel centres
    real py = (real)(row0 + y) * cell;
    pixel_view v = view_pixel(px, py, tr, axes, cut_sin2);
    return (fabs(v.path - L) <= half_band) && v.inside;
}

__kernel void arc_maxima(__global const real4 *loci, __global const int4 *box, int n,
                         __global const real *acc, int nx, real cell, real half_band,
                         real cut_sin2, int col0, int row0, __global real *best,
                         __global int *kept) {
    int i = (int)get_global_id(0);
    if (i >= n) return;
    real4 tr = loci[3 * i], axes = loci[3 * i + 1];
    real L = loci[3 * i + 2].x;
    int4 b = box[i];
    real top = R(0.0);
    int count = 0;
    for (int y = b.y; y <= b.w; ++y)
        for (int x = b.x; x <= b.z; ++x) {
            if (!on_arc(x, y, tr, axes, L, cell, half_band, cut_sin2, col0, row0)) continue;
            real a = acc[(size_t)y * nx + x];
            if (a > top) {
                top = a;
                count = 1;
            } else if (a == top) {
                ++count;
            }
        }
    best[i] = top;
    kept[i] = top > R(0.0) ? count : 0;
}

__kernel void arc_maxima_cells(__global const real4 *loci, __global const int4 *box, int n,
                               __global const real *acc, int nx, real cell, real half_band,
                               real cut_sin2, int col0, int row0, __global const real *best,
                               __global const long *offset, __global long *cells) {
    int i = (int)get_global_id(0);
    if (i >= n || best[i] <= R(0.0)) return;
    real4 tr = loci[3 * i], axes = loci[3 * i + 1];
    real L = loci[3 * i + 2].x;
    int4 b = box[i];
    long k = offset[i];
    for (int y = b.y; y <= b.w; ++y)
        for (int x = b.x; x <= b.z; ++x) {
            size_t at = (size_t)y * nx + x;
            if (acc[at] == best[i] &&
                on_arc(x, y, tr, axes, L, cell, half_band, cut_sin2, col0, row0))
                cells[k++] = (long)at;
        }
}
