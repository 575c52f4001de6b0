"""The profile stage (thesis §2.1.1, part 5): the thinned cells linked into curves, refined
to sub-cell positions in metres, and fitted as ``settings.fit`` says."""

from __future__ import annotations

import numpy as np

from ..geometry import cell_centres
from ..scene import PostSettings
from .curves import MIN_CURVE_CELLS, bridge_gaps, refine_cells, refine_to_points, trace_curves
from .fits import Profile, fit_polynomial, fit_spline
from .walls import fit_walls


def extract_profile(thin_map: np.ndarray, extent: tuple[float, ...], cell: float,
                    settings: PostSettings, weights: np.ndarray | None = None,
                    counts: np.ndarray | None = None,
                    sums: np.ndarray | None = None) -> Profile:
    """Link the thin cells into curves, refine them to sub-cell positions (``subcell``: the
    mean of the mapped points around each cell when the map counts points, ``counts`` and
    ``sums``, else the centroid of the filtered map ``weights``), bridge gaps up to
    ``settings.max_gap_m`` and fit: one polynomial along the principal axis
    (``polynomial``, the thesis), straight walls joined at corners and edges (``walls``,
    :func:`~clsonar.post.walls.fit_walls`), a smoothing spline per curve (``spline``) or
    the points as linked (``none``)."""
    curves = _curves_in_metres(trace_curves(thin_map, MIN_CURVE_CELLS), extent, cell,
                               settings, weights, counts, sums)
    if settings.fit == "polynomial":
        if not curves:
            return Profile(())
        return Profile((fit_polynomial(np.concatenate(curves), settings.poly_order, cell),))
    if settings.fit == "walls":
        return fit_walls(curves, cell, settings)
    curves = bridge_gaps(curves, settings.max_gap_m)
    if settings.fit == "spline":
        curves = [fit_spline(c, cell, cell / 2) for c in curves]
    return Profile(tuple(curves))


def _curves_in_metres(linked: list[np.ndarray], extent: tuple[float, ...], cell: float,
                      settings: PostSettings, weights: np.ndarray | None,
                      counts: np.ndarray | None, sums: np.ndarray | None) -> list[np.ndarray]:
    """The linked curves of cells ``[iy, ix]`` as points in metres: the mean of the mapped
    points around each cell (``subcell`` with ``counts`` and ``sums``; a curve with none
    left is dropped), else the cell centres, at the centroid of ``weights`` (``subcell``
    with ``weights``) or as they are."""
    curves = []
    for c in linked:
        if settings.subcell and counts is not None and sums is not None:
            refined = refine_to_points(c, counts, sums)
            if refined is not None:
                curves.append(refined)
            continue
        if settings.subcell and weights is not None:
            c = refine_cells(c, weights)
        curves.append(cell_centres(extent, cell, c[:, 0], c[:, 1]))
    return curves


def runs(points: np.ndarray, keep: np.ndarray, least: int = 2) -> list[np.ndarray]:
    """The runs of consecutive ``points`` [n, 2] where ``keep`` holds, of at least
    ``least`` points each."""
    edges = np.flatnonzero(np.diff(np.r_[0, keep.astype(np.int8), 0]))
    return [points[a:b] for a, b in zip(edges[::2], edges[1::2], strict=True)
            if b - a >= least]


def overlay(profile: Profile, curves: list[np.ndarray], radius: float) -> Profile:
    """``profile`` with ``curves`` added and its own curves' points within ``radius`` of
    them left out (what is left of a curve in runs of at least :data:`MIN_CURVE_CELLS`
    points); its vertices kept."""
    if not curves:
        return profile
    from scipy.spatial import cKDTree

    tree = cKDTree(np.concatenate(curves))
    rest = []
    for c in profile.curves:
        far = tree.query(c, distance_upper_bound=radius)[0] > radius
        rest += runs(c, far, MIN_CURVE_CELLS)
    return Profile(tuple(curves) + tuple(rest), profile.vertices)


__all__ = ["extract_profile", "overlay", "runs"]
