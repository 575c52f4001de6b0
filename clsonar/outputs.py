"""The files ``clsonar run SCENE --out DIR`` writes (DESIGN.md, "Command line — a contract").

``report.json`` (scene, device, settings, counts, per-stage seconds, metrics),
``stages.npz`` (``raw``, ``filtered``, ``thin`` ``[iy, ix]`` with ``extent`` and ``cell``),
``profile.csv`` (``x,y``), ``echoes.csv`` (``tx,rx,tof_s,amplitude,kind,order``) and one PNG
per stage with the true geometry drawn over it. Every file is built in memory first and
written atomically (temporary name, then rename); a new DIR appears all at once.
"""

from __future__ import annotations

import io
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from . import plots
from .files import write_atomic
from .pipeline import RunResult

STAGE_PNGS = ("scene.png", "raw.png", "filtered.png", "thin.png", "profile.png")


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def profile_csv(points: np.ndarray) -> str:
    """``profile.csv``: header ``x,y``, one estimated surface point (metres) a line."""
    return "x,y\n" + "".join(f"{x:.6f},{y:.6f}\n" for x, y in points)


def render(result: RunResult) -> dict[str, bytes]:
    """Every output file of ``result`` as bytes, by file name."""
    s, g = result.scene, result.geometry
    npz = io.BytesIO()
    np.savez_compressed(npz, raw=result.raw, filtered=result.filtered, thin=result.thin,
                        extent=np.asarray(s.extent), cell=np.asarray(s.cell))
    echoes = io.StringIO()
    result.echoes.write_csv(echoes)
    profile = profile_csv(result.profile.points)
    m = result.metrics
    rms = m.get("rms_m")
    summary = (f"RMS (eq. 2.6) {rms * 100:.2f} cm" if rms is not None
               else f"accuracy RMS {_cm(m['accuracy_m']['rms'])}")
    return {
        "report.json": (json.dumps(result.report(), indent=2, default=_json_default)
                        + "\n").encode(),
        "stages.npz": npz.getvalue(),
        "profile.csv": profile.encode(),
        "echoes.csv": echoes.getvalue().encode(),
        "scene.png": plots.scene_png(s, g, result.sensors, result.echoes.point),
        "raw.png": plots.map_png(s, g, result.raw, f"{s.name}: accumulated loci (raw)"),
        "filtered.png": plots.map_png(s, g, result.filtered,
                                      f"{s.name}: low-pass filtered (eq. 2.4)"),
        "thin.png": plots.map_png(s, g, result.thin, f"{s.name}: thinned ({s.post.thinning})",
                                  binary=True),
        "profile.png": plots.profile_png(s, g, result.thin, f"{s.name}: profile, {summary}",
                                         result.profile, result.sensors),
    }


def _cm(value) -> str:
    return "n/a" if value is None else f"{value * 100:.2f} cm"


def write_outputs(result: RunResult, out: str | os.PathLike[str]) -> list[Path]:
    """Write every output of ``result`` into folder ``out``; returns the paths written.

    A new folder is filled under a temporary name and renamed into place; in an existing
    folder each file is replaced atomically.
    """
    files = render(result)
    out = Path(out)
    if not out.exists():
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.", dir=out.parent))
        try:
            for name, data in files.items():
                (tmp / name).write_bytes(data)
            os.replace(tmp, out)
        except BaseException:
            shutil.rmtree(tmp, ignore_errors=True)
            raise
    else:
        for name, data in files.items():
            write_atomic(out / name, data)
    return [out / name for name in files]
