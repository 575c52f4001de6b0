"""Analytic echo returns of every transmitter→receiver pair (thesis §2.1.1, figs. 2.2, 2.5).

Two implementations of one model: :func:`compute_echoes` runs the OpenCL kernels of
``kernels/echoes.cl`` (float32 by default, float64 where the device has ``cl_khr_fp64``) and
:func:`reference_echoes` evaluates the same formulas in NumPy float64. Both start from the
same :class:`EchoProblem` (:func:`prepare_problem`) and end in the same :class:`EchoTable`.

The model, for every fired pair (T, R) of :func:`clsonar.sensors.pairs`:

- **specular / corner** (image method, thesis fig. 2.2): every sequence of 1..``max_order``
  flat walls with consecutive walls distinct. Images I0 = T, Ij = Ij−1 mirrored across wall
  sj; back-tracing from R gives the reflection points. Valid iff every crossing lies strictly
  between its two points and on its wall, and every bounce has its incoming and outgoing
  points strictly on the wall's front (two-sided walls: strictly on one side). Path length
  ``|R − Ik|``; ``corner`` if k ≥ 2 and each consecutive pair of walls meets at a concave
  corner, else ``specular``; amplitude factor ρ^k. Legs shorter than
  :data:`OCCLUSION_EPS_M` are rejected, so a path through a corner's vertex is left to:
- **corner vertex**: the double bounce T→V→R through the vertex V of a concave corner, the
  retro-reflection of a right-angled corner (for T = R the image method's middle leg has
  zero length). Valid iff T and R are strictly inside the corner and R lies within
  :data:`OCCLUSION_EPS_M` of the ray from V away from T's second-order image; ``corner``,
  order 2, factor ρ².
- **edge**: diffraction at each convex vertex V, path T→V→R, valid iff neither T nor R is
  strictly inside the solid cone; factor :func:`~clsonar.physics.edge_gain`.
- **curved**: the specular point on a cylinder (bisection on the shorter arc between the
  directions to T and R) or on a sinusoid (bisection of the path length's derivative in each
  sampling interval); factor ρ·:func:`~clsonar.physics.curved_gain`.
- **occlusion**: each leg is blocked by an occluder (wall or curve chord) it crosses more than
  :data:`OCCLUSION_EPS_M` from both ends, or a circle it passes through.
- **amplitude** ``A0·b(θ_T)·b(θ_R)·factor·absorption``, θ the angles between each
  transducer's axis and its leg (physics.py); an echo is kept only when A > 0, i.e. strictly
  inside both beams. Time of flight = path length / c (eq. 2.1).

All coordinates are made relative to the scene extent's centre before the kernels see them, so
float32 keeps micrometre resolution anywhere in the scene.
"""

from .host import KERNEL_NAMES, compute_echoes
from .problem import (
    BISECT_ITERATIONS,
    OCCLUSION_EPS_M,
    EchoProblem,
    check_sequences,
    prepare_problem,
    scene_walls,
    wall_sequences,
)
from .reference import reference_echoes
from .table import CORNER, CURVED, EDGE, KINDS, SPECULAR, EchoTable
from .view import pairs_in_view

__all__ = ["BISECT_ITERATIONS", "CORNER", "CURVED", "EDGE", "KERNEL_NAMES", "KINDS",
           "OCCLUSION_EPS_M", "SPECULAR", "EchoProblem", "EchoTable", "check_sequences",
           "compute_echoes",
           "pairs_in_view", "prepare_problem", "reference_echoes", "scene_walls",
           "wall_sequences"]
