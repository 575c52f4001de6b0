"""The stage cache (:class:`StageCache`): a run's stages reused by a later run whose
inputs to them are unchanged — a sweep's seeds and noise levels, the GUI's runs — keyed by
a hash of the scene keys each stage reads (:func:`stage_keys`)."""

from __future__ import annotations

import hashlib
import json

from .scene import Scene, scene_to_dict
from .skips import Skips


class StageCache:
    """A content-keyed cache of a run's stages: the front ones (sensors, echoes,
    detection, accumulation) one by one, post-processing as one, and what the metrics
    score against (``truth``): each is reused when every scene key it reads, the device
    and the skips are unchanged. Keeps the last ``size`` results of each."""

    def __init__(self, size: int = 4) -> None:
        self.size = size
        self._entries: dict[str, dict[str, object]] = {}

    def get(self, stage: str, key: str) -> object | None:
        return self._entries.get(stage, {}).get(key)

    def put(self, stage: str, key: str, value: object) -> None:
        entries = self._entries.setdefault(stage, {})
        entries.pop(key, None)
        entries[key] = value
        while len(entries) > self.size:
            entries.pop(next(iter(entries)))


#: The scene-file keys each stage reads (and, through its inputs, every earlier stage's).
STAGE_KEYS = {
    "sensors": ("extent", "surfaces", "sensors"),
    "echoes": ("medium", "transducer", "echo"),
    "detection": ("signal", "detection"),
    "accumulation": ("cell", "mapping"),
}


def stage_keys(scene: Scene, device: str, skips: Skips) -> dict[str, str]:
    """The cache key of each stage: a hash of the scene keys it and the stages before it
    read (:data:`STAGE_KEYS`; ``post`` for ``pipeline.post_process``), the device and the skips.
    A noise-free run is the same run whatever its noise seed (:func:`_drawn_seeds`). No
    front stage reads a post-processing setting."""
    data = _drawn_seeds(scene_to_dict(scene))
    keys: dict[str, str] = {}
    seen: list[object] = [device, repr(skips)]
    for stage, names in {**STAGE_KEYS, "post": ("post",)}.items():
        seen += [data.get(n) for n in names]
        keys[stage] = hashlib.sha256(json.dumps(seen, sort_keys=True).encode()).hexdigest()
    return keys


def _drawn_seeds(data: dict) -> dict:
    """The scene file ``data`` without the noise seed of a noise-free signal, which draws
    nothing (only ``random-lines`` and ``per-wall`` placements have seeds, and they draw
    positions)."""
    signal = data.get("signal") or {}
    if signal.get("noise_std"):
        return data
    return {**data, "signal": {k: v for k, v in signal.items() if k != "seed"}}


__all__ = ["STAGE_KEYS", "StageCache", "stage_keys"]
