// Received signals and detection (thesis eq. 2.3, §2.1.1 parts 3–4; model and host code in
// clsonar/signals/, whose NumPy float64 functions are the reference of every kernel here).
//
// The A-scan of a fired pair (T, R), sample n at time n/fs:
//
//     s[n] = Σ_e A_e·K·exp(−(u − 3σ)²/(2σ²))·sin(2π·(f/fs)·u + φ_e) + noise·N(0,1)[T, R, n]
//
// with φ_e the echo's carrier phase (0 but for an edge's diffraction; ea[e] = (A_e·K, φ_e)),
// u = n − τ_e·fs the sample's time after echo e's arrival (0 ≤ u ≤ 6σ, in samples) and
// s[n] = 0 for n < 0. Each echo arrives as its integer sample ek = floor(τ·fs) and the
// fraction ef = τ·fs − ek, so u = (n − ek) − ef is exact in float32 however long the window.
// The noise is counter-based: one Philox4x32-10 call (pyopencl's random123 header) with key
// (seed_lo, seed_hi) and counter (n >> 2, T, R, 0) gives four uint32, turned by Box–Muller into
// the normals of samples 4·(n >> 2) … 4·(n >> 2) + 3. Every sample is thus a function of
// (seed, T, R, n) alone: the same on any device, work-group size or chunking.
//
// Work decomposition: one work item per (pair slot, chunk of samples), flattened to one
// dimension (item = slot·n_chunks + chunk) and padded to the host's fixed work-group size, so
// PoCL compiles each kernel once. A work item recomputes the history samples its chunk needs
// (one sample for threshold crossings; 2·(BOX − 1) + SPAN for the envelope), so chunk
// boundaries neither lose nor duplicate detections. Candidates go to a bounded per-slot buffer
// through an atomic counter (one atomic per candidate, none per sample); the counter keeps
// counting past the capacity so the host knows how much room a re-run needs.
//
// Compile-time constants from the host: BOX (length of each of the two boxes of the envelope
// filter, samples), SPAN (half-span of the peak interpolation, samples), RING (2·SPAN + 1),
// HIST_BINS, HIST_BASE, HIST_STRIDE (the envelope histogram, see clsonar/signals/dsp.py),
// DEMOD_PERIOD (samples per carrier period when the carrier repeats in a whole number of
// samples, else 0), and REAL_DOUBLE for the float64 build.

#include "real.h"

#include <pyopencl-random123/philox.cl>

#define TWO_PI 6.283185307179586
// 2^-24: uniforms (2·(x >> 9) + 1)·2^-24 are exact in float32 and lie in (0, 1).
#define U24 5.9604644775390625e-08

// Per-scene signal constants, one real4 `kc` from the host (clsonar.signals.host.Runner).
typedef real4 signal_consts;
#define KC_NOISE(kc) ((kc).x)       // noise standard deviation, units
#define KC_SIGMA(kc) ((kc).y)       // σ of the pulse envelope, samples
#define KC_PULSE(kc) ((kc).z)       // 6σ, samples: the pulse's support is [0, 6σ]
#define KC_RATIO(kc) ((kc).w)       // carrier cycles per sample, f/fs

// --------------------------------------------------------------------------- noise

