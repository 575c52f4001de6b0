// The map: per-pixel accumulation of time-of-flight loci, the occupancy grid's log-odds and
// delay-and-sum back-projection
// (thesis §2.1.1, parts 3–4; host code in clsonar/mapping/launch.py, NumPy float64 reference in clsonar/mapping/reference.py).
//
// The kernels run over a rectangle of pixels: work item (gx, gy) owns VEC consecutive
// pixels of one row, columns col0 + gx·VEC + lane (lane = 0..VEC−1) and row row0 + gy, where
// columns and rows count from the *origin pixel*, whose centre is the local origin of every
// coordinate the host passes (transducers relative to it, in float64 before rounding to
// `real`). So a pixel centre is exactly ((real)col·cell, (real)row·cell): small integers
// times the cell, one rounding, and distances are differences of small numbers. The host
// puts the origin in the middle of the map (tiles share it, so that a tiled map is the
// dense one to the bit).
//
// Vectorisation: PoCL's CPU device does not vectorise a kernel across work items when its
// body holds a loop, so each work item computes VEC pixels as one realN vector (VEC = 8
// on CPUs: an AVX2 register of floats; 1 on GPUs). The loop over loci is uniform: every
// work item runs every locus, in order, with no early exit; the test is a mask and the vote
// a select. Only the costly parts that few pixels need, the beam weight's series and the
// back-projection's envelope gathers, wait behind "does any pixel of this work item vote"
// (skipping them changes no result). Loci come in __constant memory, one launch per block
// of them; `first` = 1 starts
// the sum at 0, else at the value already in `out`, so the sum over loci runs in locus order
// whatever the blocks (the reference sums in the same order).
//
// The host pads the rectangle to whole work-groups (fixed size: PoCL compiles a kernel anew
// for every work-group size) and `out` with it, and drops the padding.
//
// Compile-time constants: VEC (1, 2, 4, 8 or 16), WEIGHT_BEAM (1: vote b(θ_T)·b(θ_R)),
// BEAM_TERMS/BEAM_SERIES (common.h), MAX_FOCUS_GAIN (common.h), REAL_DOUBLE for float64.

#include "common.h"
#include "loci.h"

// b(θ_T)·b(θ_R) inside both beams: common.h's beam() on vectors, the same series in the same
// order from sin²θ = s²/|d|² (NaN where d = 0, which is never inside).
inline realv beam_of_sin2(realv sin2, real beam_u) {
    realv u = beam_u * sin2;
    realv sum = R(0.0);
    for (int i = BEAM_TERMS - 1; i >= 0; --i) sum = sum * u + beam_series[i];
    return (R(1.0) - u) * sum;
}

inline realv joint_beam(pixel_view v, real beam_u) {
    return beam_of_sin2((v.s_t * v.s_t) / v.dd_t, beam_u) *
           beam_of_sin2((v.s_r * v.s_r) / v.dd_r, beam_u);
}

// Start of this work item's pixels in `out`, and their centres relative to the origin.
#define PIXELS_OF_WORK_ITEM                                                              \
    size_t gx = get_global_id(0), gy = get_global_id(1);                                 \
    __global real *o = out + out_offset + gy * (size_t)pitch + gx * VEC;                  \
    realv px = ((realv)((real)(col0 + (int)(gx * VEC))) + LANES) * cell;                 \
    real py = (real)(row0 + (int)gy) * cell;                                             \
    realv acc = first ? (realv)(R(0.0)) : LOADV(o);

// Loci: every pixel p votes for each row (T, R, L = c·τ, w) with
// | |p − T| + |p − R| − L | ≤ half_band inside both beams; the vote is w (1 or the
// amplitude, from the host) or, with WEIGHT_BEAM, b(θ_T)·b(θ_R).
// loci[3i] = (Tx, Ty, Rx, Ry), loci[3i + 1] = (axis T, axis R), loci[3i + 2] = (L, w, 0, 0).
inline realv add_vote(realv acc, realv px, real py, real4 tr, real4 axes, real4 extra,
                      real half_band, real cut_sin2, real beam_u) {
    pixel_view v = view_pixel(px, py, tr, axes, cut_sin2);
    maskv vote = (fabs(v.path - extra.x) <= half_band) & v.inside;
#if WEIGHT_BEAM
    if (ANY(vote)) acc += vote ? joint_beam(v, beam_u) : (realv)(R(0.0));
#else
    acc += vote ? (realv)(extra.y) : (realv)(R(0.0));
#endif
    return acc;
}

__kernel void loci_map(__constant real4 *loci, int n_loci, real cell, real half_band,
                       real cut_sin2, real beam_u, int col0, int row0, int first,
                       __global real *out, long out_offset, int pitch) {
    PIXELS_OF_WORK_ITEM
    for (int i = 0; i < n_loci; ++i)
        acc = add_vote(acc, px, py, loci[3 * i], loci[3 * i + 1], loci[3 * i + 2], half_band,
                       cut_sin2, beam_u);
    STOREV(acc, o);
}

