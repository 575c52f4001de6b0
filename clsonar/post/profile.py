"""The profile stage (thesis §2.1.1, part 5): the thinned cells linked into curves, refined
to sub-cell positions in metres, and fitted as ``settings.fit`` says."""

from __future__ import annotations

import math

import numpy as np

from ..geometry import cell_centres
from ..mapping.along import ScanHeard
from ..numerics import median
from ..scene import PostSettings
from ..scene.settings import chosen
from .curves import MIN_CURVE_CELLS, bridge_gaps, point_means, refine_cells, trace_curves
from .fits import Profile, fit_polynomial, fit_spline
from .walls import fit_walls

#: A profile point may lie at most this many cells from an occupied cell of the map
#: (:func:`bound_profile`).
NEAR_CELLS = 3


def extract_profile(thin_map: np.ndarray, extent: tuple[float, ...], cell: float,
                    settings: PostSettings, weights: np.ndarray | None = None,
                    counts: np.ndarray | None = None,
                    sums: np.ndarray | None = None, occupied: np.ndarray | None = None,
                    origin: tuple[int, int] = (0, 0),
                    heard: ScanHeard | None = None) -> Profile:
    """Link the thin cells into curves, refine them to sub-cell positions (``subcell``: the
    mean of the mapped points around each cell when the map counts points, ``counts`` and
    ``sums``, else the centroid of the filtered map ``weights``), bridge gaps up to
    ``settings.max_gap_m`` and fit: one polynomial along the principal axis over the data's
    span (``polynomial``, the thesis), straight walls joined at corners and edges
    (``walls``, :func:`~clsonar.post.walls.fit_walls`, with what the scan ``heard`` along
    them), a smoothing spline per curve
    (``spline``) or the points as linked (``none``). With the ``occupied`` map (the maps'
    cell [0, 0] is cell ``origin`` of the scene's grid) the fitted profile is then bounded
    by :func:`bound_profile`."""
    fit = chosen(settings.fit, "post.fit")
    max_gap = chosen(settings.max_gap_m, "post.max_gap_m")
    curves = _curves_in_metres(_traced(thin_map, cell), extent, cell, settings, weights, counts,
                               sums)
    if fit == "polynomial":
        fitted = Profile(tuple(fit_polynomial(np.concatenate(curves), settings.poly_order,
                                              cell)) if curves else ())
    elif fit == "walls":
        fitted = fit_walls(curves, cell, settings, heard, extent)
    else:
        curves = bridge_gaps(curves, max_gap)
        if fit == "spline":
            curves = [fit_spline(c, cell, cell / 2) for c in curves]
        fitted = Profile(tuple(curves))
    if occupied is None:
        return fitted
    return bound_profile(fitted, occupied, extent, cell, origin, max_gap)


#: Where the map holds no curve of :data:`MIN_CURVE_CELLS`, its curves of this many cells
#: are the profile (:func:`_traced`).
LEAST_CURVE_CELLS = 2

#: A curve this long (metres) is no speck, however few cells it spans (:func:`_traced`).
MIN_CURVE_M = 0.04


def _traced(thin_map: np.ndarray, cell: float) -> list[np.ndarray]:
    """The thin map's curves as long as :data:`MIN_CURVE_CELLS` cells in a row or more
    (shorter ones are specks beside them), or :data:`MIN_CURVE_M`; where it has none,
    those of :data:`LEAST_CURVE_CELLS` cells or more: the few echoes of a reflector only
    two elements heard (a thin post 0.5 m from a sparse array, the zoo's unseen seed 33
    post-03: its loci cross in three cells) are what the map has, and a profile of them
    says more than an empty one. A lone cell (one locus, or noise) stays out. The length
    counts a diagonal step √2 cells, and a speck is one in cells only where cells are
    small: on a map of 2 cm cells a pillar's stub, one locus' 10 cm of arc, thins to three
    diagonal cells (the zoo's unseen seed 170 room-16: eight of the two pillars' stubs,
    each the only one over its 13 cm of arc, were left out, 93 % complete)."""
    curves = trace_curves(thin_map, LEAST_CURVE_CELLS)
    least = min(MIN_CURVE_CELLS - 1, MIN_CURVE_M / cell)
    return [c for c in curves if _cells_long(c) >= least] or curves


def _cells_long(curve: np.ndarray) -> float:
    """How long the linked cells ``curve`` [n, 2] are, in cells: a diagonal step √2."""
    step = np.abs(np.diff(curve, axis=0)).sum(axis=1)
    return float(np.count_nonzero(step == 1) + math.sqrt(2.0) * np.count_nonzero(step == 2))