#ifdef REAL_DOUBLE
#define CONVERT_REAL4 convert_double4
inline real4 log_unit(real4 u) { return log(u); }
inline real4 sincos_turn(real4 v, real4 *c) { return sincos(R(TWO_PI) * v, c); }
#else
#define CONVERT_REAL4 convert_float4
// ln u for u in (0, 1]: u = 2^e·m with m in [√½, √2), ln m = 2·atanh(s), s = (m − 1)/(m + 1),
// |s| ≤ 0.172, by its odd series to s⁹ (truncation < 4e-10). Plain arithmetic, so it
// vectorises and rounds the same on every IEEE device; error ≤ 2e-7 relative.
inline float4 log_unit(float4 u) {
    int4 bits = as_int4(u);
    int4 e = ((bits >> 23) & 0xff) - 127;
    float4 m = as_float4((bits & 0x007fffff) | 0x3f800000);
    int4 big = m > 1.41421356f;
    m = select(m, m * 0.5f, big);
    e = e + (big & 1);
    float4 s = (m - 1.0f) / (m + 1.0f);
    float4 s2 = s * s;
    float4 p = s * (2.0f + s2 * (0.6666666667f + s2 * (0.4f + s2 * (0.2857142857f
                                                                    + s2 * 0.2222222222f))));
    return p + convert_float4(e) * 0.6931471805599453f;
}
// sin and cos of 2π·v for v in [0, 1): quarter turn q = floor(4v) (exact), y = (4v − q − ½)·π/2
// in [−π/4, π/4) by Taylor series to y⁹ / y¹⁰ (truncation < 3e-9), rotated by π/4 and q·π/2.
inline float4 sincos_turn(float4 v, float4 *c) {
    float4 v4 = v * 4.0f;
    float4 qf = floor(v4);
    int4 q = convert_int4(qf);
    float4 y = (v4 - qf - 0.5f) * 1.5707963267948966f;
    float4 y2 = y * y;
    float4 sy = y * (1.0f + y2 * (-1.0f / 6.0f + y2 * (1.0f / 120.0f + y2 * (-1.0f / 5040.0f
                                                              + y2 * (1.0f / 362880.0f)))));
    float4 cy = 1.0f + y2 * (-0.5f + y2 * (1.0f / 24.0f + y2 * (-1.0f / 720.0f + y2 * (
                                              1.0f / 40320.0f + y2 * (-1.0f / 3628800.0f)))));
    float4 sx = (sy + cy) * 0.70710678118654752f;
    float4 cx = (cy - sy) * 0.70710678118654752f;
    int4 odd = (q & 1) != 0;
    int4 neg = (q & 2) != 0;
    float4 c1 = select(cx, -sx, odd);
    float4 s1 = select(sx, cx, odd);
    *c = select(c1, -c1, neg);
    return select(s1, -s1, neg);
}
#endif

inline uint4 philox_block(uint block, uint tx, uint rx, uint k0, uint k1) {
    philox4x32_ctr_t c = {{block, tx, rx, 0u}};
    philox4x32_key_t k = {{k0, k1}};
    philox4x32_ctr_t x = philox4x32(c, k);
    return (uint4)(x.v[0], x.v[1], x.v[2], x.v[3]);
}

// The eight normals of samples 8·group … 8·group + 7 of pair (tx, rx): Philox blocks 2·group
// and 2·group + 1, each (x0, x1, x2, x3) → r(x0)·(cos, sin)(2π·v(x1)), r(x2)·(cos, sin)(2π·v(x3))
// with r(x) = √(−2 ln u(x)), u(x) = v(x) = (2·(x >> 9) + 1)·2⁻²⁴.
inline void normals8(uint group, uint tx, uint rx, uint k0, uint k1, real v[8]) {
    uint4 a = philox_block(2u * group, tx, rx, k0, k1);
    uint4 b = philox_block(2u * group + 1u, tx, rx, k0, k1);
    uint4 xr = (uint4)(a.s0, a.s2, b.s0, b.s2);
    uint4 xt = (uint4)(a.s1, a.s3, b.s1, b.s3);
    real4 u = CONVERT_REAL4(2u * (xr >> 9) + 1u) * R(U24);
    real4 w = CONVERT_REAL4(2u * (xt >> 9) + 1u) * R(U24);
    real4 r = sqrt(R(-2.0) * log_unit(u));
    real4 c;
    real4 s = sincos_turn(w, &c);
    c *= r;
    s *= r;
    v[0] = c.s0; v[1] = s.s0; v[2] = c.s1; v[3] = s.s1;
    v[4] = c.s2; v[5] = s.s2; v[6] = c.s3; v[7] = s.s3;
}

// --------------------------------------------------------------------------- the A-scan

// What a work item carries along its samples: the window [a, b) of echoes whose pulse may
// cover the current samples.
typedef struct {
    int a, b, hi, reach;
} scan_state;

// First echo in [lo, hi) with ek ≥ limit (echoes are sorted by time of flight: ek ascends).
inline int first_echo(__global const int *ek, int lo, int hi, int limit) {
    while (lo < hi) {
        int mid = (lo + hi) >> 1;
        if (ek[mid] < limit) lo = mid + 1; else hi = mid;
    }
    return lo;
}

// Start a scan at sample n: an echo can cover n only if ek ≥ n − reach (reach = ⌈6σ⌉ + 1).
inline void scan_init(scan_state *st, __global const int *ek, int4 pr, int n,
                      signal_consts kc) {
    st->reach = (int)ceil(KC_PULSE(kc)) + 1;
    st->a = first_echo(ek, pr.z, pr.w, n - st->reach);
    st->b = st->a;
    st->hi = pr.w;
}

