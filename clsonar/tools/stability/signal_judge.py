"""Judging the detection kernels (kernels/signals.cl, float32) against the float64 reference
(:func:`clsonar.signals.detect_reference`) on the float64 echoes of the echo cases."""

from __future__ import annotations

from dataclasses import replace
from typing import get_args

import numpy as np

from ... import echoes as echoes_mod
from ... import signals
from ...echoes import EchoTable
from ...scene import Scene
from ...scene.settings import DetectionMode
from ...sensors import SensorArray, place_sensors
from .echo_cases import ECHO_FAMILIES, echo_scene
from .findings import BOUNDS, EPS32, Findings, Matches, finite

#: Echo families whose scenes also drive the detection check (``many`` has too many pairs
#: for the NumPy reference's A-scans).
SIGNAL_FAMILIES = tuple(f for f in ECHO_FAMILIES if f != "many")

#: Alternative work-group sizes of the detection kernels. (Other chunk lengths, samples per
#: work item, restart the running sums elsewhere: detections move by float32 rounding,
#: ~10⁻¹⁰ s, so they are not compared bit for bit.)
ALT_SIGNAL_GROUPS = (8, 1)


def signal_scene(family: str, seed: int) -> Scene:
    """The echo case's scene with a random detector (threshold or envelope) and noise."""
    rng = np.random.default_rng([seed, 200 + ECHO_FAMILIES.index(family)])
    scene = echo_scene(family, seed)
    modes: tuple[DetectionMode, ...] = get_args(DetectionMode)  # ("threshold", "envelope")
    mode = modes[int(rng.choice(len(modes)))]
    noise = float(rng.choice([0.0, 0.0, 0.3, 1.0]))
    return replace(scene, detection=replace(scene.detection, mode=mode),
                   signal=replace(scene.signal, noise_std=noise, seed=int(seed)))


def _match_detections(ref: signals.Detections, got: signals.Detections) -> Matches:
    """Pair detections of one (tx, rx) by nearest time of flight, closest pairs first."""
    by_pair: dict[tuple[int, int], list[int]] = {}
    for j, key in enumerate(zip(got.tx.tolist(), got.rx.tolist(), strict=True)):
        by_pair.setdefault(key, []).append(j)
    candidates = []
    for i, key in enumerate(zip(ref.tx.tolist(), ref.rx.tolist(), strict=True)):
        candidates += [(abs(got.tof_s[j] - ref.tof_s[i]), i, j) for j in by_pair.get(key, [])]
    used_i: set[int] = set()
    used_j: set[int] = set()
    matched = []
    for gap, i, j in sorted(candidates):
        if i not in used_i and j not in used_j and gap <= 10 * BOUNDS["tof_abs_s"]:
            used_i.add(i)
            used_j.add(j)
            matched.append((i, j))
    return (matched, [i for i in range(len(ref)) if i not in used_i],
            [j for j in range(len(got)) if j not in used_j])


def _nudged(table: EchoTable, rng: np.random.Generator, rel: float) -> EchoTable:
    """``table`` with amplitudes and times of flight off by float32-sized relative amounts."""
    return replace(table, amplitude=table.amplitude * (1 + rng.uniform(-rel, rel, len(table))),
                   tof_s=table.tof_s * (1 + rng.uniform(-rel, rel, len(table))))


def _edge_detections(scene: Scene, echoes: EchoTable, sensors: SensorArray,
                     jitters: int = 6) -> set[tuple]:
    """(tx, rx, tof rounded to 10 µs) of detections that the float64 reference gains or
    loses when the echoes' amplitudes and times move by a few float32 roundings: threshold
    crossings and peak merges decided by rounding."""
    def keys(d: signals.Detections) -> set[tuple]:
        return {(t, r, round(x * 1e5)) for t, r, x in
                zip(d.tx.tolist(), d.rx.tolist(), d.tof_s.tolist(), strict=True)}

    base = keys(signals.detect_reference(scene, sensors, echoes))
    rng = np.random.default_rng(1)
    unstable: set[tuple] = set()
    for _ in range(jitters):
        nudged = _nudged(echoes, rng, BOUNDS["edge_roundings"] * EPS32)
        unstable |= base ^ keys(signals.detect_reference(scene, sensors, nudged))
    return unstable


def check_signal_case(family: str, seed: int, context, *, work_groups: bool = False
                      ) -> Findings:
    """Compare the float32 detection kernels (kernels/signals.cl) with the float64 reference
    (:func:`clsonar.signals.detect_reference`) on the float64 echoes of one case."""
    name = f"signal {family} seed={seed}"
    scene = signal_scene(family, seed)
    sensors = place_sensors(scene)
    echoes = echoes_mod.reference_echoes(scene, sensors)
    f = Findings(cases=1)
    ref = signals.detect_reference(scene, sensors, echoes)
    got = signals.detect(scene, sensors, echoes, context=context)
    for label, d in (("reference", ref), ("float32", got)):
        if not finite(d.tof_s, d.amplitude):
            f.nonfinite += 1
            f.fail(name, f"NaN or Inf in the {label} detections")
            return f
    matched, ref_only, got_only = _match_detections(ref, got)
    f.echoes = len(ref)
    if matched:
        i, j = np.asarray(matched).T
        err = np.abs(got.tof_s[j] - ref.tof_s[i])
        k = int(np.argmax(err))
        f.tof_max_s = float(err[k])
        f.tof_worst = f"{name} pair {ref.tx[i[k]]}->{ref.rx[i[k]]} ({scene.detection.mode})"
        if f.tof_max_s > BOUNDS["tof_abs_s"]:
            f.fail(name, f"detected time of flight differs by {f.tof_max_s:.3g} s > 1 µs")
    if ref_only or got_only:
        edge = _edge_detections(scene, echoes, sensors)
        lonely = ([(ref.tx[i], ref.rx[i], ref.tof_s[i]) for i in ref_only]
                  + [(got.tx[j], got.rx[j], got.tof_s[j]) for j in got_only])
        for t, r, x in lonely:
            if any((int(t), int(r), round(x * 1e5) + dx) in edge for dx in (-1, 0, 1)):
                f.unmatched_edge += 1
            else:
                f.unmatched_other += 1
                f.fail(name, f"detection {t}->{r} at {x:.7g} s in one list only, and not "
                             "on a knife edge")
    if work_groups:
        for group in ALT_SIGNAL_GROUPS:
            again = signals.detect(scene, sensors, echoes, context=context, work_group=group)
            if not all(np.array_equal(a, b) for a, b in zip(
                    (got.tx, got.rx, got.tof_s, got.amplitude),
                    (again.tx, again.rx, again.tof_s, again.amplitude), strict=True)):
                f.work_group_mismatches += 1
                f.fail(name, f"work groups of {group} detect otherwise")
    return f

