"""The settings of a scene: medium, transducer, signal, echo model and the methods of each
pipeline stage (detection, mapping, post-processing).

Each setting with a fixed set of values has its ``Literal`` alias here, written once: the
dataclass field is annotated with it, the reader accepts exactly its values
(``typing.get_args``), and docs/scene-format.md lists them (tests/test_scene.py checks).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal, TypeVar

from ..physics import (
    DEFAULT_PULSE_SIGMA_S,
    DEFAULT_REFLECTION_COEFFICIENT,
    beam_constants,
    speed_of_sound,
)

#: Beam pattern of every transducer: the circular piston, or the thesis' flat sensitivity.
Directivity = Literal["piston", "uniform"]

#: ``echo.edge_model``: diffraction at convex edges (physics.edge_gain_estimate, edge_gain).
EdgeModel = Literal["estimate", "utd"]

#: How times of flight are found (:class:`DetectionSettings`).
DetectionMode = Literal["threshold", "envelope"]
#: ``detection.receiver``: the receiver's gain and comparator (clsonar.signals.polaroid).
Receiver = Literal["ideal", "polaroid-6500"]

#: How detections become a map (:class:`MappingSettings`).
MappingMode = Literal["loci", "tangents", "backprojection", "reflectors", "point-marking",
                      "directional-maximum", "occupancy", "morphological",
                      "arc-transversal-median", "triangulation"]

#: The vote of a locus (``loci`` mapping).
VoteWeight = Literal["unit", "amplitude", "beam"]

#: The kernels' arithmetic.
Precision = Literal["float32", "float64"]

#: Whether (T, R) and (R, T) make one locus or two.
Reciprocal = Literal["merge", "both"]

#: How the votes of loci add up (``loci`` mapping).
Combine = Literal["sum", "viewpoints"]

#: The low-pass filter of the map (thesis eq. 2.4, or none).
PostFilter = Literal["mean3", "none"]

#: The thinning of the filtered map.
Thinning = Literal["thesis", "guo-hall"]

#: The profile fitted to the thin map.
Fit = Literal["polynomial", "spline", "walls", "none"]


T = TypeVar("T")


def chosen(value: T | None, name: str) -> T:
    """The value of a setting that is chosen from the scene when the file leaves it out
    (null; :mod:`clsonar.survey`), once chosen. ``ValueError`` naming it before then."""
    if value is None:
        raise ValueError(f"{name} is chosen from the scene: run the scene through "
                         "clsonar.pipeline.run, or clsonar.survey.choose_settings, first")
    return value


@dataclass(frozen=True)
class Medium:
    temperature_k: float = 293.15
    speed_of_sound: float | None = None

    @property
    def c(self) -> float:
        """Speed of sound in m/s: the override if given, else thesis eq. 2.1."""
        if self.speed_of_sound is not None:
            return self.speed_of_sound
        return speed_of_sound(self.temperature_k)


@dataclass(frozen=True)
class TransducerModel:
    """The Polaroid 6500 series transducer of thesis §2.1 (50 kHz, 4 cm diameter, ±12°)."""

    frequency_hz: float = 50000.0
    radius_m: float = 0.02
    half_beam_deg: float = 12.0
    amplitude: float = 5.0
    pulse_sigma_s: float = DEFAULT_PULSE_SIGMA_S
    directivity: Directivity = "piston"

    def beam(self, c: float) -> tuple[float, float]:
        """``(cut_sin2, ka)`` for :func:`clsonar.physics.beam_pattern`."""
        return beam_constants(self.frequency_hz, self.radius_m, self.half_beam_deg,
                              self.directivity, c)


@dataclass(frozen=True)
class Signal:
    noise_std: float = 0.0
    threshold: float = 4.0
    seed: int = 1


@dataclass(frozen=True)
class EchoModel:
    """Settings of the echo engine; see physics.py for the amplitude model.

    ``curvature_gain`` false makes curved surfaces reflect as strongly as flat ones, as in
    the thesis' ray tracing (its scenes use it with ``transducer.directivity`` uniform).
    ``edge_model`` ``"utd"`` (the default) diffracts at convex edges as a rigid wedge does
    (the uniform theory of diffraction, Kouyoumjian & Pathak 1974, checked against the
    exact Biot–Tolstoy–Medwin solution: docs/physics.md); ``"estimate"`` keeps the
    order-of-magnitude coefficient with no angular factor (up to 35 dB off near a face's
    reflection boundary).
    """

    max_order: int = 2
    reflection_coefficient: float = DEFAULT_REFLECTION_COEFFICIENT
    edge_coefficient: float = 1.0
    edge_model: EdgeModel = "utd"
    absorption_db_per_m: float = 0.0
    curve_step_m: float = 0.01
    curvature_gain: bool = True


@dataclass(frozen=True)
class DetectionSettings:
    """How times of flight are found in each pair's received signal (thesis §2.1.1, 3–4).

    ``threshold``: as the thesis: the first sample above ``signal.threshold`` gives the time
    of flight; for T = R only that first crossing (the line-of-sight arc), for T ≠ R every
    crossing (after a hold-off of one pulse length, 6σ). ``envelope``: quadrature
    demodulation and a matched low-pass give the envelope, whose peaks above a
    noise-adaptive threshold (``false_alarm_sigmas`` times the estimated envelope noise, at
    least ``min_envelope`` units) give the time of flight as peak − 3σ (no threshold bias).
    ``min_envelope`` null: chosen from the scene (:mod:`clsonar.survey`).
    ``receiver`` (``envelope`` only): ``"ideal"`` (its time-varying gain undoes spreading
    exactly, the threshold as above) or ``"polaroid-6500"`` (the Polaroid 6500 ranging
    module's stepped gain, fixed comparator, blanking, 35 ft window and single-echo mode:
    :mod:`clsonar.signals.polaroid`, docs/detection.md).
    """

    mode: DetectionMode = "envelope"
    sample_rate_hz: float = 1.0e6
    false_alarm_sigmas: float = 6.0
    min_envelope: float | None = None
    receiver: Receiver = "ideal"


@dataclass(frozen=True)
class MappingSettings:
    """How detections become a map (thesis §2.1.1, 3–4).

    ``mode``:

    - ``loci`` (the thesis): every pixel p gets a vote from each detection whose time of
      flight τ puts p on its locus, ``| |p−T| + |p−R| − c·τ | ≤ band_m/2``, inside both beams
      (a circle for T = R, an ellipse otherwise); ``band_m`` null means 2√2·cell (loci at
      least √2 cells thick). ``weight``: ``unit`` (the thesis), ``amplitude`` (the detected
      amplitude) or ``beam`` (b(θ_T)·b(θ_R) at the pixel). ``combine``: ``sum`` adds the
      votes (the thesis); ``viewpoints`` counts the viewpoints (pair groups: an array, a
      ring pose) with a locus through each cell.
    - ``tangents`` (ours): the points where loci of neighbouring transducers of one viewpoint
      cross, which lie on the surface to within δ²/(8r) (mapping.tangent_points), with the
      loci's tangent segments around them, counted per cell. A locus that crosses none keeps
      the middle of its in-beam arc within ``isolated_bias_m`` of its tangent (0: dropped),
      which suits transducers that face the surface squarely, as a wall-following ring does
      (null: chosen from the scene, :mod:`clsonar.survey`).
    - ``backprojection``: the sum over pairs of each pair's envelope at the pixel's delay
      (delay-and-sum, "total focusing").
    - ``reflectors`` (ours, the default): each linear array's echoes split into reflector
      families — planes, points (edges, posts), right-angled corners, circles — by the
      paths each model predicts for its T ≠ R pairs (Kleeman & Kuc 1995); planes and
      circles drawn over their regions of constant depth (Leonard & Durrant-Whyte 1991),
      points and corners located as vertices (mapping.reflector_points). Rings, and every
      group of a scene whose transducers stand inside a closed room, as ``tangents``.
    - The arc-map methods of the literature (docs/mapping.md): ``point-marking`` (PM: the
      middle of each locus' in-beam arc), ``directional-maximum`` (DM, Barshan 2007: the
      loci drawn as ``loci``, then along each locus the cells where that map is largest),
      ``occupancy`` (BU, Elfes 1987: an occupancy grid updated in log-odds by a sonar-cone
      model), ``morphological`` (MP, Başkent & Barshan 1999: the binary loci map closed,
      then thinned), ``arc-transversal-median`` (ATM, Choset, Nagatani & Lazar 2003:
      per locus the median, by arc angle, of its crossings with all the other loci) and
      ``triangulation`` (TBF, Wijk & Christensen 2000: the crossings of the loci of
      transmitters within 1 m, clustered within 2 cm, three or more to a point).

    ``reciprocal``: ``merge`` makes the detections of (T, R) and (R, T) — one path measured
    twice — one locus with their mean time of flight; ``both`` draws both (the thesis).
    ``precision``: the kernels' arithmetic. ``line_of_sight`` (the modes whose points have
    their pairs: ``tangents``, ``reflectors``, ``point-marking``, ``directional-maximum``,
    ``arc-transversal-median``, ``triangulation``):
    drop the points that the map itself shows hidden behind a surface from their
    transducers — the ghosts of multiply reflected echoes (sight.line_of_sight).
    """

    mode: MappingMode = "reflectors"
    weight: VoteWeight = "unit"
    band_m: float | None = None
    precision: Precision = "float32"
    reciprocal: Reciprocal = "merge"
    combine: Combine = "viewpoints"
    isolated_bias_m: float | None = None
    line_of_sight: bool = True


@dataclass(frozen=True)
class PostSettings:
    """Post-processing of the map (thesis §2.1.1, 5): low-pass, thinning, profile fit.

    ``filter``: ``mean3`` (eq. 2.4) or ``none``; ``level``: occupied cells of the filtered
    map, as a fraction of its maximum (null: automatic); ``thinning``: ``thesis`` (eq. 2.5
    as written) or ``guo-hall`` (one-pixel 8-connected curves); ``fit``: ``polynomial`` of
    ``poly_order`` along a single wall (the thesis: 5–8), ``spline`` along each linked curve
    (rooms too), ``walls`` (rooms: straight walls where the data are straight, extended to
    meet at corners and edges within ``join_m`` of their ends, splines elsewhere;
    post.walls.fit_walls) or ``none``; curves closer than ``max_gap_m`` are bridged;
    ``subcell`` moves each thin cell to the vote-weighted centroid of the filtered map around
    it. ``fit``, ``max_gap_m`` and ``join_m`` null: chosen from the scene
    (:mod:`clsonar.survey`).
    """

    filter: PostFilter = "mean3"
    level: float | None = None
    thinning: Thinning = "guo-hall"
    fit: Fit | None = None
    poly_order: int = 7
    max_gap_m: float | None = None
    subcell: bool = True
    join_m: float | None = None