def bound_profile(profile: Profile, occupied: np.ndarray, extent: tuple[float, ...],
                  cell: float, origin: tuple[int, int] = (0, 0), max_gap: float = 0.0,
                  near: int = NEAR_CELLS) -> Profile:
    """``profile`` with only what the map supports, whatever the fit. A fit extends its
    data — a polynomial beyond its points, a circle round a cylinder's hidden side, a wall
    past the end of its patch — and only the map says how far that is honest:

    - a point is supported when it lies within ``near`` cells (centre to centre) of an
      occupied cell of ``occupied`` (whose cell [0, 0] is cell ``origin`` of the grid);
    - unsupported points are dropped and each curve is cut there, except in a stretch
      between two supported ones that is at most ``max_gap`` long (arc length: the gaps
      the settings let a fit bridge, ``post.max_gap_m``) or no longer than either of them
      (interpolation between data on both sides, as the thesis' polynomial between two
      arrays' patches), and at a curve's end that reaches a located vertex (a wall drawn
      to the corner or edge where it meets the next one, found from both);
    - no point and no located vertex outside the ``extent`` is kept.
    """
    curves = []
    insides, keeps = _supported(profile.curves, occupied, extent, cell, origin, near)
    for c, inside, keep in zip(profile.curves, insides, keeps, strict=True):
        if _closed(c) and keep.any() and not keep.all():
            start = int(np.flatnonzero(keep & ~np.roll(keep, 1))[0])  # a loop: start at
            c, keep, inside = (np.roll(a, -start, axis=0) for a in (c, keep, inside))  # data
        keep |= inside & _bridged(c, keep, max_gap, profile.vertices, cell)
        cuts = np.flatnonzero(np.diff(keep.astype(np.int8)) != 0) + 1
        for piece, kept in zip(np.split(c, cuts), np.split(keep, cuts), strict=True):
            if kept[0]:
                curves.append(piece)
    vertices = profile.vertices[_inside(profile.vertices, extent)]
    left = sum(len(c) for c in curves)
    return Profile(tuple(curves), vertices, len(profile.points) - left)