// s[n] for the eight samples n = 8·group … 8·group + 7 (0 for n < 0). Groups must be visited
// in increasing order. Each sample sums only the echoes whose pulse covers it.
inline void signal8(scan_state *st, int group, int4 pr, uint k0, uint k1, signal_consts kc,
                    __global const int *ek, __global const real *ef,
                    __global const real2 *ea, real s[8]) {
    if (group < 0) {
        for (int i = 0; i < 8; ++i) s[i] = R(0.0);
        return;
    }
    if (KC_NOISE(kc) > R(0.0)) {
        normals8((uint)group, (uint)pr.x, (uint)pr.y, k0, k1, s);
        for (int i = 0; i < 8; ++i) s[i] *= KC_NOISE(kc);
    } else {
        for (int i = 0; i < 8; ++i) s[i] = R(0.0);
    }
    int n0 = group << 3;
    if (st->a == st->b && (st->b == st->hi || ek[st->b] > n0 + 7)) return;
    real centre = R(3.0) * KC_SIGMA(kc);
    real two_s2 = R(2.0) * KC_SIGMA(kc) * KC_SIGMA(kc);
    for (int i = 0; i < 8; ++i) {
        int n = n0 + i;
        while (st->b < st->hi && ek[st->b] <= n) st->b++;
        while (st->a < st->b && ek[st->a] + st->reach < n) st->a++;
        for (int e = st->a; e < st->b; ++e) {
            real u = (real)(n - ek[e]) - ef[e];
            if (u >= R(0.0) && u <= KC_PULSE(kc)) {
                real d = u - centre;
                real env = exp(-(d * d) / two_s2);
                s[i] += ea[e].x * env * sin(R(TWO_PI) * (KC_RATIO(kc) * u) + ea[e].y);
            }
        }
    }
}

// --------------------------------------------------------------------------- test kernels

// Raw Philox outputs and normals of blocks [block0, block0 + count) of pair (tx, rx).
__kernel void philox_normals(uint k0, uint k1, uint tx, uint rx, uint block0, int count,
                             __global uint4 *raw, __global real4 *normals) {
    int i = get_global_id(0);
    if (i >= count) return;
    uint block = block0 + (uint)i;
    raw[i] = philox_block(block, tx, rx, k0, k1);
    real v[8];
    normals8(block >> 1, tx, rx, k0, k1, v);
    int o = (block & 1u) ? 4 : 0;
    normals[i] = (real4)(v[o], v[o + 1], v[o + 2], v[o + 3]);
}

// Samples [0, n_samples) of every pair slot into out[slot·n_samples + n].
__kernel void a_scans(__global const int4 *pairs, int n_slots, __global const int *ek,
                      __global const real *ef, __global const real2 *ea, uint k0, uint k1,
                      signal_consts kc, int n_samples, int chunk, int n_chunks,
                      __global real *out) {
    int item = get_global_id(0);
    if (item >= n_slots * n_chunks) return;
    int slot = item / n_chunks;
    int n0 = (item - slot * n_chunks) * chunk;
    int n1 = min(n0 + chunk, n_samples);
    int4 pr = pairs[slot];
    scan_state st;
    scan_init(&st, ek, pr, n0, kc);
    real sv[8];
    for (int g = n0 >> 3; (g << 3) < n1; ++g) {
        signal8(&st, g, pr, k0, k1, kc, ek, ef, ea, sv);
        for (int i = 0; i < 8; ++i) {
            int n = (g << 3) + i;
            if (n >= n0 && n < n1) out[(size_t)slot * n_samples + n] = sv[i];
        }
    }
}

// --------------------------------------------------------------------------- threshold mode

// The (slot, chunk) of this work item: from the host's list `items` when it gives one (a
// noise-free scan leaves out the chunks no echo reaches: their signal is exactly 0), else
// item = slot·n_chunks + chunk. False when the item is past the end.
inline bool item_of(__global const int2 *items, int n_items, int n_slots, int n_chunks,
                    int *slot, int *c) {
    int item = get_global_id(0);
    if (items) {
        if (item >= n_items) return false;
        *slot = items[item].x;
        *c = items[item].y;
        return true;
    }
    if (item >= n_slots * n_chunks) return false;
    *slot = item / n_chunks;
    *c = item - *slot * n_chunks;
    return true;
}

