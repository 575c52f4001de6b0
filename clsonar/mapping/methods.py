"""The mapping methods by name (``mapping.mode``; the shape of pyroomacoustics'
``algorithms = {"SRP": SRP, ...}``): :data:`METHODS` maps each name to a function of the
scene, its sensors, echoes and detections that returns the method's :class:`Votes`, and
:func:`map_votes` runs the one the scene names. The line-of-sight check and the drawing of
the point map are left to the caller (the pipeline), which does them in the open."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .. import signals
from ..echoes import EchoTable
from ..scene import Scene
from ..scene.settings import chosen
from ..sensors import SensorArray, pairs
from ..signals import Detections
from .arcs import arc_middles, cell_points, closed_arc_map
from .crossings import arc_transversal_medians, triangulated_points
from .directional import arc_maxima
from .few import faces_corners, loud_corners, loud_crossings
from .launch import AccumulationStats, accumulate_with_stats, backproject, occupancy_grid
from .loci import Loci, as_loci, count_viewpoints, merge_reciprocal
from .occupancy import OCCUPIED_LOG_ODDS
from .reflectors import reflector_points
from .tangents import tangent_map

if TYPE_CHECKING:
    import pyopencl as cl


@dataclass(frozen=True, eq=False)
class Votes:
    """What a mapping method hands to post-processing: a raw map of votes, or estimated
    reflection points (with their pairs) whose map is drawn after the line-of-sight check."""

    raw: np.ndarray | None = None  # [ny, nx] votes (loci, backprojection)
    #: [n, 2] estimated reflection points (tangents, point-marking, directional-maximum), or
    #: the centres of the cells a method marks occupied (occupancy, morphological)
    points: np.ndarray | None = None
    #: [n] transmitter index of each point's pair (None: points without a pair, which the
    #: line of sight cannot check)
    tx: np.ndarray | None = None
    rx: np.ndarray | None = None  # [n] receiver index
    counts: dict[str, int] = field(default_factory=dict)  # the stage's counters
    #: [k, 2] located point reflectors (corners, edges, thin posts; reflectors)
    vertices: np.ndarray | None = None
    #: exclusive ends, within ``points``, of the fitted patches' points (the first
    #: ``patch_ends[-1]`` points, in order along each patch; reflectors): curves of the
    #: profile as they are
    patch_ends: np.ndarray | None = None


#: ``(scene, sensors, echoes, detections, context, tiles) → Votes``.
MapMethod = Callable[[Scene, SensorArray, EchoTable, Detections, "cl.Context", bool], Votes]


def _loci(scene: Scene, detections: Detections) -> Loci:
    """The detections as loci, reciprocal pairs merged when ``mapping.reciprocal`` is
    ``"merge"`` (within 6 pulse σ)."""
    loci = as_loci(detections)
    if scene.mapping.reciprocal == "merge":
        loci = merge_reciprocal(loci, 6.0 * scene.transducer.pulse_sigma_s)
    return loci


def backprojection_votes(scene: Scene, sensors: SensorArray, echoes: EchoTable,
                         detections: Detections, context: cl.Context, tiles: bool) -> Votes:
    """``"backprojection"``: every fired pair's envelope back-projected
    (:func:`~clsonar.mapping.backproject`); the detections are not used."""
    dt, env = signals.envelopes(scene, sensors, echoes, context=context)
    return Votes(raw=backproject(scene, sensors, pairs(sensors), env, dt, context=context))


def _arc_map(scene: Scene, sensors: SensorArray, loci: Loci, context: cl.Context,
             tiles: bool) -> tuple[np.ndarray, dict[str, int]]:
    """The loci drawn (:func:`~clsonar.mapping.accumulate`), all in one map
    (``combine = "sum"``) or counted by viewpoint (``"viewpoints"``,
    :func:`~clsonar.mapping.count_viewpoints`), and the tiled accumulation's counters."""
    stats: list[AccumulationStats] = []

    def draw(part) -> np.ndarray:
        votes, one = accumulate_with_stats(scene, sensors, part, context=context, tiles=tiles)
        stats.append(one)
        return votes

    raw = (count_viewpoints(scene, sensors, loci, draw)
           if scene.mapping.combine == "viewpoints" else draw(loci))
    return raw, {
        "tiles_total": sum(t.tiles_total for t in stats),
        "tiles_skipped": sum(t.tiles_skipped for t in stats),
        "pixel_locus_tests": sum(t.pixel_locus_tests for t in stats),
        "dense_pixel_locus_tests": sum(t.dense_tests for t in stats)}


