"""Post-processing of the accumulated map (thesis §2.1.1, part 5).

- :func:`low_pass`: the 3×3 mean filter of eq. 2.4;
- :func:`binarize`: occupied cells of the filtered map;
- :func:`thin_thesis`: the template of eq. 2.5 exactly as the thesis writes it;
- :func:`thin`: a proper thinning (Guo and Hall's parallel algorithm) that leaves one-pixel
  wide, 8-connected curves and keeps every curve's connectivity.

Maps are indexed ``[iy, ix]`` with ``iy`` growing with y (DESIGN.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy import ndimage

from .scene import PostSettings

#: Correlation weights giving each pixel an 8-bit code of its neighbours: bit k−1 is
#: neighbour x_k of Guo and Hall, counted counter-clockwise from x1 = east (array rows grow
#: downwards here, so "north" is row − 1; the algorithm is symmetric and does not care).
_NEIGHBOUR_BITS = np.array([[8, 4, 2], [16, 0, 1], [32, 64, 128]])


def low_pass(raw: np.ndarray) -> np.ndarray:
    """3×3 mean filter, thesis eq. 2.4 (``(1/9)·ones(3, 3)``), zero outside the map.

    Each cell is the sum of its nine cells, added in a fixed order, divided by 9: a cell's
    value depends on those nine cells only (a running-sum filter would leave rounding
    residues far from any vote), so filtering a part of the map gives the same values."""
    p = np.pad(np.asarray(raw, dtype=np.float64), 1)
    ny, nx = p.shape[0] - 2, p.shape[1] - 2
    total = np.zeros((ny, nx))
    for dy in range(3):
        for dx in range(3):
            total += p[dy:dy + ny, dx:dx + nx]
    return total / 9.0


def binarize(filtered: np.ndarray, level: float) -> np.ndarray:
    """Cells whose filtered value is at least ``level`` (the occupied, "black" cells). A cell
    with no vote is never occupied, so a map without echoes stays empty at any level."""
    filtered = np.asarray(filtered)
    return (filtered >= level) & (filtered > 0)


def thin_thesis(binary: np.ndarray, up: tuple[int, int] = (0, -1)) -> np.ndarray:
    """Thinning as thesis eq. 2.5 is written: keep a cell that matches

    ::

        0 0 0
        X 1 X      (X: don't care)
        1 1 1

    i.e. the three cells "above" it are empty and the three "below" it are occupied; every
    other cell is zeroed. This keeps one edge of each thick band, one pixel wide where the
    band is at least two pixels deep; cells outside the map count as empty.

    ``up`` is the array step ``(diy, dix)`` to the row above. The thesis' MATLAB maps index
    their rows by x ("a wall located 9 m away from the origin along the x direction" is a
    row of the image), so by default the row above a cell is the one at smaller x, and the
    template keeps the edge of a band that faces the sensors of the thesis' scenes.
    """
    b = np.pad(np.asarray(binary, dtype=bool), 1)
    ny, nx = binary.shape
    side = (up[1], up[0])  # perpendicular to up

    def shifted(dy: int, dx: int) -> np.ndarray:
        return b[1 + dy:1 + dy + ny, 1 + dx:1 + dx + nx]

    centre = shifted(0, 0)
    above = np.zeros_like(centre)
    below = np.ones_like(centre)
    for k in (-1, 0, 1):
        oy, ox = k * side[0], k * side[1]
        above |= shifted(up[0] + oy, up[1] + ox)
        below &= shifted(-up[0] + oy, -up[1] + ox)
    return centre & ~above & below


def _guo_hall_tables() -> tuple[np.ndarray, np.ndarray]:
    """Deletion tables of the two sub-iterations of Guo and Hall (1989), indexed by the
    8-bit neighbour code (bit k−1 = neighbour x_k, x1 = east, counter-clockwise)."""
    first = np.zeros(256, dtype=bool)
    second = np.zeros(256, dtype=bool)
    for code in range(256):
        x = [None] + [(code >> k) & 1 for k in range(8)] + [code & 1]  # x[1..8], x[9] = x1
        crossings = sum(1 for i in (1, 3, 5, 7) if not x[i] and (x[i + 1] or x[i + 2]))
        n1 = sum(x[2 * k - 1] | x[2 * k] for k in range(1, 5))
        n2 = sum(x[2 * k] | x[2 * k + 1] for k in range(1, 5))
        if crossings != 1 or not 2 <= min(n1, n2) <= 3:
            continue
        first[code] = ((x[2] | x[3] | (1 - x[8])) & x[1]) == 0
        second[code] = ((x[6] | x[7] | (1 - x[4])) & x[5]) == 0
    return first, second


_DELETE_FIRST, _DELETE_SECOND = _guo_hall_tables()


def _simple_table() -> np.ndarray:
    """Whether a foreground pixel with a given neighbour code is *simple*: deleting it keeps
    the topology (its neighbours form one 8-connected foreground component and it touches
    one 4-connected background component)."""
    table = np.zeros(256, dtype=bool)
    four = ndimage.generate_binary_structure(2, 1)
    for code in range(256):
        patch = (code & _NEIGHBOUR_BITS) > 0
        n_fg = ndimage.label(patch, np.ones((3, 3)))[1]
        bg, _ = ndimage.label(~patch & (_NEIGHBOUR_BITS > 0), four)
        touching = {bg[i, j] for i, j in ((0, 1), (1, 0), (1, 2), (2, 1)) if bg[i, j]}
        table[code] = n_fg == 1 and len(touching) == 1
    return table


_SIMPLE = _simple_table()


def _codes_at(b: np.ndarray, iy: np.ndarray, ix: np.ndarray) -> np.ndarray:
    """The neighbour code (the correlation with :data:`_NEIGHBOUR_BITS`) of the pixels
    ``(iy, ix)`` of ``b`` only — thinning needs it at set pixels, a few per cent of a map."""
    p = np.pad(b, 1)
    code = np.zeros(len(iy), dtype=np.int64)
    for i in range(3):
        for j in range(3):
            if _NEIGHBOUR_BITS[i, j]:
                code += int(_NEIGHBOUR_BITS[i, j]) * p[iy + i, ix + j]
    return code


def _redundant_at(b: np.ndarray, iy: np.ndarray, ix: np.ndarray) -> np.ndarray:
    """Whether the set pixels ``(iy, ix)`` make a curve thicker than one pixel in the
    8-connected sense: two orthogonal 4-neighbours set (a staircase corner, or part of a
    2×2 block)."""
    p = np.pad(b, 1)
    north, south = p[iy + 2, ix + 1], p[iy, ix + 1]
    east, west = p[iy + 1, ix + 2], p[iy + 1, ix]
    return (north | south) & (east | west)


def _guo_hall(skeleton: np.ndarray, max_iterations: int) -> np.ndarray:
    for _ in range(max_iterations):
        before = np.count_nonzero(skeleton)
        for table in (_DELETE_FIRST, _DELETE_SECOND):
            iy, ix = np.nonzero(skeleton)
            gone = table[_codes_at(skeleton, iy, ix)]
            skeleton[iy[gone], ix[gone]] = False
        if np.count_nonzero(skeleton) == before:
            break
    return skeleton


def thin(binary: np.ndarray, max_iterations: int = 10_000) -> np.ndarray:
    """Thin occupied bands to one-pixel-wide 8-connected curves, keeping the connectivity
    (and the holes) of every band.

    Guo and Hall's parallel thinning (the algorithm of ``skimage.morphology.thin``) runs
    to convergence; it can leave 2×2 blocks and staircase corners, whose *simple* pixels
    (deleting them keeps the topology) are then deleted one parity subfield at a time —
    pixels of one subfield are never neighbours, so deleting them together cannot
    disconnect anything. Both steps repeat until nothing changes. Each step looks only at
    the set pixels.
    """
    skeleton = np.asarray(binary, dtype=bool).copy()
    for _ in range(max_iterations):
        before = np.count_nonzero(skeleton)
        skeleton = _guo_hall(skeleton, max_iterations)
        for a, b in ((0, 0), (0, 1), (1, 0), (1, 1)):
            iy, ix = np.nonzero(skeleton)
            mine = (iy % 2 == a) & (ix % 2 == b)
            iy, ix = iy[mine], ix[mine]
            gone = _redundant_at(skeleton, iy, ix) & _SIMPLE[_codes_at(skeleton, iy, ix)]
            skeleton[iy[gone], ix[gone]] = False
        if np.count_nonzero(skeleton) == before:
            break
    return skeleton


# --------------------------------------------------------------------------- profile


def cell_centres(mask: np.ndarray, extent: tuple[float, ...], cell: float) -> np.ndarray:
    """[n, 2] metres: centres of the set cells of ``mask`` (``[iy, ix]``, DESIGN.md)."""
    iy, ix = np.nonzero(mask)
    return np.stack([extent[0] + (ix + 0.5) * cell, extent[1] + (iy + 0.5) * cell], axis=-1)


_EIGHT = np.ones((3, 3), dtype=bool)
_STEPS = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dy or dx]


def trace_curves(thin_map: np.ndarray, min_cells: int = 5) -> list[np.ndarray]:
    """Link the cells of a thinned map into ordered curves ([n, 2] ``(iy, ix)`` each).

    Cells with one neighbour are curve ends, cells with three or more are junctions; each
    run between ends and junctions becomes a curve (a closed loop without junctions is one
    curve, its first cell repeated at its end). Curves of fewer than ``min_cells`` cells
    (spurs, specks) are dropped.
    """
    t = np.asarray(thin_map, dtype=bool)
    rows, cols = voted_box(t, margin=1)  # only the set cells' box is looked at
    part = t[rows, cols]
    degree = ndimage.correlate(part.astype(np.uint8), _EIGHT.astype(np.uint8),
                               mode="constant") - 1
    iy, ix = np.nonzero(part)
    cells = set(zip((iy + rows.start).tolist(), (ix + cols.start).tolist(), strict=True))
    node = {(y + rows.start, x + cols.start)
            for y, x in zip(iy.tolist(), ix.tolist(), strict=True) if degree[y, x] != 2}
    used_edges: set[tuple] = set()
    curves = []

    def walk(start, first):
        path = [start, first]
        used_edges.add((start, first))
        used_edges.add((first, start))
        prev, here = start, first
        while here not in node and here != start:
            nxt = [n for n in _neighbours(here, cells) if n != prev and (here, n) not in used_edges]
            if not nxt:
                break
            # prefer the 4-neighbour, which is the curve's next cell at a staircase
            nxt.sort(key=lambda n: abs(n[0] - here[0]) + abs(n[1] - here[1]))
            prev, here = here, nxt[0]
            used_edges.add((prev, here))
            used_edges.add((here, prev))
            path.append(here)
        return path

    for start in sorted(node):
        for first in _neighbours(start, cells):
            if (start, first) not in used_edges:
                curves.append(walk(start, first))
    visited = {c for curve in curves for c in curve}
    for start in sorted(cells - visited - node):  # closed loops without junctions
        if start in visited:
            continue
        first = _neighbours(start, cells)[0]
        loop = walk(start, first)
        visited.update(loop)
        curves.append(loop)
    return [np.asarray(c) for c in curves if len(c) >= min_cells]


def _neighbours(c: tuple[int, int], cells: set) -> list[tuple[int, int]]:
    return [(c[0] + dy, c[1] + dx) for dy, dx in _STEPS if (c[0] + dy, c[1] + dx) in cells]


def bridge_gaps(curves: list[np.ndarray], max_gap: float) -> list[np.ndarray]:
    """Join curves whose ends are within ``max_gap`` (same units as the points), nearest
    ends first, each end at most once and never into a loop, reversing curves as needed:
    gaps left by unscanned parts of a surface."""
    from scipy.spatial import cKDTree

    curves = [np.asarray(c, dtype=np.float64) for c in curves]
    if len(curves) < 2:
        return curves
    ends = np.array([c[k] for c in curves for k in (0, -1)])  # end 2i: start of i, 2i+1: end
    pairs = np.array(sorted(cKDTree(ends).query_pairs(max_gap, output_type="set")))
    if len(pairs) == 0:
        return curves
    pairs = pairs[pairs[:, 0] // 2 != pairs[:, 1] // 2]
    order = np.argsort(np.hypot(*(ends[pairs[:, 0]] - ends[pairs[:, 1]]).T), kind="stable")
    link = {}  # end -> the end it is joined to
    root = list(range(len(curves)))

    def find(i: int) -> int:
        while root[i] != i:
            root[i] = root[root[i]]
            i = root[i]
        return i

    for a, b in pairs[order].tolist():
        if a in link or b in link or find(a // 2) == find(b // 2):
            continue
        link[a], link[b] = b, a
        root[find(a // 2)] = find(b // 2)
    out, done = [], set()
    for i in range(len(curves)):
        if i in done or (2 * i in link and 2 * i + 1 in link):
            continue  # chains are walked from a curve with a free end
        start_end = 2 * i if 2 * i not in link else 2 * i + 1  # the free end
        chain, end = [], start_end
        while True:
            k = end // 2
            done.add(k)
            chain.append(curves[k] if end % 2 == 0 else curves[k][::-1])
            other = end ^ 1  # the far end of this curve
            if other not in link:
                break
            end = link[other]
        out.append(np.concatenate(chain))
    return out


def fit_polynomial(points: np.ndarray, order: int, spacing: float) -> np.ndarray:
    """The thesis' polynomial fit (§2.1.1, part 5; order 5–8 in chapter 3): in the frame of
    the points' principal axis u, fit v = P(u) by least squares and sample it every
    ``spacing`` over the points' span of u. Returns [n, 2] points."""
    p = np.asarray(points, dtype=np.float64)
    if len(p) <= order:
        return p
    centre = p.mean(axis=0)
    _, _, vt = np.linalg.svd(p - centre, full_matrices=False)
    u_axis, v_axis = vt[0], vt[1]
    u = (p - centre) @ u_axis
    v = (p - centre) @ v_axis
    poly = np.polynomial.Polynomial.fit(u, v, order)
    us = np.arange(u.min(), u.max() + 0.5 * spacing, spacing)
    return centre + us[:, None] * u_axis + poly(us)[:, None] * v_axis


def fit_spline(curve: np.ndarray, spacing: float, noise: float) -> np.ndarray:
    """A smoothing spline through an ordered curve of points (scipy's parametric spline,
    smoothing chosen so the residual RMS is about ``noise``), sampled every ``spacing`` of
    arc length. Short or degenerate curves come back unchanged."""
    from scipy import interpolate

    p = np.asarray(curve, dtype=np.float64)
    keep = np.r_[True, np.any(np.diff(p, axis=0) != 0, axis=1)]
    p = p[keep]
    if len(p) < 4:
        return p
    steps = np.hypot(*np.diff(p, axis=0).T)
    closed = len(p) > 8 and np.hypot(*(p[0] - p[-1])) <= 2 * np.median(steps)
    if closed and np.any(p[0] != p[-1]):
        p = np.concatenate([p, p[:1]])
        steps = np.r_[steps, np.hypot(*(p[-1] - p[-2]))]
    arc = np.r_[0.0, np.cumsum(steps)]
    try:
        tck, _ = interpolate.splprep(p.T, u=arc, s=len(p) * noise**2, k=3, per=int(closed))
    except (ValueError, TypeError):
        return p
    samples = np.arange(0.0, arc[-1] + 0.5 * spacing, spacing)
    return np.stack(interpolate.splev(samples, tck), axis=-1)


# --------------------------------------------------------------------------- the stages


@dataclass(frozen=True, eq=False)
class Profile:
    """The estimated surfaces: curves of points in metres (the fitted profile), and the
    corners and edges located as intersections of adjoining walls (``fit = "walls"``)."""

    curves: tuple[np.ndarray, ...]
    vertices: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))

    @property
    def points(self) -> np.ndarray:
        """[n, 2] all curves' points (``profile.csv``)."""
        if not self.curves:
            return np.zeros((0, 2))
        return np.concatenate(self.curves)


