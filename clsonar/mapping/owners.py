"""Detections that a family of another window owns (``mapping.mode = "reflectors"``): a
plane widened by the rows no family explained that its plane predicts (:func:`widened`),
a family whose every echo is a located corner's double bounce
(:func:`a_corners_echoes`), point families of other windows that one point explains
(:func:`one_point_each`), and the leftover echoes a drawn face reflects
(:func:`drawn_faces_echoes`)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace

import numpy as np

from .envelope import in_beams
from .families import (
    GROW_ROUNDS,
    Family,
    Fit,
    Window,
    _fit,
    _inliers,
    _measured_bend,
    _predict,
    _strong,
    _tolerance,
    _valid,
    as_well_limit,
    detection_noise,
    outside_allowed,
)
from .starts import family_starts


def widened(f: Family, w: Window, free: np.ndarray) -> tuple[Family, np.ndarray]:
    """``(family, taken)``: the plane family ``f`` with the rows ``free`` of ``w`` (the
    detections no family explained, every array's) that its plane predicts within their
    tolerance, in front of it and inside both beams, as strong as a mirror's echo there
    (:func:`_inliers`): other elements' echoes of the same face, too few or too far apart
    to be a family of their own. Refitted to all of its rows, then widened again by the
    refitted plane, until it takes no more (at most :data:`GROW_ROUNDS` rounds, as
    :func:`_grow`: an echo far along the face, which the family's own short stretch
    predicts to 0.3 mm, fits once a nearer one has tilted the plane into place — the
    zoo's seed 39 wall-07); its bend measured over all of them (:func:`_bend`). ``f``
    itself (nothing taken) when it is no plane or takes none; a round that would give up
    rows an earlier one took, or whose refitted plane no longer explains all its rows, is
    not taken."""
    taken = free[:0]
    if f.kind != "plane":
        return f, taken
    kept: tuple[Window, Fit] | None = None  # the last round taken: its window and fit
    params = f.params
    for _ in range(GROW_ROUNDS):
        found = _inliers(w, "plane", params, free)
        if len(found) <= len(taken) or not np.isin(taken, found).all():
            break  # nothing more, or it would give up rows it took
        both = _joined(f, w, found)
        every = np.arange(len(both.paths))
        fit = _fit(both, "plane", every, params)
        if len(_inliers(both, "plane", fit.params, every)) < len(every):
            break
        taken, kept, params = found, (both, fit), fit.params
    if kept is None:
        return f, taken
    both, fit = kept  # its bend and reflection points, of the last round only
    every = np.arange(len(both.paths))
    bend = _measured_bend(both, every, {}, {"curve": fit.params}, detection_noise(both.tolerance))
    q = _predict(both, "plane", fit.params, every)[1]
    return Family("plane", fit.params, both.x0, every, q, fit.rms, both, bend), taken


#: Point families located at most this far apart are tried as one (:func:`one_point_each`),
#: metres.
SAME_POINT_M = 0.1


def one_point_each(families: list[Family]) -> list[Family]:
    """``families`` with the point families (edges, posts) that other windows or arrays
    located at one point, each pair whose echoes together one point explains (each
    family's as well as its own fit did, inside both beams: :func:`_explains`), as one
    family fitted to all of them, largest first. Each window's fit is as good as the
    spread of its own pairs allows: with noise, a convex edge seen by a short stretch of
    an array is placed by its loci's crossings, cm across the line of sight, and two such
    stretches (or arrays) together span more (the zoo's unseen seed 163 edge-02, σ 0.3:
    two arrays' point families 0.9 and 2.0 cm from the edge, together 0.28 cm)."""
    points = sorted((k for k, f in enumerate(families) if f.kind == "point"),
                    key=lambda k: -len(families[k].rows))
    out = list(families)
    gone: set[int] = set()
    for i in points:
        for j in points:
            if i == j or i in gone or j in gone or math.dist(
                    out[i].params, out[j].params) > SAME_POINT_M:
                continue
            f, g = out[i], out[j]  # a locus in both (windows overlap) counted once
            both = _joined(f, g.window, g.rows[~np.isin(g.loci, f.loci)])
            every = np.arange(len(both.paths))
            fit = _fit(both, "point", every, f.params)
            if all(len(rows) == 0 or _explains(both, rows, fit.params, as_well_limit(
                    h.rms, detection_noise(both.tolerance[rows])), "point")
                   for h, rows in ((f, every[:len(f.rows)]), (g, every[len(f.rows):]))):
                q = _predict(both, "point", fit.params, every)[1]
                out[i] = Family("point", fit.params, both.x0, every, q, fit.rms, both)
                gone.add(j)
    return [f for k, f in enumerate(out) if k not in gone]


def _joined(f: Family, w: Window, found: np.ndarray) -> Window:
    """The window of ``f``'s rows and the rows ``found`` of ``w``, about their middle."""
    a, b = f.window, f.rows

    def cat(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        return np.concatenate([x[b], y[found]])

    T, R = cat(a.T, w.T), cat(a.R, w.R)
    return replace(w, rows=cat(a.rows, w.rows), T=T, R=R, axT=cat(a.axT, w.axT),
                   axR=cat(a.axR, w.axR), paths=cat(a.paths, w.paths),
                   amplitude=cat(a.amplitude, w.amplitude),
                   tolerance=cat(a.tolerance, w.tolerance), x0=0.5 * (T + R).mean(axis=0))


def a_corners_echoes(f: Family, corner: Family) -> bool:
    """Whether every echo of ``f`` (a plane, point or curve family) is the double bounce
    of the located ``corner`` (a family of more rows): its model predicts each of them
    within their tolerance, its vertex inside both beams (:func:`_inliers`). Kleeman &
    Kuc's pairs tell a corner from a plane by about L²/(4r) of path (L the pair's
    separation, r the range): a few elements of an array far away, or its last stretch's
    weak echoes, cannot, and their echoes of the vertex fit a plane through it, square to
    their line of sight, as well; the corner that pairs farther apart located explains
    them as one reflector. With noise, all but the share of them a best fit may leave
    outside their tolerance (:func:`outside_allowed`), as :func:`_simplest` names
    families (the zoo's seed 12 corner-05, σ 0.6: 44 of a plane's 45 echoes, one 0.1 mm
    beyond its 1.4 mm tolerance, and the plane was drawn 80 cm across the vertex). A
    corner off the right angle turns the double bounce one way or the other by the order
    in which its walls are met (:func:`~.models.corner_paths`): either order's echoes are
    its own (the zoo's unseen seed 180 corner-07: an 81° corner's 4 echoes of the other
    order, which its model with β negated predicts to 0.014 mm, fitted a plane through the
    vertex that was drawn 39 cm from it, 22 cm RMS)."""
    if corner.kind != "corner" or f.kind == "corner" or len(corner.rows) <= len(f.rows):
        return False
    least = len(f.rows) - outside_allowed(f.window, f.rows)
    orders = [corner.params]
    if len(corner.params) > 2 and corner.params[2] != 0.0:
        orders.append(np.r_[corner.params[:2], -corner.params[2]])
    return any(len(_inliers(f.window, "corner", p, f.rows)) >= least for p in orders)


def as_plane(f: Family) -> Family | None:
    """Family ``f``'s echoes as a plane's, where a plane explains each of them within its
    tolerance as strongly as a mirror's; None otherwise."""
    w, rows = f.window, f.rows
    fit = _fit(w, "plane", rows, family_starts(w, f.kind, f.params, rows)["plane"])
    path, q = _predict(w, "plane", fit.params, rows)
    if np.any(np.abs(path - w.paths[rows]) > _tolerance(w, "plane", rows)) \
            or not np.all(_strong(w, "plane", rows, q, fit.params)):
        return None
    return Family("plane", fit.params, w.x0, rows, q, fit.rms, w, f.bend)


def fits_as_well(f: Family, corner: Family, resolution: float,
                 certain: Callable[[], bool] = lambda: False) -> bool:
    """Whether the located ``corner`` (of more rows, or ``certain()``: no plane explains
    its own echoes, :func:`as_plane`, asked only then) predicts the echoes of ``f`` (a
    plane, point or curve), its vertex inside both beams, with an RMS as good as ``f``'s
    (:func:`~.families.as_well_limit`), as :func:`~.families._simplest` names a family: with
    noise more than a tenth of them may leave their tolerance of either model (the zoo's
    unseen seed 19 corner-05, σ 0.6: a plane of 51 echoes of a 2 cm-pitch array 7.4 m
    away, RMS 0.51 mm, the corner 250 echoes located 0.79 mm, 7 outside; the plane drawn
    through the vertex, 13.7 cm RMS). The corner as located, then refitted to both
    families' echoes together (:func:`_joined`), still explaining its own as well: with
    noise, a vertex that pairs of another array located some millimetres off moves the
    double bounce of an array that sees it from elsewhere by twice that along its line of
    sight (the zoo's unseen seed 105 corner-02, σ 0.3: a corner of 10 echoes located 5 mm
    off, a plane of 15 through the vertex, 3.4 mm RMS from the corner as located, drawn
    8.6 cm RMS off the walls). Refitted, the vertex may move by no more than
    ``resolution`` (the pulse's, c·σ): a corner of a few echoes far away is located
    loosely across its line of sight, and refitted with a family of many more it becomes
    that family's fit, wherever it lies (the zoo's unseen seed 130 edge-02, σ 0.3: an edge
    7.4 m from a 16-element array, a corner of 5 echoes located 35 cm off, refitted 37 cm
    onto the point of 54 echoes, which it then claimed; the edge was mapped 35 cm off).
    The refits this is for moved 3–6 mm (seeds 105 and 112)."""
    if corner.kind != "corner" or f.kind == "corner" or (len(corner.rows) <= len(f.rows)
                                                         and not certain()):
        return False
    w = f.window
    bar = as_well_limit(f.rms, detection_noise(w.tolerance[f.rows]))
    if _explains(w, f.rows, corner.params, bar):
        return True
    both = _joined(corner, w, f.rows)
    every = np.arange(len(both.paths))
    params = _fit(both, "corner", every, corner.params).params
    if math.hypot(*(params[:2] - corner.params[:2])) > resolution:
        return False  # f's own fit, not the corner's
    own = every[:len(corner.rows)]
    return _explains(both, every[len(own):], params, bar) and _explains(
        both, own, params, as_well_limit(corner.rms, detection_noise(both.tolerance[own])))


def _explains(w: Window, rows: np.ndarray, params: np.ndarray, bar: float,
              kind: str = "corner") -> bool:
    """Whether the corner (or point) ``params`` predicts ``rows`` with an RMS within
    ``bar``, its vertex inside both beams of each."""
    path, q = _predict(w, kind, params, rows)
    return bool(np.all(_valid(w, kind, params, rows, q))) and math.sqrt(
        float(np.mean((path - w.paths[rows]) ** 2))) <= bar


#: Leftover echoes tested against the drawn faces at once (bounds the [rows, points] arrays).
FACE_ECHO_CHUNK = 64


def drawn_faces_echoes(T: np.ndarray, R: np.ndarray, axT: np.ndarray, axR: np.ndarray,
                       paths: np.ndarray, tolerance: np.ndarray, faces: np.ndarray,
                       ends: np.ndarray, cut_sin2: float) -> np.ndarray:
    """Which echoes (pairs at ``T`` and ``R`` with unit axes ``axT``, ``axR``, of ``paths``)
    a drawn face reflects: one of the faces (``faces`` [n, 2], patch after patch, the
    first ``ends[-1]`` points, each patch's in order along it) has a specular point for
    the pair inside both beams whose path |T − q| + |q − R| is within ``tolerance`` of
    the echo's. By Fermat's principle the specular point is where the path over the face
    is stationary: a drawn point nearer in path than both of its patch's neighbours, not a
    patch's end (there the face runs on past the pair's specular point, or stops short of
    it). Such an echo is the face's own, detected off by more than a family's tolerance
    where two of the face's echoes merged (a curved wall's specular points a pulse's
    length apart in path: the zoo's unseen seed 160 sinusoid-04, a detection 5 mm short of
    its first echo) and drawn elsewhere as the middle of its arc, it stood 17 cm off the
    wall."""
    out = np.zeros(len(paths), dtype=bool)
    n = int(ends[-1]) if len(ends) else 0
    if n < 3 or not len(paths):
        return out
    q = faces[:n]
    inner = np.ones(n, dtype=bool)
    inner[0] = inner[-1] = False
    starts = np.minimum(ends[:-1], n - 1)  # (a patch clipped to nothing ends where it starts)
    inner[starts] = inner[starts - 1] = False  # every patch's first and last point
    for a in range(0, len(paths), FACE_ECHO_CHUNK):
        b = slice(a, a + FACE_ECHO_CHUNK)
        t, r = T[b, None, :], R[b, None, :]
        path = np.hypot(*(q - t).transpose(2, 0, 1)) + np.hypot(*(q - r).transpose(2, 0, 1))
        lower = np.zeros(path.shape, dtype=bool)
        lower[:, 1:-1] = (path[:, 1:-1] <= path[:, :-2]) & (path[:, 1:-1] <= path[:, 2:])
        hit = (lower & inner & (np.abs(path - paths[b, None]) <= tolerance[b, None])
               & in_beams(q, t, axT[b, None, :], cut_sin2)
               & in_beams(q, r, axR[b, None, :], cut_sin2))
        out[b] = hit.any(axis=1)
    return out


__all__ = ["SAME_POINT_M", "a_corners_echoes", "as_plane", "drawn_faces_echoes", "fits_as_well",
           "one_point_each", "widened"]