def _supported(curves: tuple[np.ndarray, ...], occupied: np.ndarray, extent: tuple[float, ...],
               cell: float, origin: tuple[int, int], near: int
               ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Per curve, [n] whether each point lies inside ``extent``, and whether it is also
    near an occupied cell (:func:`_near_occupied`): all curves' points at once, point by
    point."""
    if not curves:
        return [], []
    every = np.concatenate(curves)
    inside = _inside(every, extent)
    keep = inside & _near_occupied(every, occupied, extent, cell, origin, near)
    cuts = np.cumsum([len(c) for c in curves])[:-1]
    return np.split(inside, cuts), np.split(keep, cuts)


def _closed(curve: np.ndarray) -> bool:
    """Whether ``curve`` is a loop: its ends no farther apart than two of its steps."""
    if len(curve) < 4:
        return False
    steps = np.hypot(*np.diff(curve, axis=0).T)
    return bool(np.hypot(*(curve[0] - curve[-1])) <= 2 * median(steps))


def _bridged(curve: np.ndarray, supported: np.ndarray, max_gap: float, vertices: np.ndarray,
             cell: float) -> np.ndarray:
    """[n] bool: the unsupported points of ``curve`` [n, 2] that :func:`bound_profile`
    keeps: in a stretch between two supported ones, at most ``max_gap`` long or no longer
    than either; in an end stretch whose end lies within a cell of one of ``vertices``."""
    out = np.zeros(len(curve), dtype=bool)
    if not supported.any():
        return out
    arc = np.r_[0.0, np.cumsum(np.hypot(*np.diff(curve, axis=0).T))]
    cuts = np.flatnonzero(np.diff(supported.astype(np.int8)) != 0) + 1
    runs = np.split(np.arange(len(curve)), cuts)
    for k, run in enumerate(runs):
        if supported[run[0]]:
            continue
        if 0 < k < len(runs) - 1:
            before, after = runs[k - 1], runs[k + 1]
            span = arc[after[0]] - arc[before[-1]]
            out[run] = span <= max(max_gap, min(arc[before[-1]] - arc[before[0]],
                                                 arc[after[-1]] - arc[after[0]]))
        elif len(vertices):
            end = curve[run[0] if k == 0 else run[-1]]
            out[run] = bool(np.min(np.hypot(*(vertices - end).T)) <= cell)
    return out


def _inside(points: np.ndarray, extent: tuple[float, ...]) -> np.ndarray:
    """[n] bool: ``points`` [n, 2] inside ``extent`` (its border included)."""
    xmin, ymin, xmax, ymax = extent
    x, y = points[:, 0], points[:, 1]
    return (x >= xmin) & (x <= xmax) & (y >= ymin) & (y <= ymax)


def _near_occupied(points: np.ndarray, occupied: np.ndarray, extent: tuple[float, ...],
                   cell: float, origin: tuple[int, int], near: int) -> np.ndarray:
    """[n] bool: the cell of each of ``points`` is within ``near`` cells (centre to centre)
    of an occupied cell of ``occupied`` (cell [0, 0] at ``origin`` of the grid)."""
    ny, nx = occupied.shape
    with np.errstate(invalid="ignore"):
        iy = np.floor((points[:, 1] - extent[1]) / cell) - origin[0]
        ix = np.floor((points[:, 0] - extent[0]) / cell) - origin[1]
    ok = np.isfinite(iy) & np.isfinite(ix)
    iy = np.where(ok, iy, -near - 1).astype(np.int64)
    ix = np.where(ok, ix, -near - 1).astype(np.int64)
    found = np.zeros(len(points), dtype=bool)
    for dy in range(-near, near + 1):
        for dx in range(-near, near + 1):
            if dy * dy + dx * dx > near * near:
                continue
            y, x = iy + dy, ix + dx
            valid = (y >= 0) & (y < ny) & (x >= 0) & (x < nx)
            found[valid] |= occupied[y[valid], x[valid]]
    return found


def _curves_in_metres(linked: list[np.ndarray], extent: tuple[float, ...], cell: float,
                      settings: PostSettings, weights: np.ndarray | None,
                      counts: np.ndarray | None, sums: np.ndarray | None) -> list[np.ndarray]:
    """The linked curves of cells ``[iy, ix]`` as points in metres: the mean of the mapped
    points around each cell (``subcell`` with ``counts`` and ``sums``; a curve with none
    left is dropped), else the cell centres, at the centroid of ``weights`` (``subcell``
    with ``weights``) or as they are."""
    if not linked:
        return []
    every = np.concatenate(linked)  # all curves' cells at once, element by element
    cuts = np.cumsum([len(c) for c in linked])[:-1]
    if settings.subcell and counts is not None and sums is not None:
        n, total = point_means(every, counts, sums)
        return [t[k] / m[k, None] for m, t in zip(np.split(n, cuts), np.split(total, cuts),
                                                   strict=True) if (k := m > 0).any()]
    if settings.subcell and weights is not None:
        every = refine_cells(every, weights)
    return np.split(cell_centres(extent, cell, every[:, 0], every[:, 1]), cuts)


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


def with_patches(profile: Profile, points: np.ndarray | None, ends: np.ndarray | None,
                 keep: np.ndarray | None, radius: float) -> Profile:
    """``profile`` with fitted patches as its curves where they are: patch k is
    ``points[ends[k-1]:ends[k]]``, its points where ``keep`` holds, in runs, in place of
    the profile's curves within ``radius`` of them (:func:`overlay`). A patch of one point
    (a reflector smaller than the spacing of its points: a thin post's specular spot) is
    kept as it is."""
    if ends is None or len(ends) == 0 or points is None or keep is None:
        return profile
    starts = np.r_[0, ends[:-1]]
    pieces = [run for a, b in zip(starts, ends, strict=True)
              for run in runs(points[a:b], keep[a:b], min(2, b - a))]
    return overlay(profile, pieces, radius)


def with_vertices(profile: Profile, vertices: np.ndarray | None) -> Profile:
    """``profile`` with located point reflectors (corners, edges, thin posts) as one-point
    curves and vertices."""
    if vertices is None or len(vertices) == 0:
        return profile
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 2)
    return Profile(profile.curves + tuple(v[k:k + 1] for k in range(len(v))),
                   np.concatenate([profile.vertices, v]))


def within_extent(profile: Profile, extent: tuple[float, ...]) -> Profile:
    """``profile`` with no point and no vertex outside ``extent`` (curves cut there)."""
    def inside(p: np.ndarray) -> np.ndarray:
        return ((p[:, 0] >= extent[0]) & (p[:, 0] <= extent[2])
                & (p[:, 1] >= extent[1]) & (p[:, 1] <= extent[3]))

    curves = [run for c in profile.curves for run in runs(c, inside(c), 1)]
    return Profile(tuple(curves), profile.vertices[inside(profile.vertices)])


__all__ = ["NEAR_CELLS", "bound_profile", "extract_profile", "overlay", "runs",
           "with_patches", "with_vertices", "within_extent"]
