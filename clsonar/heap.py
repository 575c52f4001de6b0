"""glibc's heap thresholds for a run's arrays (issue 16).

glibc hands a block of more than ``M_MMAP_THRESHOLD`` bytes (128 kB at start) straight
from the kernel and gives it back on ``free``; it raises that threshold, up to 32 MB, each
time such a block is freed, but only from then on. A floor's rooms allocate and free
arrays of a few hundred kB to tens of MB thousands of times, and each fresh mapping is
paid again in page faults: system time 0.9 s of the 30 m floor's 11 s, 9–10 s of the
100 m floor's 100 s. Which arrays a run happened to free first decided how soon the
threshold rose (a run that imported ``scipy.optimize`` freed a large block early and paid
0.4–0.6 s there). :func:`settle` sets the thresholds where glibc's own rule ends up — 32 MB
to map a block directly, 64 MB of free heap before it is given back — from the start, for
this process (``mallopt``) and the processes it starts (``MALLOC_MMAP_THRESHOLD_`` and
``MALLOC_TRIM_THRESHOLD_``, read by glibc as a process starts). Elsewhere (another C
library, or where the environment sets them already) nothing changes.
"""

from __future__ import annotations

import ctypes
import os

#: Blocks above this many bytes are mapped from the kernel directly (glibc's largest
#: dynamic threshold on a 64-bit machine).
MMAP_THRESHOLD = 32 << 20

#: Free memory at the top of the heap beyond this many bytes is given back (twice the above,
#: as glibc's dynamic rule sets it).
TRIM_THRESHOLD = 64 << 20

#: ``mallopt``'s parameter numbers (glibc's malloc.h).
_M_TRIM_THRESHOLD, _M_MMAP_THRESHOLD = -1, -3

_SETTINGS = {"MALLOC_MMAP_THRESHOLD_": (_M_MMAP_THRESHOLD, MMAP_THRESHOLD),
             "MALLOC_TRIM_THRESHOLD_": (_M_TRIM_THRESHOLD, TRIM_THRESHOLD)}


def settle() -> bool:
    """Set the heap thresholds above for this process and its children, unless the
    environment names either already; whether ``mallopt`` took them (glibc only)."""
    if any(name in os.environ for name in _SETTINGS):
        return False
    try:
        mallopt = ctypes.CDLL(None).mallopt  # the process's own symbols: its C library's
    except (OSError, AttributeError):
        return False
    taken = all(mallopt(number, value) == 1 for number, value in _SETTINGS.values())
    if taken:
        os.environ.update({name: str(value) for name, (_, value) in _SETTINGS.items()})
    return taken


__all__ = ["MMAP_THRESHOLD", "TRIM_THRESHOLD", "settle"]