// Rising crossings of `thr` (s[n − 1] < thr ≤ s[n]) for n in [1, n_samples), the thesis'
// detector (§2.1.1 parts 3–4). Each candidate stores n and s[n]. For T = R a work item stops
// at its first crossing (only the pair's first crossing counts); the host applies that rule
// and the hold-off across chunks.
__kernel void threshold_scan(__global const int4 *pairs, int n_slots, __global const int *ek,
                             __global const real *ef, __global const real2 *ea, uint k0,
                             uint k1, signal_consts kc, real thr, int n_samples, int chunk,
                             int n_chunks, int capacity, __global int *count,
                             __global int *cand_n, __global real *cand_v,
                             __global const int2 *items, int n_items) {
    int slot, c;
    if (!item_of(items, n_items, n_slots, n_chunks, &slot, &c)) return;
    int n0 = max(1, c * chunk);
    int n1 = min(c * chunk + chunk, n_samples);
    if (n0 >= n1) return;
    int4 pr = pairs[slot];
    bool first_only = pr.x == pr.y;
    scan_state st;
    scan_init(&st, ek, pr, n0 - 1, kc);
    real prev = thr;  // no crossing at n0 − 1's own turn: it only serves as s[n0 − 1]
    real sv[8];
    bool done = false;
    for (int g = (n0 - 1) >> 3; !done && (g << 3) < n1; ++g) {
        signal8(&st, g, pr, k0, k1, kc, ek, ef, ea, sv);
        for (int i = 0; i < 8; ++i) {
            int n = (g << 3) + i;
            if (n < n0 - 1 || n >= n1) continue;
            real s = sv[i];
            if (n >= n0 && prev < thr && s >= thr) {
                int k = atomic_inc(count + slot);
                if (k < capacity) {
                    cand_n[(size_t)slot * capacity + k] = n;
                    cand_v[(size_t)slot * capacity + k] = s;
                }
                if (first_only) { done = true; break; }
            }
            prev = s;
        }
    }
}

// --------------------------------------------------------------------------- envelope mode