#: Occupied cells need at least this many coincident votes after the low-pass (automatic
#: level): one locus band alone (√2 cells wide) averages to about 0.5 there, two to 1.
AUTO_LEVEL_VOTES = 0.75

#: Linked curves shorter than this many cells are dropped as specks.
MIN_CURVE_CELLS = 5


#: Automatic level of a map of surface points (``mapping.mode`` ``tangents``): any point
#: within a 3×3 neighbourhood (the points are already cross-checked by two loci).
AUTO_LEVEL_POINTS = 0.99 / 9.0


def occupancy_level(filtered: np.ndarray, settings: PostSettings, points: bool = False) -> float:
    """The value above which a filtered cell is occupied: ``settings.level`` × the map's
    maximum, or (automatic) :data:`AUTO_LEVEL_VOTES` for a map of loci — cells where loci
    coincide stay, lone arcs go — or :data:`AUTO_LEVEL_POINTS` for a map of points."""
    peak = float(np.max(filtered)) if np.size(filtered) else 0.0
    if settings.level is not None:
        return settings.level * peak
    return AUTO_LEVEL_POINTS if points else AUTO_LEVEL_VOTES


#: Zero cells kept around the voted cells when post-processing looks at their box only.
BOX_MARGIN = 4


def voted_box(raw: np.ndarray, margin: int = BOX_MARGIN) -> tuple[slice, slice]:
    """``(rows, cols)``: the bounding box of the voted (nonzero) cells of ``raw``, grown by
    ``margin`` cells and starting at an even row and column (thinning's subfields go by
    parity), clipped to the map; empty when nothing voted."""
    rows = np.flatnonzero(np.any(raw != 0, axis=1))
    if len(rows) == 0:
        return slice(0, 0), slice(0, 0)
    cols = np.flatnonzero(np.any(raw[rows[0]:rows[-1] + 1] != 0, axis=0))
    r0, c0 = max(0, rows[0] - margin) & ~1, max(0, cols[0] - margin) & ~1
    return (slice(r0, min(raw.shape[0], rows[-1] + margin + 1)),
            slice(c0, min(raw.shape[1], cols[-1] + margin + 1)))


