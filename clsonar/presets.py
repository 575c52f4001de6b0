"""The presets of a run: the thesis' whole world and method (``thesis``), and ours (``best``,
the defaults of a scene file). ``clsonar run --preset NAME``; :func:`clsonar.pipeline.run`'s
``preset``."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from .scene import DetectionSettings, Directivity, MappingSettings, PostSettings, Scene


@dataclass(frozen=True)
class Preset:
    """The detection, mapping and post-processing settings a preset puts in a scene, and the
    parts of the world it sets: the transducer's ``directivity`` and the echo's
    ``curvature_gain`` (None: the scene's own; the scene's other transducer and echo keys
    are always kept)."""

    detection: DetectionSettings
    mapping: MappingSettings
    post: PostSettings
    directivity: Directivity | None = None
    curvature_gain: bool | None = None


#: Settings of the thesis' method and of ours (the defaults of a scene file). ``thesis`` is
#: the thesis' whole world: its uniform beam inside the ±12° cut (§2.1), no curvature gain
#: (its ray tracing), threshold detection, loci summed, eq. 2.5 thinning and the polynomial.
PRESETS: dict[str, Preset] = {
    "thesis": Preset(
        detection=DetectionSettings(mode="threshold"),
        mapping=MappingSettings(mode="loci", weight="unit", reciprocal="both", combine="sum",
                                isolated_bias_m=0.0),
        post=PostSettings(filter="mean3", level=1e-6, thinning="thesis", fit="polynomial",
                          poly_order=7, subcell=False, max_gap_m=0.3, join_m=0.5),
        directivity="uniform", curvature_gain=False),
    "best": Preset(DetectionSettings(), MappingSettings(), PostSettings()),
}


def apply_preset(scene: Scene, preset: str | None) -> Scene:
    """``scene`` with the detection/mapping/post settings of ``preset``, and its transducer
    directivity and echo curvature gain where the preset sets them (None: unchanged)."""
    if preset is None:
        return scene
    if preset not in PRESETS:
        raise ValueError(f"unknown preset {preset!r} (choose from {', '.join(PRESETS)})")
    chosen = PRESETS[preset]
    transducer, echo = scene.transducer, scene.echo
    if chosen.directivity is not None:
        transducer = dataclasses.replace(transducer, directivity=chosen.directivity)
    if chosen.curvature_gain is not None:
        echo = dataclasses.replace(echo, curvature_gain=chosen.curvature_gain)
    return dataclasses.replace(scene, detection=chosen.detection, mapping=chosen.mapping,
                               post=chosen.post, transducer=transducer, echo=echo)


__all__ = ["PRESETS", "Preset", "apply_preset"]