// The envelope E[m]² at every sample m: quadrature demodulation z[n] = s[n]·exp(−2πi·r·n)
// (r = f/fs; the phase origin is the work item's first sample, which leaves |·| unchanged),
// two running boxes of BOX samples (a triangle of 2·BOX − 1 samples, about the matched filter
// of the pulse's Gaussian envelope), E² = calib²·|y|². Each box is a running sum over a ring
// of its last BOX inputs: O(1) per sample.
//
// mode 0 (detect): for m in the item's [m0, m1) ∩ [1, n_env): every local maximum
// E[m − 1] < E[m] ≥ E[m + 1] with E[m] ≥ floor[slot] is a candidate (m; E[m − SPAN], E[m],
// E[m + SPAN]); every HIST_STRIDE-th E[m]² goes to the slot's histogram (if `hist` is set) for
// the host's noise estimate. mode 1 (envelopes): out[slot·n_out + j] = E[j·dec + offset] for
// the item's outputs j.
inline void envelope_core(int mode, __global const int4 *pairs, int n_slots,
                          __global const int *ek, __global const real *ef,
                          __global const real2 *ea, uint k0, uint k1, signal_consts kc,
                          real calib2, int n_env, int chunk, int n_chunks,
                          __global const real *floor_, int capacity, __global int *count,
                          __global int *cand_n, __global real4 *cand_v, __global int *hist,
                          int dec, int offset, int n_out, __global real *out,
                          __global const real2 *demod, __global const int2 *items,
                          int n_items) {
    int slot, c;
    if (!item_of(items, n_items, n_slots, n_chunks, &slot, &c)) return;
    int4 pr = pairs[slot];
    int m0, m1, n_end;
    if (mode == 0) {
        m0 = c * chunk;
        m1 = min(m0 + chunk, n_env);
        n_end = m1 + SPAN;             // E is needed up to m1 − 1 + SPAN: m runs to m1 − 1
    } else {
        int j0 = c * chunk;
        int j1 = min(j0 + chunk, n_out);
        m0 = j0 * dec + offset;
        m1 = (j1 - 1) * dec + offset + 1;
        n_end = m1;
    }
    int n_start = m0 - SPAN - 2 * (BOX - 1);
    real flo2 = R(0.0);
    if (mode == 0) {
        real f = floor_[slot];
        flo2 = f * f;
    }

    real2 ring1[BOX], ring2[BOX];
    real ering[RING];
    int hloc[HIST_BINS];
    for (int i = 0; i < BOX; ++i) { ring1[i] = (real2)(R(0.0), R(0.0)); ring2[i] = ring1[i]; }
    for (int i = 0; i < RING; ++i) ering[i] = R(0.0);
    bool histogram = mode == 0 && hist != 0;
    if (histogram)
        for (int i = 0; i < HIST_BINS; ++i) hloc[i] = 0;

    real2 acc1 = (real2)(R(0.0), R(0.0));
    real2 acc2 = acc1;
    int bslot = 0;                     // ring1/ring2 slot of the sample BOX back
    int eslot = RING - 1;              // ering slot of E²[n] (advanced before the store)
    int next = mode == 0 ? m0 + (HIST_STRIDE - m0 % HIST_STRIDE) % HIST_STRIDE : m0;
#if DEMOD_PERIOD > 0
    int dslot = 0;
#endif
    scan_state st;
    scan_init(&st, ek, pr, max(n_start, 0), kc);
    real sv[8];
    for (int g = n_start >> 3; (g << 3) < n_end; ++g) {
      signal8(&st, g, pr, k0, k1, kc, ek, ef, ea, sv);
      for (int i = 0; i < 8; ++i) {
        int n = (g << 3) + i;
        if (n < n_start || n >= n_end) continue;
        real s = sv[i];
#if DEMOD_PERIOD > 0
        // exp(−2πi·r·k), k = n − n_start, from the host's table of one carrier period
        real2 w = demod[dslot];
        dslot = dslot + 1 == DEMOD_PERIOD ? 0 : dslot + 1;
        real2 z = s * w;
#else
        real cs;
        real sn = sincos(R(TWO_PI) * (KC_RATIO(kc) * (real)(n - n_start)), &cs);
        real2 z = (real2)(s * cs, -(s * sn));
#endif
        acc1 += z - ring1[bslot];
        ring1[bslot] = z;
        acc2 += acc1 - ring2[bslot];
        ring2[bslot] = acc1;
        bslot = bslot + 1 == BOX ? 0 : bslot + 1;
        real e2 = calib2 * (acc2.x * acc2.x + acc2.y * acc2.y);
        if (mode == 1) {
            if (n == next) {
                out[(size_t)slot * n_out + (n - offset) / dec] = sqrt(e2);
                next += dec;
            }
            continue;
        }
        eslot = eslot + 1 == RING ? 0 : eslot + 1;
        ering[eslot] = e2;
        int m = n - SPAN;
        if (m < m0) continue;
        // E²[m] = E²[n − SPAN], its neighbours, and E²[m − SPAN] (the oldest in the ring)
        int mid = eslot - SPAN < 0 ? eslot - SPAN + RING : eslot - SPAN;
        real q = ering[mid];
        if (m == next) {
            if (histogram) {
#ifdef REAL_DOUBLE
                uint bits = as_uint((float)q);
#else
                uint bits = as_uint(q);
#endif
                int b = (int)(bits >> 21) - HIST_BASE + 1;
                hloc[clamp(b, 0, HIST_BINS - 1)] += 1;
            }
            next += HIST_STRIDE;
        }
        if (m < 1 || q < flo2) continue;
        real before = ering[mid == 0 ? RING - 1 : mid - 1];
        real after = ering[mid + 1 == RING ? 0 : mid + 1];
        if (!(before < q && q >= after)) continue;
        int k = atomic_inc(count + slot);
        if (k < capacity) {
            int oldest = eslot + 1 == RING ? 0 : eslot + 1;
            cand_n[(size_t)slot * capacity + k] = m;
            cand_v[(size_t)slot * capacity + k] =
                (real4)(sqrt(ering[oldest]), sqrt(q), sqrt(e2), R(0.0));
        }
      }
    }
    if (histogram)
        for (int i = 0; i < HIST_BINS; ++i)
            if (hloc[i]) atomic_add(hist + (size_t)slot * HIST_BINS + i, hloc[i]);
}

__kernel void envelope_scan(__global const int4 *pairs, int n_slots, __global const int *ek,
                            __global const real *ef, __global const real2 *ea, uint k0,
                            uint k1, signal_consts kc, real calib2, int n_env, int chunk,
                            int n_chunks, __global const real *floor_, int capacity,
                            __global int *count, __global int *cand_n,
                            __global real4 *cand_v, __global int *hist,
                            __global const real2 *demod, __global const int2 *items,
                            int n_items) {
    envelope_core(0, pairs, n_slots, ek, ef, ea, k0, k1, kc, calib2, n_env, chunk, n_chunks,
                  floor_, capacity, count, cand_n, cand_v, hist, 1, 0, 0, 0, demod, items,
                  n_items);
}

__kernel void envelope_samples(__global const int4 *pairs, int n_slots, __global const int *ek,
                               __global const real *ef, __global const real2 *ea, uint k0,
                               uint k1, signal_consts kc, real calib2, int chunk, int n_chunks,
                               int dec, int offset, int n_out, __global real *out,
                               __global const real2 *demod) {
    envelope_core(1, pairs, n_slots, ek, ef, ea, k0, k1, kc, calib2, 0, chunk, n_chunks, 0, 0,
                  0, 0, 0, 0, dec, offset, n_out, out, demod, 0, 0);
}