def filter_box(raw: np.ndarray, settings: PostSettings, points: bool = False,
               box: bool = True) -> tuple[tuple[slice, slice], np.ndarray, np.ndarray]:
    """Low-pass (eq. 2.4, when ``settings.filter`` is ``mean3``), occupancy level and
    binarize: ``(window, filtered, occupied)`` of the map's ``window``.

    With ``box`` the window is the :func:`voted_box` — the same result as the whole map
    (every cell farther than one cell from a vote filters to exactly 0: a 3×3 window, zero
    outside the map; the level is a fraction of the maximum); else the whole map.
    """
    raw = np.asarray(raw)
    window = voted_box(raw) if box else (slice(0, raw.shape[0]), slice(0, raw.shape[1]))
    part = raw[window]
    filtered = low_pass(part) if settings.filter == "mean3" else np.asarray(part, float)
    return window, filtered, binarize(filtered, occupancy_level(filtered, settings, points))


def embed(shape: tuple[int, ...], window: tuple[slice, slice], part: np.ndarray) -> np.ndarray:
    """``part`` placed at ``window`` of a zero map of ``shape`` (``part`` itself when the
    window is the whole map)."""
    if part.shape == tuple(shape):
        return part
    full = np.zeros(shape, dtype=part.dtype)
    full[window] = part
    return full


