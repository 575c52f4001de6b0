"""Judging the echo kernels (kernels/echoes.cl, float32) against the float64 reference
(:func:`clsonar.echoes.reference_echoes`) on the echo cases."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from dataclasses import replace

import numpy as np

from ... import echoes as echoes_mod
from ...echoes import EchoTable
from ...echoes import host as echo_host
from ...geometry import build_geometry
from ...scene import Circle, Scene
from ...scene import Transducer as SceneTransducer
from .echo_cases import echo_scene
from .findings import BOUNDS, EPS32, Findings, Matches, finite

#: Alternative work-group sizes of the echo kernels (along the elements).
ALT_ECHO_GROUPS = (8, 1)

def _keys(table: EchoTable) -> list[tuple]:
    """(tx, rx, kind, order, element) of every row."""
    return list(zip(table.tx.tolist(), table.rx.tolist(), table.kind.tolist(),
                    table.order.tolist(), table.element.tolist(), strict=True))


def _n_circles(scene: Scene) -> int:
    """How many circles ``scene`` has (a sinusoid's element numbers follow theirs)."""
    return sum(isinstance(s, Circle) for s in scene.surfaces)


def _near_keys(key: tuple, n_circles: int) -> list[tuple]:
    """``key`` and, for a sinusoid's echo, the same echo from a neighbouring sampling
    interval."""
    if key[2] == echoes_mod.CURVED and key[4] >= n_circles:
        return [key, (*key[:4], key[4] - 1), (*key[:4], key[4] + 1)]
    return [key]


def match_echoes(ref: EchoTable, got: EchoTable, n_circles: int) -> Matches:
    """Pair rows of ``got`` with rows of ``ref`` on (tx, rx, kind, order, element), nearest
    time of flight first; a sinusoid's echo may come from the neighbouring sampling interval
    (its specular point on the shared sample). Returns (pairs, ref-only rows, got-only rows)."""
    index: dict[tuple, list[int]] = {}
    for j, key in enumerate(_keys(got)):
        index.setdefault(key, []).append(j)
    used = np.zeros(len(got), dtype=bool)
    matched, ref_only = [], []
    for i, key in enumerate(_keys(ref)):
        options = [j for k in _near_keys(key, n_circles) for j in index.get(k, []) if not used[j]]
        if not options:
            ref_only.append(i)
            continue
        j = min(options, key=lambda j: abs(got.tof_s[j] - ref.tof_s[i]))
        used[j] = True
        matched.append((i, j))
    return matched, ref_only, np.flatnonzero(~used).tolist()


def _jittered(scene: Scene, rng: np.random.Generator, delta: float) -> Scene:
    """``scene`` with every transducer moved by up to ``delta`` and turned by up to
    ``delta`` radians (float32 rounding of a position or direction)."""
    ts = tuple(SceneTransducer((t.position[0] + rng.uniform(-delta, delta),
                                t.position[1] + rng.uniform(-delta, delta)),
                               t.heading_deg + math.degrees(rng.uniform(-delta, delta)), t.group)
               for t in scene.sensors.transducers)
    return replace(scene, sensors=replace(scene.sensors, transducers=ts))


def _edge_echo_keys(scene: Scene, jitters: int = 6) -> set[tuple]:
    """Keys (tx, rx, kind, order, element) of echoes whose existence in the float64
    reference changes when the transducers move by a few float32 roundings of the scene's
    local coordinates: knife-edge decisions that float32 may take either way."""
    delta = _roundings_m(scene)
    base = set(_keys(echoes_mod.reference_echoes(scene)))
    rng = np.random.default_rng(0)
    unstable: set[tuple] = set()
    for _ in range(jitters):
        unstable |= base ^ set(_keys(echoes_mod.reference_echoes(_jittered(scene, rng, delta))))
    return unstable


def _roundings_m(scene: Scene) -> float:
    """``edge_roundings`` float32 roundings of the scene's local coordinates, metres."""
    x0, y0, x1, y1 = scene.extent
    return BOUNDS["edge_roundings"] * EPS32 * max(0.5 * math.hypot(x1 - x0, y1 - y0), 1e-3)


def _on_a_vertex(point: np.ndarray, vertices: np.ndarray, scene: Scene) -> bool:
    """Whether an echo's reflection point lies within :func:`_roundings_m` of a polyline's
    vertex or end: whether it exists there hangs on the strict tests of the vertex (on the
    wall, in front of it, a leg not blocked by the next wall), which moving the transducers
    does not always flip (:func:`_edge_echo_keys`)."""
    return (bool(len(vertices))
            and float(np.min(np.hypot(*(vertices - point).T))) <= _roundings_m(scene))


def _table_arrays(t: EchoTable) -> tuple:
    return (t.tx, t.rx, t.tof_s, t.amplitude, t.kind, t.order, t.point, t.element)


def _same_table(a: EchoTable, b: EchoTable) -> bool:
    """Whether two echo tables are identical, to the bit."""
    return len(a) == len(b) and all(np.array_equal(x, y) for x, y in
                                    zip(_table_arrays(a), _table_arrays(b), strict=True))


@contextlib.contextmanager
def echo_work_group(size: int) -> Iterator[None]:
    """Run the echo kernels with work groups of ``size`` along the elements."""
    saved = echo_host.WORK_GROUP
    echo_host.WORK_GROUP = size
    try:
        yield
    finally:
        echo_host.WORK_GROUP = saved



def check_echo_case(family: str, seed: int, context, *, many: int = 40,
                    work_groups: bool = False) -> Findings:
    """Compare the float32 echo kernels with the float64 reference on one case."""
    name = f"echo {family} seed={seed}"
    scene = echo_scene(family, seed, many=many)
    f = Findings(cases=1)
    ref = echoes_mod.reference_echoes(scene)
    got = echoes_mod.compute_echoes(scene, context=context, precision="float32")
    for label, t in (("reference", ref), ("float32", got)):
        if not finite(t.tof_s, t.amplitude, t.point):
            f.nonfinite += 1
            f.fail(name, f"NaN or Inf in the {label} echo table")
            return f
    n_circles = _n_circles(scene)
    matched, ref_only, got_only = match_echoes(ref, got, n_circles)
    f.echoes = len(ref)
    if matched:
        i, j = np.asarray(matched).T
        err = np.abs(got.tof_s[j] - ref.tof_s[i])
        k = int(np.argmax(err))
        f.tof_max_s = float(err[k])
        f.tof_worst = (f"{name} pair {ref.tx[i[k]]}->{ref.rx[i[k]]} "
                       f"{echoes_mod.KINDS[ref.kind[i[k]]]}")
        rel = np.abs(got.amplitude[j] - ref.amplitude[i]) / ref.amplitude[i]
        k = int(np.argmax(rel))
        f.amp_max_rel = float(rel[k])
        f.amp_worst = (f"{name} pair {ref.tx[i[k]]}->{ref.rx[i[k]]} "
                       f"{echoes_mod.KINDS[ref.kind[i[k]]]} A={ref.amplitude[i[k]]:.3g}")
        if f.tof_max_s > BOUNDS["tof_abs_s"]:
            f.fail(name, f"time of flight differs by {f.tof_max_s:.3g} s > 1 µs ({f.tof_worst})")
    if ref_only or got_only:
        edge = _edge_echo_keys(scene)
        keys_ref, keys_got = _keys(ref), _keys(got)
        weak = BOUNDS["weak_echo"] * scene.transducer.amplitude
        lonely = ([(keys_ref[i], ref.amplitude[i], ref.point[i]) for i in ref_only]
                  + [(keys_got[j], got.amplitude[j], got.point[j]) for j in got_only])
        vertices = build_geometry(scene).vertices
        for key, amp, point in lonely:
            if (any(k in edge for k in _near_keys(key, n_circles))
                    or _on_a_vertex(point, vertices, scene)):
                f.unmatched_edge += 1
            elif amp < weak:
                f.unmatched_weak += 1
            else:
                f.unmatched_other += 1
                f.fail(name, f"echo {key} in one table only, and not on a knife edge")
    if work_groups:
        for size in ALT_ECHO_GROUPS:
            with echo_work_group(size):
                again = echoes_mod.compute_echoes(scene, context=context, precision="float32")
            if not _same_table(got, again):
                f.work_group_mismatches += 1
                f.fail(name, f"work groups of {size} give another echo table")
    return f

