"""The runs of a sweep: scenes × grid × seeds, each with its final scene and a stable id
(:func:`plan`), and :func:`load_spec`, which validates every run's scene before anything
runs."""

from __future__ import annotations

import hashlib
import itertools
import json
import os
from dataclasses import dataclass
from typing import Any

from ...scene import Scene, scene_from_dict, scene_to_dict
from ...version import __version__
from ..variants import at_distance, with_seed
from .spec import PSEUDO_KEYS, SceneEntry, Spec, SpecError, read_spec, set_key


@dataclass(frozen=True, eq=False)
class Run:
    """One planned run: the final scene (parameters and seed applied) and its row's keys."""

    index: int
    label: str
    params: dict[str, Any]
    seed: int
    scene: Scene
    preset: str | None
    run_id: str


def run_id(scene: Scene, preset: str | None, params: dict[str, Any], seed: int) -> str:
    """A stable id of a run: a hash of its final scene, preset, parameters, seed and the
    clsonar version (a sweep resumed by another version redoes its runs)."""
    text = json.dumps({"scene": scene_to_dict(scene), "preset": preset, "params": params,
                       "seed": seed, "clsonar": __version__}, sort_keys=True,
                      allow_nan=False)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def make_run(index: int, label: str, scene: Scene, params: dict[str, Any], seed: int,
             preset: str | None) -> Run:
    """A :class:`Run` of ``scene`` (parameters already applied) at seed ``seed``."""
    seeded = with_seed(scene, seed)
    return Run(index, label, dict(params), seed, seeded, preset,
               run_id(seeded, preset, params, seed))


def _apply(spec: Spec, entry: SceneEntry, params: dict[str, Any]) -> Scene:
    """``entry``'s scene with the scene-key parameters set (validated) and moved to
    ``distance_m`` if that is swept."""
    data = scene_to_dict(entry.scene)
    for key, value in params.items():
        if key in PSEUDO_KEYS:
            continue
        try:
            data = set_key(data, key, value)
        except KeyError as e:
            raise SpecError(f"unknown key path in scene {entry.label!r}: {e.args[0]}",
                            f"grid.{key}", spec.source) from None
    where = ", ".join(f"{k}={json.dumps(v)}" for k, v in params.items())
    scene = scene_from_dict(data, source=f"{spec.source} ({entry.label}, {where})")
    if "distance_m" in params:
        assert entry.distance_m is not None  # read_spec requires it when distance_m is swept
        try:
            scene = at_distance(scene, entry.distance_m, float(params["distance_m"]))
        except ValueError as e:
            raise SpecError(str(e), "grid.distance_m", spec.source) from None
    return scene


def plan(spec: Spec) -> list[Run]:
    """Every run of ``spec``, in order: scenes × grid (first key slowest) × seeds."""
    runs: list[Run] = []
    keys = spec.parameters
    for entry in spec.scenes:
        for values in itertools.product(*(v for _, v in spec.grid)):
            params = dict(zip(keys, values, strict=True))
            scene = _apply(spec, entry, params)
            preset = params.get("preset", spec.preset)
            for seed in spec.seeds:
                runs.append(make_run(len(runs), entry.label, scene, params, seed, preset))
    return runs




def load_spec(path: str | os.PathLike[str]) -> Spec:
    """Read and validate a sweep spec (TOML if it ends in ``.toml``, else JSON).

    Every run is expanded and its scene validated here, so a bad spec fails with one
    :class:`SpecError` (or the scene loader's :class:`SceneError`) before anything runs.
    """
    spec = read_spec(path)
    plan(spec)  # validates every run's scene
    return spec
