"""The noise of the received signals: counter-based Philox4x32-10 (random123, as pyopencl
ships it) and Box–Muller, so a sample's noise is a function of (seed, T, R, n) alone — the
same on every device, work-group size and chunking. NumPy reference of the kernels'."""

from __future__ import annotations

import math

import numpy as np

#: Philox4x32 multipliers and Weyl key increments (random123, as in pyopencl's philox.cl).
PHILOX_M = (0xD2511F53, 0xCD9E8D57)
PHILOX_W = (0x9E3779B9, 0xBB67AE85)
PHILOX_ROUNDS = 10


def philox_key(seed: int) -> tuple[int, int]:
    """The Philox key of a noise ``seed``: its low and high 32 bits."""
    return (seed & 0xFFFFFFFF, (seed >> 32) & 0xFFFFFFFF)


def philox4x32(counter: np.ndarray, key: tuple[int, int]) -> np.ndarray:
    """Philox4x32-10 of ``counter`` ([..., 4] uint32) under ``key`` (k0, k1): [..., 4] uint32.

    Vectorised NumPy in uint64 arithmetic; bit-identical to random123's ``philox4x32``.
    """
    mask = np.uint64(0xFFFFFFFF)
    c = np.asarray(counter, dtype=np.uint32).astype(np.uint64)
    c0, c1, c2, c3 = c[..., 0], c[..., 1], c[..., 2], c[..., 3]
    k0, k1 = np.uint64(key[0] & 0xFFFFFFFF), np.uint64(key[1] & 0xFFFFFFFF)
    m0, m1 = np.uint64(PHILOX_M[0]), np.uint64(PHILOX_M[1])
    w0, w1 = np.uint64(PHILOX_W[0]), np.uint64(PHILOX_W[1])
    shift = np.uint64(32)
    for r in range(PHILOX_ROUNDS):
        if r:
            k0 = (k0 + w0) & mask
            k1 = (k1 + w1) & mask
        p0 = m0 * c0
        p1 = m1 * c2
        c0, c1, c2, c3 = (p1 >> shift) ^ c1 ^ k0, p1 & mask, (p0 >> shift) ^ c3 ^ k1, p0 & mask
    return np.stack([c0, c1, c2, c3], axis=-1).astype(np.uint32)


def box_muller(raw: np.ndarray) -> np.ndarray:
    """Four normals per four uint32 ([..., 4] → [..., 4] float64), as the kernel computes
    them: u = (2·(x >> 9) + 1)·2⁻²⁴, (r cos 2πv, r sin 2πv) with r = √(−2 ln u), for (x0, x1)
    and (x2, x3)."""
    x = np.asarray(raw, dtype=np.uint32)
    u = (2.0 * (x >> np.uint32(9)).astype(np.float64) + 1.0) * 2.0**-24
    r = np.sqrt(-2.0 * np.log(u[..., 0::2]))
    th = 2.0 * math.pi * u[..., 1::2]
    out = np.empty(x.shape, dtype=np.float64)
    out[..., 0::2] = r * np.cos(th)
    out[..., 1::2] = r * np.sin(th)
    return out


def noise(seed: int, tx: int, rx: int, n_samples: int, start: int = 0) -> np.ndarray:
    """Standard normals of samples [start, start + n_samples) of pair (tx, rx) (float64)."""
    key = philox_key(seed)
    if n_samples <= 0:
        return np.zeros(0)
    b0, b1 = start >> 2, (start + n_samples - 1) >> 2
    blocks = np.arange(b0, b1 + 1, dtype=np.uint64)
    ctr = np.zeros((len(blocks), 4), dtype=np.uint32)
    ctr[:, 0] = blocks.astype(np.uint32)
    ctr[:, 1] = tx
    ctr[:, 2] = rx
    z = box_muller(philox4x32(ctr, key)).ravel()
    off = start - 4 * b0
    return z[off:off + n_samples]
