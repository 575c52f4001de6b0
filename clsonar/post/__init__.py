"""Post-processing of the accumulated map (thesis §2.1.1, part 5), in the order the
pipeline runs it:

1. **Low-pass** (:mod:`~clsonar.post.filters`): :func:`low_pass`, the 3×3 mean filter of
   eq. 2.4, then :func:`binarize` at the :func:`occupancy_level` — the occupied cells.
   :func:`filter_box` does both on the :func:`voted_box` only and :func:`embed` puts the
   result back on the whole map (the same numbers).
2. **Thinning** (:mod:`~clsonar.post.thinning`): :func:`thin_thesis`, the template of
   eq. 2.5 exactly as the thesis writes it (:func:`thin_oriented`: in the direction that
   fits each part of the map), or :func:`thin`, a proper thinning (Guo and
   Hall's parallel algorithm) that leaves one-pixel wide, 8-connected curves and keeps
   every curve's connectivity; :func:`thin_map` picks one as the settings say, and
   :func:`filter_and_thin` runs steps 1 and 2.
3. **Curves** (:mod:`~clsonar.post.curves`): :func:`trace_curves` links the thin cells into
   ordered curves, :func:`refine_cells` / :func:`refine_to_points` move them to sub-cell
   positions, :func:`bridge_gaps` joins curves across gaps.
4. **Fit** (:mod:`~clsonar.post.fits`, :mod:`~clsonar.post.walls`): the thesis' polynomial
   along the principal axis (:func:`fit_polynomial`), a smoothing spline per curve
   (:func:`fit_spline`), or a room's straight walls joined at corners and edges with
   circles for cylinders (:func:`fit_walls`, thesis §3.6).

:func:`extract_profile` (:mod:`~clsonar.post.profile`) runs steps 3 and 4 and returns the
:class:`Profile`, bounded by :func:`bound_profile`: whatever the fit, no point outside the
extent, nor farther than :data:`NEAR_CELLS` cells from an occupied cell but to bridge a
gap between supported stretches. Maps are indexed ``[iy, ix]`` with ``iy`` growing with y
(docs/design.md).
"""

from .circles import Arc, find_circles
from .curves import MIN_CURVE_CELLS, bridge_gaps, refine_cells, refine_to_points, trace_curves
from .filters import (
    AUTO_LEVEL_POINTS,
    AUTO_LEVEL_VOTES,
    BOX_MARGIN,
    binarize,
    embed,
    filter_and_thin,
    filter_box,
    low_pass,
    occupancy_level,
    voted_box,
)
from .fits import Profile, fit_polynomial, fit_spline
from .profile import (
    NEAR_CELLS,
    bound_profile,
    extract_profile,
    overlay,
    runs,
    with_patches,
    with_vertices,
    within_extent,
)
from .thinning import along_x, thin, thin_map, thin_oriented, thin_thesis
from .walls import Wall, fit_walls, join_walls, merge_collinear, split_straight

__all__ = [
    "AUTO_LEVEL_POINTS", "AUTO_LEVEL_VOTES", "BOX_MARGIN", "MIN_CURVE_CELLS", "NEAR_CELLS", "Arc",
    "Profile", "Wall", "along_x", "binarize", "bound_profile", "bridge_gaps", "embed",
    "extract_profile", "filter_and_thin", "filter_box", "find_circles", "fit_polynomial",
    "fit_spline", "fit_walls", "join_walls", "low_pass", "merge_collinear", "occupancy_level",
    "overlay", "refine_cells", "refine_to_points", "runs", "split_straight", "thin", "thin_map",
    "thin_oriented", "thin_thesis", "trace_curves", "voted_box", "with_patches", "with_vertices",
    "within_extent",
]