def loci_votes(scene: Scene, sensors: SensorArray, echoes: EchoTable,
               detections: Detections, context: cl.Context, tiles: bool) -> Votes:
    """``"loci"`` (the thesis; voting and thresholding, VT): the loci drawn, summed or
    counted by viewpoint (:func:`_arc_map`); counts the tiled accumulation's work."""
    raw, counts = _arc_map(scene, sensors, _loci(scene, detections), context, tiles)
    return Votes(raw=raw, counts=counts)


#: ``(scene, sensors, loci) → (points [m, 2], the locus of each [m])``: a method that
#: gives one point per locus or per cluster of crossings.
PointsOfLoci = Callable[[Scene, SensorArray, Loci], tuple[np.ndarray, np.ndarray]]


def _points_of(method: PointsOfLoci, counter: str, scene: Scene, sensors: SensorArray,
               detections: Detections) -> Votes:
    """The :class:`Votes` of a method of points (``method`` on the detections' loci), each
    with its locus' pair, their number under ``counter``."""
    loci = _loci(scene, detections)
    points, source = method(scene, sensors, loci)
    return Votes(points=points, tx=loci.tx[source], rx=loci.rx[source],
                 counts={counter: len(points)})


def point_marking_votes(scene: Scene, sensors: SensorArray, echoes: EchoTable,
                        detections: Detections, context: cl.Context, tiles: bool) -> Votes:
    """``"point-marking"`` (PM): one point at the middle of each locus' in-beam arc
    (:func:`~clsonar.mapping.arc_middles`), with its pair."""
    return _points_of(arc_middles, "arc_points", scene, sensors, detections)


def directional_maximum_votes(scene: Scene, sensors: SensorArray, echoes: EchoTable,
                              detections: Detections, context: cl.Context,
                              tiles: bool) -> Votes:
    """``"directional-maximum"`` (DM; Barshan 2007): the loci drawn as for ``"loci"``, then
    along each locus the cells where that map is largest (:func:`~clsonar.mapping.arc_maxima`),
    each as its centre with the locus' pair."""
    loci = _loci(scene, detections)
    raw, counts = _arc_map(scene, sensors, loci, context, tiles)
    kept = arc_maxima(scene, sensors, loci, raw, context=context)
    return Votes(points=cell_points(scene, kept.cells), tx=loci.tx[kept.source],
                 rx=loci.rx[kept.source], counts={**counts, "arc_maxima": len(kept.cells)})


def arc_transversal_median_votes(scene: Scene, sensors: SensorArray, echoes: EchoTable,
                                 detections: Detections, context: cl.Context,
                                 tiles: bool) -> Votes:
    """``"arc-transversal-median"`` (ATM; Choset, Nagatani & Lazar 2003): one point per
    locus, the median of its crossings with every other locus
    (:func:`~clsonar.mapping.arc_transversal_medians`), with its pair."""
    return _points_of(arc_transversal_medians, "arc_medians", scene, sensors, detections)


def triangulation_votes(scene: Scene, sensors: SensorArray, echoes: EchoTable,
                        detections: Detections, context: cl.Context, tiles: bool) -> Votes:
    """``"triangulation"`` (TBF; Wijk & Christensen 2000): the centroids of the clusters of
    the pairwise crossings of nearby transmitters' loci
    (:func:`~clsonar.mapping.triangulated_points`), each with its nearest locus' pair."""
    return _points_of(triangulated_points, "triangulated_points", scene, sensors, detections)


def occupancy_votes(scene: Scene, sensors: SensorArray, echoes: EchoTable,
                    detections: Detections, context: cl.Context, tiles: bool) -> Votes:
    """``"occupancy"`` (BU; Elfes 1987): the occupancy grid's log-odds
    (:func:`~clsonar.mapping.occupancy_grid`); the centres of the cells above
    :data:`~clsonar.mapping.occupancy.OCCUPIED_LOG_ODDS`."""
    odds = occupancy_grid(scene, sensors, _loci(scene, detections), context=context)
    cells = np.flatnonzero(odds.ravel() > OCCUPIED_LOG_ODDS)
    return Votes(points=cell_points(scene, cells), counts={"grid_occupied_cells": len(cells)})