// Tiled loci: the same votes, each tile of the map testing only the loci whose band can
// reach it (clsonar/mapping/tiles.py bins them on the host, conservatively). One work-group per
// non-empty tile of tw × th pixels (the group is tw/VEC × th work items): work item
// (lx, ly) of group t owns the VEC pixels at column col0 + at[t].x + lx·VEC and row
// row0 + at[t].y + ly (counted from the origin pixel as above) and writes them, tile after
// tile, to out[t·tw·th + ly·tw + lx·VEC ...]; the host puts the tiles in place. The tile's
// loci are loci[members[k]] for k = start[t] .. start[t + 1] − 1, in the original order, so
// every pixel adds the same votes in the same order as loci_map: the same map, to the bit.
// They are copied TILE_CHUNK at a time into local memory by the whole group (one global
// read per locus and group, then every work item reads local memory). Empty tiles are not
// launched.
#ifndef TILE_CHUNK
#define TILE_CHUNK 64
#endif

__kernel void loci_tiles(__global const real4 *loci, __global const int *members,
                         __global const int *start, __global const int2 *at, real cell,
                         real half_band, real cut_sin2, real beam_u, int col0, int row0,
                         __global real *out) {
    __local real4 chunk[3 * TILE_CHUNK];
    size_t t = get_group_id(0);
    int lx = (int)get_local_id(0), ly = (int)get_local_id(1);
    int tw = (int)get_local_size(0) * VEC;
    int me = ly * (int)get_local_size(0) + lx;
    int items = (int)(get_local_size(0) * get_local_size(1));
    int2 a = at[t];
    __global real *o = out + t * (size_t)(tw * (int)get_local_size(1)) + ly * tw + lx * VEC;
    realv px = ((realv)((real)(col0 + a.x + lx * VEC)) + LANES) * cell;
    real py = (real)(row0 + a.y + ly) * cell;
    realv acc = (realv)(R(0.0));
    int end = start[t + 1];
    for (int c = start[t]; c < end; c += TILE_CHUNK) {
        int n = min(TILE_CHUNK, end - c);
        for (int k = me; k < 3 * n; k += items)
            chunk[k] = loci[3 * (size_t)members[c + k / 3] + (size_t)(k % 3)];
        barrier(CLK_LOCAL_MEM_FENCE);
        for (int i = 0; i < n; ++i)
            acc = add_vote(acc, px, py, chunk[3 * i], chunk[3 * i + 1], chunk[3 * i + 2],
                           half_band, cut_sin2, beam_u);
        barrier(CLK_LOCAL_MEM_FENCE);
    }
    STOREV(acc, o);
}

// Occupancy grid (Elfes 1987; Moravec & Elfes 1985): the log-odds each detection adds to a
// pixel inside both beams, by the sonar cone's sensor model: extra.y (occupied) where the
// path is within the band, | |p − T| + |p − R| − L | ≤ half_band, extra.z (empty) where it
// is shorter, |p − T| + |p − R| < L − half_band (the host puts 0 there for a pair's later
// echoes: beyond its first echo nothing is known empty). Same rows and launch as loci_map.
__kernel void occupancy_map(__constant real4 *loci, int n_loci, real cell, real half_band,
                            real cut_sin2, real beam_u, int col0, int row0, int first,
                            __global real *out, long out_offset, int pitch) {
    PIXELS_OF_WORK_ITEM
    for (int i = 0; i < n_loci; ++i) {
        real4 extra = loci[3 * i + 2];
        pixel_view v = view_pixel(px, py, loci[3 * i], loci[3 * i + 1], cut_sin2);
        realv miss = v.path - extra.x;
        acc += ((fabs(miss) <= half_band) & v.inside) ? (realv)(extra.y) : (realv)(R(0.0));
        acc += ((miss < -half_band) & v.inside) ? (realv)(extra.z) : (realv)(R(0.0));
    }
    STOREV(acc, o);
}

// Back-projection (delay and sum): every pixel adds, for each pair, the pair's envelope at
// the pixel's delay (|p − T| + |p − R|)/c, linearly interpolated between samples taken every
// dt from 0 (t = path·inv_c_dt samples; 0 beyond the last sample), inside both beams; with
// WEIGHT_BEAM times b(θ_T)·b(θ_R). pairs[2i] = (Tx, Ty, Rx, Ry), pairs[2i + 1] = (axis T,
// axis R); the envelope of pair i is env[i·n_samples ...], n_samples ≥ 2.
__kernel void backproject_map(__constant real4 *pairs, int n_pairs, __global const real *env,
                              int n_samples, real inv_c_dt, real cell,
                              real cut_sin2, real beam_u, int col0, int row0, int first,
                              __global real *out, long out_offset, int pitch) {
    PIXELS_OF_WORK_ITEM
    real last = (real)(n_samples - 1);
    for (int i = 0; i < n_pairs; ++i) {
        pixel_view v = view_pixel(px, py, pairs[2 * i], pairs[2 * i + 1], cut_sin2);
        realv t = v.path * inv_c_dt;
        maskv vote = (t <= last) & v.inside;
        if (!ANY(vote)) continue;  // the whole vector is outside the beams or past the end
        realv k = fmin(floor(t), last - R(1.0));
        realv f = t - k;
        intv ik = CONVERT_INTV(k);
        __global const real *e = env + (size_t)i * (size_t)n_samples;
        realv e0 = GATHER(e, ik);
        realv e1 = GATHER(e + 1, ik);
        realv w = e0 + f * (e1 - e0);
#if WEIGHT_BEAM
        w = w * joint_beam(v, beam_u);
#endif
        acc += vote ? w : (realv)(R(0.0));
    }
    STOREV(acc, o);
}
