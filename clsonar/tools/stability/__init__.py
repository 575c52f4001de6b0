"""Numerical stability: the float32 kernels against their float64 references on hostile scenes.

One set of scene generators serves the property tests (tests/test_stability.py, a few dozen
cases on every CI run) and ``clsonar stress`` (thousands, on the user's device). A case is
``(family, seed)``: the family names the hazard, the seed draws the rest from NumPy's
``default_rng``, so every case is reproducible from those two values alone.

Echo families (kernels/echoes.cl against :func:`clsonar.echoes.reference_echoes`):

- ``far`` — a room up to 10⁵ m from the origin; ``tiny`` — a room a few centimetres wide;
- ``coincident`` — T = R and receivers 0 … 1 mm from their transmitter;
- ``grazing`` — transducers a hair above a wall's line, or on a circle's tangent;
- ``ends`` — reflection points exactly at a wall's end or at a vertex;
- ``caustic`` — sinusoids curved so that several specular points crowd together, and very
  short periods;
- ``headings`` — headings at and around ±180° (and ±540°);
- ``many`` — one group of many transducers: a long pair list.

Detection (kernels/signals.cl against :func:`clsonar.signals.detect_reference`): every echo
family but ``many``, its float64 echoes received with a random detector (threshold or
envelope) and noise level.

Map families (kernels/accumulate.cl against :func:`clsonar.mapping.accumulate_reference`,
:func:`clsonar.mapping.backproject_reference`): ``far``, ``tiny``, ``coincident`` (T = R and
nearly coincident T and R), ``flat`` (c·τ within 1 µm of |T − R|: a flat ellipse), ``focus``
(a transducer exactly on a pixel centre), ``knife`` (pixel centres exactly on a band edge),
``headings``, ``outside`` (transducers outside the map,
beams leaving it), ``ragged`` (extents that are not multiples of the cell), ``million``
(``MILLION`` loci on one map) and ``backprojection``.

The properties (:data:`BOUNDS`), checked on every case:

- no NaN or Inf in any output;
- echoes: each float32 echo matched to its float64 twin has |Δτ| ≤ 1 µs; an echo present in
  one table only must be a knife-edge decision: the float64 reference itself gains or loses
  it when the transducers move by a float32 rounding (:func:`_edge_echo_keys`), or be
  weaker than 5 % of A0 (a beam edge or grazing incidence, as tests/test_echoes.py allows);
- maps: every pixel where float32 and float64 differ (beyond float32 summation rounding)
  lies within a few float32 roundings of a band edge or a beam edge of some locus
  (:func:`edge_pixels`), and at most 0.1 % of the pixels differ;
- work groups: the same case run with other work-group sizes (and tile shapes, and the dense
  map kernel instead of the tiled one) gives bit-identical output.

The package: scene generators in :mod:`.echo_cases` and :mod:`.map_cases`, the judges in
:mod:`.echo_judge`, :mod:`.signal_judge` and :mod:`.map_judge`, what they find and the bounds
in :mod:`.findings`.
"""

from .echo_cases import ECHO_FAMILIES, echo_scene
from .echo_judge import ALT_ECHO_GROUPS, check_echo_case, echo_work_group, match_echoes
from .findings import BOUNDS, EPS32, Findings
from .map_cases import MAP_FAMILIES, MILLION, MapCase, map_case
from .map_judge import (
    ALT_MAP_LAUNCH,
    beam_slack,
    check_map_case,
    compare_maps,
    edge_pixels,
    map_launch,
    value_tolerance,
)
from .signal_judge import ALT_SIGNAL_GROUPS, SIGNAL_FAMILIES, check_signal_case, signal_scene

__all__ = ["ALT_ECHO_GROUPS", "ALT_MAP_LAUNCH", "ALT_SIGNAL_GROUPS", "BOUNDS", "ECHO_FAMILIES",
           "EPS32", "MAP_FAMILIES", "MILLION", "SIGNAL_FAMILIES", "Findings", "MapCase",
           "beam_slack", "check_echo_case", "check_map_case", "check_signal_case",
           "compare_maps", "echo_scene", "echo_work_group", "edge_pixels", "map_case",
           "map_launch", "match_echoes", "signal_scene", "value_tolerance"]
