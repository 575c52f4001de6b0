"""A corner off the right angle that one array heard as planes (``mapping.mode =
"reflectors"``): :func:`turned_corners`.

Two walls meeting at 90° − β/2 turn the double bounce's returning ray by β, so only pairs
about r·β apart hear it (none of the elements alone), and over one stretch of an array
their paths are a mirror's: a plane through the vertex, tilted by about β/2 from the
line of sight, fits them to micrometres (:func:`~.families._simplest` names the plane,
of two parameters, before the turned corner, of three). Each stretch then fits its own
plane, every one through the vertex, turned a little more from stretch to stretch — a
pencil of planes, which no wall makes (one wall's stretches give one line) — and they
were drawn as a wall through the vertex, across the corner (the zoo's unseen seed 118
corner-01: a 97° corner 8.3 m from a 62-element array, 19 planes from 2.29 to 2.49 rad,
21 cm RMS). The corner model (:func:`~.models.corner_paths`) fitted to the echoes of two
such planes together explains both where no plane does; it then takes every plane of
the array whose echoes it explains.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..numerics import unique
from .families import Family, Window, _fit, _fit_corner, _inliers, _predict, outside_allowed

#: Two planes of one array are a pencil's only where their normals part by at least this
#: (radians): nearly parallel lines are one wall's, their crossing far and ill-defined.
PENCIL_MIN_TURN_RAD = math.radians(0.2)

#: A pencil's vertex is where the planes cross, within this of both of their reflection
#: points' span (metres): the planes of a corner's double bounce all touch its vertex.
PENCIL_NEAR_M = 0.5

#: Pairs of planes tried per array (each try is two fits).
PENCIL_TRIES = 24

#: ``rows → Window``: the detections ``rows`` (loci) as one window.
MakeWindow = Callable[[np.ndarray], Window]


def _crossing(a: Family, b: Family) -> np.ndarray | None:
    """Where the planes of ``a`` and ``b`` cross, None where their normals part by less
    than :data:`PENCIL_MIN_TURN_RAD` or the crossing lies farther than
    :data:`PENCIL_NEAR_M` from either's reflection points."""
    pa, pb = float(a.params[0]), float(b.params[0])
    det = math.sin(pb - pa)
    if abs(det) < math.sin(PENCIL_MIN_TURN_RAD):
        return None
    da, db = float(a.params[1]), float(b.params[1])
    x = np.array([(da * math.sin(pb) - db * math.sin(pa)) / det,
                  (db * math.cos(pa) - da * math.cos(pb)) / det])
    for f in (a, b):
        if float(np.min(np.hypot(*(f.q - x).T))) > PENCIL_NEAR_M:
            return None
    return x


def _explains(w: Window, kind: str, params: np.ndarray, rows: np.ndarray) -> bool:
    """Whether the model explains all of ``rows`` but the share a best fit may leave out
    (:func:`~.families.outside_allowed`)."""
    found = _inliers(w, kind, params, rows)
    return len(found) >= len(rows) - outside_allowed(w, rows)


def _corner_of(parts: list[Family], start: np.ndarray, make_window: MakeWindow
               ) -> Family | None:
    """The corner family of the echoes of the planes ``parts`` together, fitted from the
    vertex ``start``, where it explains them and one plane does not; else None."""
    loci = unique(np.concatenate([p.loci for p in parts]))
    w = make_window(loci)
    rows = np.arange(len(loci))
    plane = _fit(w, "plane", rows, parts[0].params)
    if _explains(w, "plane", plane.params, rows):
        return None  # one wall's echoes
    fit = _fit_corner(w, rows, np.asarray(start[:2], dtype=np.float64))
    kept = _inliers(w, "corner", fit.params, rows)
    if len(kept) < len(rows) - outside_allowed(w, rows):  # as _explains
        return None
    return Family("corner", fit.params, w.x0, kept, _predict(w, "corner", fit.params, kept)[1],
                  fit.rms, w)


def _pencil(planes: list[Family], make_window: MakeWindow
            ) -> tuple[Family, list[Family]] | None:
    """``(corner, planes it takes)``: the first two of ``planes`` (most echoes first)
    whose echoes one corner explains (:func:`_corner_of`), with every other plane whose
    echoes it explains, refitted to all; None if no pair's does."""
    planes = sorted(planes, key=lambda f: -len(f.rows))
    tries = 0
    for i, a in enumerate(planes):
        for b in planes[i + 1:]:
            x = _crossing(a, b)
            if x is None:
                continue
            tries += 1
            if tries > PENCIL_TRIES:
                return None
            corner = _corner_of([a, b], x, make_window)
            if corner is None:
                continue
            taken = [a, b] + [p for p in planes if p is not a and p is not b and _explains(
                p.window, "corner", corner.params, p.rows)]
            return _corner_of(taken, corner.params, make_window) or corner, taken
    return None


def turned_corners(families: list[Family], group_of: np.ndarray, make_window: MakeWindow
                   ) -> list[Family]:
    """``families`` with each pencil of one array's planes that a turned corner explains
    (module docstring) replaced by that corner, in the place of its first plane
    (``group_of``: each locus's array)."""
    def array_of(f: Family) -> int:  # -1: the planes of several arrays' echoes
        groups = unique(group_of[f.loci])
        return int(groups[0]) if len(groups) == 1 else -1

    out = list(families)
    for g in unique([array_of(f) for f in out if f.kind == "plane"]):
        while g >= 0:
            planes = [f for f in out if f.kind == "plane" and array_of(f) == g]
            found = _pencil(planes, make_window) if len(planes) >= 2 else None
            if found is None:
                break
            corner, taken = found
            first = min(k for k, f in enumerate(out) if any(f is t for t in taken))
            out = [corner if k == first else f for k, f in enumerate(out)
                   if k == first or not any(f is t for t in taken)]
    return out


__all__ = ["PENCIL_MIN_TURN_RAD", "PENCIL_NEAR_M", "PENCIL_TRIES", "turned_corners"]
