"""The map: from detected echoes to votes per cell (thesis §2.1.1, parts 3–4).

The methods, by ``mapping.mode`` (:data:`METHODS`, run by :func:`map_votes`, each returning
the :class:`Votes` post-processing starts from):

**Loci** (``"loci"``, the thesis; :mod:`.launch`, :mod:`.tiles`). Each detected echo
(T, R, τ) puts the reflector on the locus ``|p − T| + |p − R| = c·τ``: for T = R the circle
of radius c·τ/2 ("a 24° arc is drawn from the centre of the transducer with a radius equal to
half of the round-trip distance"), for T ≠ R the ellipse with foci T and R ("the elliptical
arc which falls within the joint sensitivity region ... is drawn"). The map has one pixel per
cell (docs/design.md: arrays ``[iy, ix]``, cell centres ``(xmin + (ix + ½)·cell,
ymin + (iy + ½)·cell)``); every pixel centre p gets, from every row, a vote iff

    | |p − T| + |p − R| − c·τ | ≤ band/2      (band = mapping.band_m, default 2√2·cell)

(the band is a width in path length, :func:`band_m`: 2√2·cell of it make a locus at least
√2 cells thick on the map) and p lies inside both beams: cosθ > 0 and sin²θ ≤ the hard cut
(:func:`clsonar.physics.beam_cut_sin2`) for the angles θ_T, θ_R between each transducer's
axis and the direction d to p: the echo engine's ``beam()`` test ``axis·d > 0`` and
``(axis×d)²/|d|² ≤ cut``, multiplied out as ``(axis×d)² ≤ cut·|d|²``. The vote is 1
(``weight = "unit"``, the thesis), the detected amplitude (``"amplitude"``) or
b(θ_T)·b(θ_R) (``"beam"``, the piston pattern of :func:`clsonar.physics.beam_pattern`).
Votes add up over rows in row order; with ``combine = "viewpoints"`` a cell counts the
viewpoints with a locus through it instead (:func:`count_viewpoints`).

**Tangent points** (``"tangents"``, the default; :mod:`.tangents`, :mod:`.envelope`,
:mod:`.points`): the points where the loci of neighbouring transducers cross inside all beams
(:func:`tangent_points`), and for a moving ring the scan's envelope (:func:`scan_envelope`);
their map (:func:`point_map`) is drawn by the caller after the line-of-sight check.

**Reflectors** (``"reflectors"``, the default; :mod:`.models`, :mod:`.families`,
:mod:`.patches`, :mod:`.joins`, :mod:`.reflectors`): each linear array's detections split
into reflector families — planes, points (edges, posts), right-angled corners, circles —
by the paths each model predicts for the array's T ≠ R pairs (Kleeman & Kuc 1995); planes
and circles drawn over their regions of constant depth (Leonard & Durrant-Whyte 1991),
joined and met at corners, points and corners located as vertices
(:func:`reflector_points`); rings, and scenes whose transducers stand in a closed room, as
``tangents``.

**Back-projection** (``"backprojection"``): every pixel in a pair's joint beam adds that
pair's envelope at the pixel's delay ``(|p − T| + |p − R|)/c``, linearly interpolated between
samples taken every ``dt`` from 0 (0 past the last sample); with ``weight = "beam"`` times
b(θ_T)·b(θ_R), otherwise unweighted (:func:`backproject`).

**The arc-map methods of the literature** (issue 15; docs/mapping.md): point marking
(``"point-marking"``, :func:`arc_middles`), the directional maximum
(``"directional-maximum"``, :func:`arc_maxima`, kernels of ``kernels/directional.cl``), the
occupancy grid (``"occupancy"``, :func:`occupancy_grid`, :mod:`.occupancy`) and morphological
processing (``"morphological"``, :func:`closed_arc_map`), the arc-transversal median
(``"arc-transversal-median"``, :func:`arc_transversal_medians`) and triangulation-based
fusion (``"triangulation"``, :func:`triangulated_points`); :mod:`.arcs`,
:mod:`.directional`, :mod:`.crossings`.

Two implementations of loci and back-projection, as for the echoes: :func:`accumulate` and
:func:`backproject` run the OpenCL kernels of ``kernels/accumulate.cl`` (float32 by default,
float64 where the device has ``cl_khr_fp64``; :mod:`.launch`); :func:`accumulate_reference`
and :func:`backproject_reference` evaluate the same expressions, in the same order, in NumPy
float64 (:mod:`.reference`), so the float64 kernels reproduce them bit for bit.

Numerics: coordinates are taken relative to the centre of an *origin pixel* in the middle of
the map (:class:`MapGrid`), in float64 on the host, so the kernels see pixel centres as exact
integers times the cell and distances of at most the map's half-diagonal; float32 then
decides every pixel as float64 does except those within a few float32 roundings of a band
edge or a beam edge.

Performance: :func:`accumulate` works on tiles (default): :func:`bin_loci` bounds each
locus' band on the host (the bounding box of its outer ellipse ∩ those of its two beam
sectors, then per tile the ring and beam tests widened by the tile's half-diagonal, coarse
tiles first) and lists per tile, in locus order, the loci that can vote there; the kernel
``loci_tiles`` runs one work-group per non-empty tile with its loci in local memory, and
empty tiles are never launched. The map is the dense one to the bit (same votes, same
order). At most ``launch.MAX_LAUNCH_BYTES`` of tiles are drawn per launch, so the device
never holds the whole map: a 100 m × 100 m floor at 1 cm (10⁸ cells) takes 0.4 GB of host
memory in float32. ``tiles=False`` runs the dense kernel ``loci_map`` (loci in
``__constant`` memory in blocks of at most ``launch.MAX_ROWS_PER_LAUNCH``), every pixel
against every locus.

The modules: :mod:`.grid` (the map's grid, band, memory check), :mod:`.loci` (the inputs),
:mod:`.reference`, :mod:`.tiles`, :mod:`.launch`, :mod:`.tangents`, :mod:`.envelope`,
:mod:`.points`, :mod:`.models`, :mod:`.families`, :mod:`.patches`, :mod:`.joins`,
:mod:`.reflectors`, :mod:`.few`, :mod:`.openings`, :mod:`.arcs`, :mod:`.directional`,
:mod:`.occupancy`, :mod:`.crossings` and
:mod:`.methods` (the registry). The scalar launch limits
(``MAX_ROWS_PER_LAUNCH``, ``MAX_LAUNCH_BYTES``, ``MAX_PAIRS_PER_LAUNCH``, ``TILE_CHUNK``,
``BIN_*``) are read from their own modules: set them there.
"""