def filter_and_thin(raw: np.ndarray, settings: PostSettings, points: bool = False,
                    box: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(filtered, occupied, thin)`` full-size maps of :func:`filter_box` and
    :func:`thin_map` (thinning changes only occupied cells, so the box gives the same)."""
    window, filtered, occupied = filter_box(raw, settings, points, box)
    thin_cells = thin_map(occupied, settings)
    shape = np.shape(raw)
    return (embed(shape, window, filtered), embed(shape, window, occupied),
            embed(shape, window, thin_cells))


def thin_map(occupied: np.ndarray, settings: PostSettings) -> np.ndarray:
    """The thinning stage: eq. 2.5 as written (``thesis``) or :func:`thin` (``guo-hall``)."""
    return thin_thesis(occupied) if settings.thinning == "thesis" else thin(occupied)


def _around(cells: np.ndarray, shape: tuple[int, ...], radius: int):
    """For each offset (dy, dx) of the (2·radius + 1)² window: the offset, the indices
    ``(iy, ix)`` of the cells' neighbours, and which of them lie inside the map (no padded
    copy of the map: this runs once per linked curve)."""
    for dy in range(-radius, radius + 1):
        for dx in range(-radius, radius + 1):
            iy, ix = cells[:, 0] + dy, cells[:, 1] + dx
            inside = (iy >= 0) & (iy < shape[0]) & (ix >= 0) & (ix < shape[1])
            yield dy, dx, np.where(inside, iy, 0), np.where(inside, ix, 0), inside


def refine_cells(cells: np.ndarray, weights: np.ndarray, radius: int = 1) -> np.ndarray:
    """[n, 2] sub-cell ``(iy, ix)`` of ``cells`` [n, 2]: the centroid of ``weights`` (the
    filtered map) over the (2·radius + 1)² cells around each. A vote ridge symmetric about
    the true surface puts the centroid on it, to a fraction of a cell."""
    cells = np.asarray(cells, dtype=np.int64)
    w = np.asarray(weights, dtype=np.float64)
    total = np.zeros(len(cells))
    moment = np.zeros((len(cells), 2))
    for dy, dx, iy, ix, inside in _around(cells, w.shape, radius):
        v = np.where(inside, w[iy, ix], 0.0)
        total += v
        moment += v[:, None] * np.array([dy, dx])
    shift = np.where(total[:, None] > 0, moment / np.maximum(total, 1e-300)[:, None], 0.0)
    return cells + shift


def refine_to_points(cells: np.ndarray, counts: np.ndarray, sums: np.ndarray,
                     radius: int = 1) -> np.ndarray | None:
    """[n, 2] metres: the mean of the points counted in the (2·radius + 1)² cells around each
    of ``cells`` (``counts`` per cell and ``sums`` [ny, nx, 2] of their coordinates); cells
    with no point nearby are dropped (None if none is left)."""
    cells = np.asarray(cells, dtype=np.int64)
    n = np.zeros(len(cells))
    total = np.zeros((len(cells), 2))
    for _, _, iy, ix, inside in _around(cells, counts.shape, radius):
        n += np.where(inside, counts[iy, ix], 0.0)
        total += np.where(inside[:, None], sums[iy, ix], 0.0)
    keep = n > 0
    return total[keep] / n[keep, None] if keep.any() else None


def extract_profile(thin_map: np.ndarray, extent: tuple[float, ...], cell: float,
                    settings: PostSettings, weights: np.ndarray | None = None,
                    counts: np.ndarray | None = None,
                    sums: np.ndarray | None = None) -> Profile:
    """Link the thin cells into curves, refine them to sub-cell positions (``subcell``: the
    mean of the mapped points around each cell when the map counts points, ``counts`` and
    ``sums``, else the centroid of the filtered map ``weights``), bridge gaps up to
    ``settings.max_gap_m`` and fit: one polynomial along the principal axis
    (``polynomial``, the thesis), a smoothing spline per curve (``spline``) or the points as
    linked (``none``)."""
    linked = trace_curves(thin_map, MIN_CURVE_CELLS)
    curves = []
    for c in linked:
        if settings.subcell and counts is not None and sums is not None:
            refined = refine_to_points(c, counts, sums)
            if refined is not None:
                curves.append(refined)
            continue
        if settings.subcell and weights is not None:
            c = refine_cells(c, weights)
        curves.append(np.stack([extent[0] + (c[:, 1] + 0.5) * cell,
                                extent[1] + (c[:, 0] + 0.5) * cell], axis=-1))
    if settings.fit == "polynomial":
        if not curves:
            return Profile(())
        return Profile((fit_polynomial(np.concatenate(curves), settings.poly_order, cell),))
    if settings.fit == "walls":
        from .rooms import fit_walls

        return fit_walls(curves, cell, settings)
    curves = bridge_gaps(curves, settings.max_gap_m)
    if settings.fit == "spline":
        curves = [fit_spline(c, cell, cell / 2) for c in curves]
    return Profile(tuple(curves))