def morphological_votes(scene: Scene, sensors: SensorArray, echoes: EchoTable,
                        detections: Detections, context: cl.Context, tiles: bool) -> Votes:
    """``"morphological"`` (MP; Başkent & Barshan 1999): the binary arc map closed
    (:func:`~clsonar.mapping.closed_arc_map`), its cells' centres; post-processing thins
    them."""
    raw, counts = _arc_map(scene, sensors, _loci(scene, detections), context, tiles)
    cells = np.flatnonzero(closed_arc_map(raw).ravel())
    return Votes(points=cell_points(scene, cells), counts={**counts, "closed_cells": len(cells)})


def tangent_votes(scene: Scene, sensors: SensorArray, echoes: EchoTable,
                  detections: Detections, context: cl.Context, tiles: bool) -> Votes:
    """``"tangents"`` (the default): the tangent points of the loci
    (:func:`~clsonar.mapping.tangent_map`), the pair of the locus each came from, and the
    point reflectors located from a moving ring's isolated loci as vertices."""
    loci = _loci(scene, detections)
    points, source, vertices = tangent_map(scene, sensors, loci,
                                           isolated_bias_m=chosen(scene.mapping.isolated_bias_m,
                                                                  "mapping.isolated_bias_m"))
    return Votes(points=points, tx=loci.tx[source], rx=loci.rx[source],
                 vertices=vertices if len(vertices) else None)


def reflector_votes(scene: Scene, sensors: SensorArray, echoes: EchoTable,
                    detections: Detections, context: cl.Context, tiles: bool) -> Votes:
    """``"reflectors"`` (the default): each linear array's echoes fitted by reflector
    models, planes and circles drawn as points, points and corners located as vertices;
    other groups' tangent points (:func:`~clsonar.mapping.reflector_points`); where those
    are none, the faces two loud echoes are a plane's (counted as ``two_echo_faces``) and
    the crossings of the other loud echoes' loci (:func:`~.few.loud_crossings`,
    counted as ``crossing_points``); else the right-angled corners whose double bounces
    two loud echoes left over are (:func:`~.few.loud_corners`, located vertices), and the
    crossings of two drawn faces' lines that an echo left over came from
    (:func:`~.few.faces_corners`)."""
    loci = _loci(scene, detections)
    drawn = reflector_points(scene, sensors, loci)
    few = len(drawn.points) == len(drawn.vertices) == 0
    if few:
        drawn = loud_crossings(scene, sensors, loci, drawn)
    else:
        drawn = faces_corners(scene, sensors, loci, loud_corners(scene, sensors, loci, drawn))
    face_points = int(drawn.ends[-1]) if len(drawn.ends) else 0  # the patches' points first
    return Votes(points=drawn.points, tx=loci.tx[drawn.source], rx=loci.rx[drawn.source],
                 vertices=drawn.vertices, patch_ends=drawn.ends,
                 counts={"patches": len(drawn.ends), "vertices_located": len(drawn.vertices),
                         "crossing_points": len(drawn.points) - face_points if few else 0,
                         "two_echo_faces": len(drawn.ends) if few else 0})


#: The mapping methods by ``mapping.mode``.
METHODS: dict[str, MapMethod] = {
    "loci": loci_votes,
    "backprojection": backprojection_votes,
    "tangents": tangent_votes,
    "reflectors": reflector_votes,
    "point-marking": point_marking_votes,
    "directional-maximum": directional_maximum_votes,
    "occupancy": occupancy_votes,
    "morphological": morphological_votes,
    "arc-transversal-median": arc_transversal_median_votes,
    "triangulation": triangulation_votes,
}


def map_votes(scene: Scene, sensors: SensorArray, echoes: EchoTable, detections: Detections,
              *, context: cl.Context, tiles: bool = True) -> Votes:
    """Run the method ``scene.mapping.mode`` names (:data:`METHODS`); ``tiles`` lets the
    loci be drawn tile by tile (the same map)."""
    try:
        method = METHODS[scene.mapping.mode]
    except KeyError:
        raise ValueError(f"unknown mapping mode {scene.mapping.mode!r} "
                         f"(choose from {', '.join(METHODS)})") from None
    return method(scene, sensors, echoes, detections, context, tiles)