from __future__ import annotations

__all__ = [
    "LAUNCH",
    "LOCUS_SAMPLES",
    "METHODS",
    "PAIR_BYTES",
    "TILES",
    "WEIGHTS",
    "AccumulationStats",
    "ArcMaxima",
    "Loci",
    "MapGrid",
    "MapMethod",
    "MapProblem",
    "OpenGap",
    "ScanHeard",
    "TileBins",
    "Votes",
    "accumulate",
    "accumulate_reference",
    "accumulate_with_stats",
    "arc_maxima",
    "arc_maxima_reference",
    "arc_middles",
    "arc_transversal_median_votes",
    "arc_transversal_medians",
    "as_loci",
    "backproject",
    "backproject_reference",
    "backprojection_votes",
    "band_boxes",
    "band_m",
    "bin_loci",
    "cell_centres",
    "cell_points",
    "check_map_memory",
    "check_pair_memory",
    "closed_arc_map",
    "count_viewpoints",
    "directional_maximum_votes",
    "envelope_links",
    "in_beams",
    "loci_votes",
    "map_grid",
    "map_votes",
    "merge_reciprocal",
    "morphological_votes",
    "occupancy_grid",
    "occupancy_grid_reference",
    "occupancy_votes",
    "open_gaps",
    "point_map",
    "point_marking_votes",
    "points_window",
    "prepare_backprojection",
    "prepare_loci",
    "reference_beam",
    "reflector_points",
    "reflector_votes",
    "scan_envelope",
    "scan_heard",
    "sounded_cells",
    "tangent_map",
    "tangent_points",
    "tangent_votes",
    "triangulated_points",
    "triangulation_votes",
    "work_items",
]

from .along import ScanHeard, scan_heard
from .arcs import arc_middles, cell_points, closed_arc_map
from .crossings import arc_transversal_medians, triangulated_points
from .directional import ArcMaxima, arc_maxima, arc_maxima_reference
from .envelope import envelope_links, in_beams, scan_envelope
from .grid import (
    LAUNCH,
    PAIR_BYTES,
    MapGrid,
    band_m,
    cell_centres,
    check_map_memory,
    check_pair_memory,
    map_grid,
    work_items,
)
from .launch import (
    TILES,
    AccumulationStats,
    accumulate,
    accumulate_with_stats,
    backproject,
    occupancy_grid,
    sounded_cells,
)
from .loci import (
    WEIGHTS,
    Loci,
    MapProblem,
    as_loci,
    count_viewpoints,
    merge_reciprocal,
    prepare_backprojection,
    prepare_loci,
)
from .methods import (
    METHODS,
    MapMethod,
    Votes,
    arc_transversal_median_votes,
    backprojection_votes,
    directional_maximum_votes,
    loci_votes,
    map_votes,
    morphological_votes,
    occupancy_votes,
    point_marking_votes,
    reflector_votes,
    tangent_votes,
    triangulation_votes,
)
from .openings import OpenGap, open_gaps
from .points import point_map, points_window
from .reference import (
    accumulate_reference,
    backproject_reference,
    occupancy_grid_reference,
    reference_beam,
)
from .reflectors import reflector_points
from .tangents import LOCUS_SAMPLES, tangent_map, tangent_points
from .tiles import TileBins, band_boxes, bin_loci
