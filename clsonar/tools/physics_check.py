"""clsonar's echo amplitudes against independent references (issue 18, docs/physics.md).

For each reflector kind a set of geometries — ranges from 0.3 to 10 m, several incidence
angles — is built as a scene, its echoes computed by clsonar's echo engine (the NumPy
float64 model, :func:`~clsonar.echoes.reference_echoes`, which the kernels match) and the
amplitude of the echo of that kind compared with the reference of
:mod:`clsonar.tools.references`, written from the published formulas:

- ``plane``: the Kirchhoff integral of a 40 m wall (an image source, to 1e-5);
- ``corner``: the image method's double bounce of a rigid right-angled corner, which is the
  exact solution of a 90° wedge (its diffraction terms cancel, ν = 2);
- ``edge``: the Biot–Tolstoy–Medwin solution of a rigid 90° box corner, for the pulse;
- ``knife``: the same solution for a thin wall's free end inside the map (a half-plane,
  n = 2: geometry.free_ends);
- ``boundary``: the same box corner seen within 3° of a face's reflection boundary, where
  the face's specular echo and the edge's diffraction arrive together and interfere:
  clsonar's received signal (both echoes, each with its carrier phase, detected) against
  the face's image source and the BTM diffraction summed for the pulse
  (:func:`~clsonar.tools.references.wedge_echo_gain`);
- ``cylinder``: the eigenfunction series of a rigid cylinder, for the pulse;
- ``sinusoid``: the Kirchhoff integral of the sinusoid over its crest (convex) and trough
  (concave), whose focusing geometrical optics caps at the caustic.

Transducers face the reflection point, with a uniform beam, a reflection coefficient of 1
and no absorption, so an echo's amplitude over A0 is the reflector's gain over a flat
mirror at the same path (physics.py). ``python -m clsonar.tools.physics_check --out DIR``
writes ``tables.md``, one plot per kind and ``ranges.md`` (each kind's detection range with
the default settings and with the Polaroid 6500 receiver, :mod:`clsonar.tools.detection_ranges`)
into DIR.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TypedDict

import numpy as np

from ..echoes import reference_echoes
from ..scene import Scene, scene_from_dict
from ..survey import OPEN_MIN_ENVELOPE
from . import detection_ranges
from . import references as ref

#: Ranges (m) of every kind, and the extra ones of the plots.
RANGES = (0.3, 1.0, 3.0, 10.0)
PLOT_RANGES = tuple(np.geomspace(0.3, 10.0, 12))


@dataclass(frozen=True)
class Row:
    """One geometry: clsonar's gain and the reference's (relative to a flat mirror)."""

    kind: str
    case: str  # what the geometry is
    range_m: float  # from the transducer to the reflector
    model: float  # clsonar's echo amplitude over A0
    reference: float
    note: str = ""  # where the comparison leaves the model's domain (not held to 1 dB)

    @property
    def db(self) -> float:
        """clsonar over the reference, in dB."""
        return 20.0 * math.log10(self.model / self.reference)


def _scene(surfaces: list[dict], transducers: list[tuple[np.ndarray, np.ndarray]],
           edge_model: str = "utd", open_floor: bool = False) -> Scene:
    """A scene of ``surfaces`` and transducers (position, aim point) facing their aims;
    with ``open_floor`` its envelope detection's floor is an open scene's
    (clsonar.survey.OPEN_MIN_ENVELOPE), so the received echoes are detected."""
    pts = np.array([p for p, _ in transducers] + [a for _, a in transducers])
    lo, hi = pts.min(axis=0) - 1.0, pts.max(axis=0) + 1.0
    return scene_from_dict({
        "clsonar": 1, "name": "physics-check", "extent": [*lo, *hi], "cell": 0.05,
        "surfaces": surfaces,
        "transducer": {"directivity": "uniform"},
        "echo": {"reflection_coefficient": 1.0, "max_order": 2, "edge_model": edge_model},
        **({"detection": {"min_envelope": OPEN_MIN_ENVELOPE}} if open_floor else {}),
        "sensors": {"transducers": [
            {"position": [float(p[0]), float(p[1])], "group": 0, "heading_deg":
             math.degrees(math.atan2(a[1] - p[1], a[0] - p[0]))} for p, a in transducers]},
    }, "physics-check")


def model_gain(scene: Scene, kind: str, tx: int = 0, rx: int = 0,
               tof: float | None = None) -> float:
    """The amplitude over A0 of the echo of ``kind`` from ``tx`` to ``rx``: the largest, or
    the one whose time of flight is nearest ``tof``."""
    table = reference_echoes(scene)
    pick = np.flatnonzero((table.kind_names() == kind) & (table.tx == tx) & (table.rx == rx))
    if len(pick) == 0:
        return math.nan
    if tof is not None:
        pick = pick[np.abs(table.tof_s[pick] - tof) == np.abs(table.tof_s[pick] - tof).min()]
    return float(table.amplitude[pick].max() / scene.transducer.amplitude)


def received_gain(scene: Scene, tof: float) -> float:
    """The largest detection over A0 of transmitter 0's own received signal (every echo,
    each with its carrier phase, synthesised and detected in float64, clsonar.signals)
    whose time of flight is within 12σ of ``tof``: what the receiver reads of echoes that
    arrive together."""
    from ..signals import detect_reference

    found = detect_reference(scene, None, reference_echoes(scene))
    near = (found.tx == 0) & (found.rx == 0) & (
        np.abs(found.tof_s - tof) < 12 * scene.transducer.pulse_sigma_s)
    return float(found.amplitude[near].max() / scene.transducer.amplitude) if near.any() \
        else math.nan


def _polar(d: float, angle_deg: float) -> np.ndarray:
    a = math.radians(angle_deg)
    return np.array([d * math.cos(a), d * math.sin(a)])


def plane_rows(ranges=RANGES) -> Iterator[Row]:
    """A wall along y = 0 seen square on (T = R) and at 20° incidence (T ≠ R)."""
    wall = [{"type": "polyline", "points": [[-20.0, 0.0], [20.0, 0.0]]}]
    curve = np.array(wall[0]["points"])
    for d in ranges:
        for inc in (0.0, 20.0):
            t, r = _polar(d, 90.0 + inc), _polar(d, 90.0 - inc)
            pair = [(t, np.zeros(2))] if inc == 0 else [(t, np.zeros(2)), (r, np.zeros(2))]
            scene = _scene(wall, pair)
            got = model_gain(scene, "specular", 0, 0 if inc == 0 else 1)
            want = ref.kirchhoff_gain_near(curve, t, r, 2 * d / scene.medium.c, **_wave(scene))
            yield Row("plane", f"incidence {inc:g}°", d, got, want)


class _Wave(TypedDict):
    c: float
    f: float
    sigma: float


def _wave(scene: Scene) -> _Wave:
    """The references' keywords for ``scene``'s sound: speed, carrier and pulse σ."""
    t = scene.transducer
    return {"c": scene.medium.c, "f": t.frequency_hz, "sigma": t.pulse_sigma_s}


def corner_rows(ranges=RANGES) -> Iterator[Row]:
    """A right-angled corner's retro-reflection (T = R) seen at 20°, 45° and 70° from a
    wall; the reference is the image method (exact for a rigid 90° wedge), gain 1."""
    corner = [{"type": "polyline", "points": [[20.0, 0.0], [0.0, 0.0], [0.0, 20.0]]}]
    for d in ranges:
        for angle in (20.0, 45.0, 70.0):
            t = _polar(d, angle)
            got = model_gain(_scene(corner, [(t, np.zeros(2))]), "corner")
            yield Row("corner", f"seen at {angle:g}°", d, got, 1.0)


#: A box corner at the origin: faces along −x (a) and −y (b), the box between them.
_FACE_A, _FACE_B = np.array([-1.0, 0.0]), np.array([0.0, -1.0])


#: Angles of the edge rows: 90° and 180° are the reflection boundaries of faces a and b
#: (the face's specular point at the vertex), approached from both sides.
EDGE_ANGLES = (5.0, 45.0, 85.0, 89.0, 91.0, 95.0, 135.0, 175.0, 185.0, 225.0, 265.0)


def edge_rows(ranges=RANGES, angles=EDGE_ANGLES, edge_model: str = "utd") -> Iterator[Row]:
    """A rigid box corner (a 270° free wedge, n = 1.5) seen monostatically at angle φ from
    face a through the free region (90° and 180°: the faces' reflection boundaries)."""
    box = [[-10.0, 0.0], [0.0, 0.0], [0.0, -10.0]]
    return _wedge_rows("edge", box, _FACE_B, ranges, angles, edge_model)


def _wedge_rows(kind: str, points: list[list[float]], face_b: np.ndarray, ranges, angles,
                edge_model: str = "utd") -> Iterator[Row]:
    """The diffraction of the vertex at the origin of the polyline ``points`` (face a along
    −x, face b along ``face_b``) seen monostatically at angle φ from face a, against the
    BTM solution, as rows of ``kind``."""
    wall = [{"type": "polyline", "points": points}]
    for d in ranges:
        for phi in angles:
            t = _polar(d, 180.0 - phi)  # face a points to 180°, φ grows clockwise
            scene = _scene(wall, [(t, np.zeros(2))], edge_model)
            got = model_gain(scene, "edge")
            want = ref.btm_edge_gain(t, t, np.zeros(2), _FACE_A, face_b, **_wave(scene))
            yield Row(kind, f"φ {phi:g}°", d, got, want)


#: Angles of the knife-edge rows: 90° and 270° are the reflection boundaries of the wall's
#: two sides; at 180° (end-on) a half-plane's monostatic diffraction vanishes.
KNIFE_ANGLES = (5.0, 45.0, 85.0, 89.0, 91.0, 95.0, 135.0, 225.0, 265.0, 269.0, 271.0, 355.0)


def knife_rows(ranges=RANGES, angles=KNIFE_ANGLES) -> Iterator[Row]:
    """A thin wall's free end inside the map (the wall along −x from the origin, both of
    its sides reflecting: a rigid half-plane, n = 2) seen monostatically at angle φ from
    its upper side through the free region."""
    return _wedge_rows("knife", [[-10.0, 0.0], [0.0, 0.0]], _FACE_A, ranges, angles)


#: Angles of the boundary rows: within 3° of face a's reflection boundary (90°), where the
#: face's specular echo arrives within about a pulse of the edge's at every range.
BOUNDARY_ANGLES = (87.0, 89.0, 89.7, 90.3, 91.0, 93.0)


def boundary_rows(ranges=RANGES, angles=BOUNDARY_ANGLES) -> Iterator[Row]:
    """The box corner of :func:`edge_rows` seen monostatically near face a's reflection
    boundary (φ < 90°: the lit side, where the face's specular echo exists): the whole
    received echo, face and edge together, against the wedge's exact one."""
    box = [{"type": "polyline", "points": [[-10.0, 0.0], [0.0, 0.0], [0.0, -10.0]]}]
    for d in ranges:
        for phi in angles:
            t = _polar(d, 180.0 - phi)
            scene = _scene(box, [(t, np.zeros(2))], open_floor=True)
            got = received_gain(scene, 2 * d / scene.medium.c)
            want = ref.wedge_echo_gain(t, t, np.zeros(2), _FACE_A, _FACE_B, **_wave(scene))
            yield Row("boundary", f"φ {phi:g}°", d, got, want)


def cylinder_rows(ranges=RANGES, radii=(0.05, 0.3, 1.0)) -> Iterator[Row]:
    """A rigid cylinder of radius a at distance d from its surface (T = R)."""
    for a in radii:
        circle = [{"type": "circle", "center": [0.0, 0.0], "radius": a}]
        for d in ranges:
            t = np.array([0.0, a + d])
            scene = _scene(circle, [(t, np.zeros(2))])
            got = model_gain(scene, "curved")
            want = ref.cylinder_series_echo_gain(t, t, np.zeros(2), a, **_wave(scene))
            yield Row("cylinder", f"radius {a:g} m", d, got, want)


#: The sinusoid of the check: y = A·sin(πx), period 2 m; radius of curvature at its crest
#: (x = 0.5, convex) and trough (x = −0.5, concave) 1/(A·π²) = 2.03 m.
SINE_A = 0.05


def sinusoid_rows(ranges=(0.3, 0.6, 1.0, 1.5, 2.0, 3.0, 10.0)) -> Iterator[Row]:
    """The sinusoid's crest and trough seen square on (T = R) from ``ranges`` above them."""
    wave = [{"type": "sinusoid", "from": [-10.0, 0.0], "to": [10.0, 0.0],
             "amplitude": SINE_A, "period": 2.0}]
    x = np.linspace(-3.0, 3.0, 6001)
    curve = np.column_stack([x, SINE_A * np.sin(math.pi * x)])
    for name, x0, y0 in (("crest", 0.5, SINE_A), ("trough", -0.5, -SINE_A)):
        for d in ranges:
            t = np.array([x0, y0 + d])
            scene = _scene(wave, [(t, np.array([x0, y0]))])
            got = model_gain(scene, "curved", tof=2 * d / scene.medium.c)
            want = ref.kirchhoff_gain_near(curve, t, t, 2 * d / scene.medium.c, **_wave(scene))
            yield Row("sinusoid", name, d, got, want, _caustic_note(name, d))


def _caustic_note(name: str, d: float) -> str:
    """Why a trough row leaves geometrical optics' domain: near its caustic (the centre of
    curvature, 1/(A·π²)) the focus is capped at physics.MAX_FOCUS_GAIN; past it three
    specular points' echoes overlap, which the receiver sums."""
    caustic = 1.0 / (SINE_A * math.pi**2)
    if name != "trough" or d < 0.9 * caustic:
        return ""
    if d <= 1.1 * caustic:
        return "at the caustic: geometrical optics diverges, capped at MAX_FOCUS_GAIN"
    return "past the caustic: three overlapping echoes, the receiver sums them"


KINDS: dict[str, Callable[..., Iterator[Row]]] = {
    "plane": plane_rows, "corner": corner_rows, "edge": edge_rows, "knife": knife_rows,
    "boundary": boundary_rows, "cylinder": cylinder_rows, "sinusoid": sinusoid_rows,
}


def all_rows(kinds=tuple(KINDS), plot_ranges: bool = False) -> list[Row]:
    """The rows of ``kinds`` (at :data:`PLOT_RANGES` with ``plot_ranges``), and the edges
    again under ``echo.edge_model`` ``"estimate"`` (kind ``edge-estimate``)."""
    rows = [r for k in kinds
            for r in (KINDS[k](ranges=PLOT_RANGES) if plot_ranges else KINDS[k]())]
    if "edge" in kinds:
        rows += [Row("edge-estimate", r.case, r.range_m, r.model, r.reference, r.note)
                 for r in edge_rows(PLOT_RANGES if plot_ranges else RANGES,
                                    edge_model="estimate")]
    return rows


def markdown(rows: list[Row]) -> str:
    """One table per kind: case, range, clsonar, reference, difference in dB."""
    out = []
    for kind in dict.fromkeys(r.kind for r in rows):
        mine = [r for r in rows if r.kind == kind]
        worst = max(abs(r.db) for r in mine if not r.note)
        out += [f"### {kind}", "", f"Largest difference in the model's domain: "
                f"**{worst:.2f} dB**.", "",
                "| case | range m | clsonar | reference | dB | note |",
                "| --- | ---: | ---: | ---: | ---: | --- |"]
        out += [f"| {r.case} | {r.range_m:g} | {r.model:.4g} | {r.reference:.4g} | "
                f"{r.db:+.2f} | {r.note} |" for r in mine]
        out.append("")
    return "\n".join(out)


def plot(rows: list[Row], kind: str, path: Path) -> None:
    """Gain over range (log–log) of ``kind``: clsonar's lines, the reference's markers."""
    from ..files import write_atomic
    from ..plots import figure, png_bytes

    fig = figure((6.4, 4.4), 130)
    ax = fig.add_subplot()
    for i, case in enumerate(dict.fromkeys(r.case for r in rows if r.kind == kind)):
        mine = sorted((r for r in rows if r.kind == kind and r.case == case),
                      key=lambda r: r.range_m)
        x = [r.range_m for r in mine]
        line, = ax.plot(x, [r.model for r in mine], color=f"C{i % 10}", label=case)
        ax.plot(x, [r.reference for r in mine], "o", color=line.get_color(), mfc="none")
    ax.set(xscale="log", yscale="log", xlabel="range (m)", ylabel="gain over a flat mirror",
           title=f"{kind}: clsonar (lines) and reference (circles)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    write_atomic(path, png_bytes(fig))


def main(argv: list[str] | None = None) -> int:
    """``python -m clsonar.tools.physics_check --out DIR``: the tables and plots."""
    parser = argparse.ArgumentParser(prog="python -m clsonar.tools.physics_check",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, type=Path, help="output folder")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    from ..files import write_atomic

    rows = all_rows()
    write_atomic(args.out / "tables.md", (markdown(rows) + "\n").encode())
    curves = all_rows(plot_ranges=True)
    for kind in dict.fromkeys(r.kind for r in curves):
        plot(curves, kind, args.out / f"{kind}.png")
    write_atomic(args.out / "ranges.md", detection_ranges.markdown().encode())
    print(f"wrote {args.out}/tables.md, ranges.md and {len(set(r.kind for r in curves))} "
          "plots")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
