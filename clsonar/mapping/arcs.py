"""Two arc-map methods of the literature that work on the host: point marking
(``mapping.mode = "point-marking"``: one point at the middle of each arc, :func:`arc_middles`)
and morphological processing (``"morphological"``, Başkent & Barshan 1999: the binary arc
map closed, :func:`closed_arc_map`, then thinned by post-processing)."""

from __future__ import annotations

import numpy as np

from .. import geometry
from ..scene import Scene
from ..sensors import SensorArray
from .loci import as_loci
from .tangents import LOCUS_SAMPLES, run_starts, sample_loci


def _run_middles(inside: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(rows, middle)``: the rows of ``inside`` [n, S] with any sample in, and the
    (half-)index of the middle of each one's run of samples in (the run may wrap around
    sample 0; a row all in has its middle at (S − 1)/2)."""
    rows = np.flatnonzero(inside.any(axis=1))
    sub = inside[rows]
    return rows, run_starts(sub) + 0.5 * (np.count_nonzero(sub, axis=1) - 1)


def arc_middles(scene: Scene, sensors: SensorArray, loci) -> tuple[np.ndarray, np.ndarray]:
    """``(points [m, 2], source [m])``: point marking (PM; Barshan 2007, IJRR 26(8), after
    the thesis lab's comparison): each locus' reflector put at the middle of its arc inside
    the joint beam region of T and R, the one point a sonar that reports its axis would give
    (a surface met square on reflects there). The loci are sampled as the tangent points'
    are (every 360°/:data:`~clsonar.mapping.LOCUS_SAMPLES` of eccentric anomaly, both beams
    tested per sample): the middle is the middle of the run of samples in, to within half a
    sample (0.125°) of the true middle; between two samples, the midpoint of their chord.
    ``source`` is the locus of each point; loci with no sample in both beams give none."""
    loci = as_loci(loci)
    if len(loci) == 0:
        return np.zeros((0, 2)), np.zeros(0, dtype=np.int64)
    s = sample_loci(scene, sensors, loci)
    p = s.p
    rows, middle = _run_middles(s.inside)
    lo = np.floor(middle).astype(np.int64) % LOCUS_SAMPLES
    hi = np.ceil(middle).astype(np.int64) % LOCUS_SAMPLES
    return 0.5 * (p[rows, lo] + p[rows, hi]), rows.astype(np.int64)


def closed_arc_map(raw: np.ndarray, size: int = 3) -> np.ndarray:
    """Morphological processing (MP; Başkent & Barshan 1999, "Surface profile determination
    from multiple sonar data using morphological processing", IJRR 18(8)), its first step:
    the binary arc map (cells with a vote) closed — dilated, then eroded — by a ``size`` ×
    ``size`` square, which fills the gaps between neighbouring arcs and the notches of a
    band; the map's edge does not erode (the map is padded before closing). The thinning
    that follows is post-processing's (``post.thinning``, Guo–Hall by default)."""
    from scipy import ndimage  # only here: its import costs a plain run 0.2 s

    binary = np.asarray(raw) > 0
    pad = size
    closed = ndimage.binary_closing(np.pad(binary, pad), structure=np.ones((size, size), bool))
    return closed[pad:-pad, pad:-pad]


def cell_points(scene: Scene, cells: np.ndarray) -> np.ndarray:
    """[m, 2] the centres of the map's cells whose flat indices ``iy·nx + ix`` are
    ``cells`` (docs/design.md's cell-centre convention)."""
    iy, ix = np.divmod(np.asarray(cells, dtype=np.int64), scene.grid_shape[1])
    return geometry.cell_centres(scene.extent, scene.cell, iy, ix).reshape(-1, 2)
