"""The files ``clsonar run SCENE --out DIR`` writes (docs/design.md, "Command line — a
contract").

``report.json`` (scene, device, settings, counts, per-stage seconds, metrics),
``stages.npz`` (``raw``, ``filtered``, ``thin`` ``[iy, ix]`` with ``extent`` and ``cell``),
``profile.csv`` (``x,y``), ``echoes.csv`` (``tx,rx,tof_s,amplitude,kind,order``) and one PNG
per stage with the true geometry drawn over it (``--png``,
:data:`~clsonar.files.PNG_CHOICES`). Every file is built in memory first, then the whole set
is written as one folder (:func:`clsonar.files.write_folder`): a run's outputs appear whole
or not at all, and two runs writing the same DIR leave one run's outputs, never a mix.

The map stages' PNGs are drawn straight from the arrays (:mod:`clsonar.pictures`); the
scene and profile plots need matplotlib (``clsonar[plots]``): :mod:`clsonar.plots` is
imported only when they are drawn, so every other output is written without it
(:func:`plots_available`). ``clsonar run`` has them drawn by a worker process on a free
core while the pipeline runs (:func:`plot_worker`, :mod:`clsonar.drawing`): the same
bytes.
"""

from __future__ import annotations

import importlib.util
import io
import json
import os
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import drawing
from .drawing import Job, PlotWorker, draw
from .errors import ClsonarError
from .files import write_folder
from .pipeline import RunResult, StageCache, apply_preset

if TYPE_CHECKING:  # the pipeline's own imports of them
    from .pipeline import EchoTable, Geometry, Scene, SensorArray

#: The data files of a run, and every picture it may draw (:func:`stage_pngs`).
DATA_NAMES = ("report.json", "stages.npz", "profile.csv", "echoes.csv")
PNG_NAMES = ("raw.png", "filtered.png", "thin.png", "scene.png", "profile.png")
#: Every file ``clsonar run`` may write: a folder holding only these is a run's outputs,
#: replaced whole by the next run's.
OUTPUT_NAMES = frozenset(DATA_NAMES + PNG_NAMES)

#: How to install what the pictures need.
PLOTS_INSTALL = "pip install 'clsonar[plots]'"
#: ``clsonar run``'s warning where scene.png and profile.png cannot be drawn.
PLOTS_MISSING = ("matplotlib is not installed: scene.png and profile.png not written "
                 f"({PLOTS_INSTALL})")


def plots_available() -> bool:
    """Whether matplotlib, which every PNG needs, is installed."""
    return importlib.util.find_spec("matplotlib") is not None


def require_plots(what: str) -> None:
    """Refuse, before any work, a command whose ``what`` needs matplotlib when it is not
    installed (:class:`~clsonar.errors.ClsonarError`, one line)."""
    if not plots_available():
        raise ClsonarError(f"{what} needs matplotlib: {PLOTS_INSTALL}")


def metric(metrics: Mapping[str, object], path: str) -> Any:
    """The value at ``path`` in a run's metrics (``"rms_m"``, ``"accuracy_m.rms"``,
    ``"completeness.2cm"``); None where the run has no such metric."""
    value: Any = metrics
    for key in path.split("."):
        value = value.get(key) if isinstance(value, Mapping) else None
    return value


def headline_error(metrics: Mapping[str, object]) -> tuple[str, float | None]:
    """The run's error in one number, with its name: the RMS of eq. 2.6 where it applies
    (one wall), else the accuracy RMS (metres; None: no profile)."""
    rms = metric(metrics, "rms_m")
    if rms is not None:
        return "RMS (eq. 2.6)", rms
    return "accuracy RMS", metric(metrics, "accuracy_m.rms")


def error_summary(metrics: Mapping[str, object]) -> str:
    """``RMS (eq. 2.6) 0.42 cm`` (or the accuracy RMS, or ``n/a``): :func:`headline_error`."""
    name, value = headline_error(metrics)
    return f"{name} {'n/a' if value is None else f'{value * 100:.2f} cm'}"


def _json_default(value: object) -> object:
    if isinstance(value, np.generic):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def profile_csv(points: np.ndarray) -> str:
    """``profile.csv``: header ``x,y``, one estimated surface point (metres) a line (each
    as a Python float, the same text as the float64 gives, a third of the time)."""
    return "x,y\n" + "".join(f"{x:.6f},{y:.6f}\n" for x, y in np.asarray(points).tolist())


def chosen_settings(result: RunResult) -> str:
    """``settings chosen for ring poses inside a closed room: post.fit walls, …`` (empty
    when the file or a preset gave them all): ``clsonar run``'s summary line of them."""
    auto = {k: why.removeprefix("auto: ") for k, why in result.settings_why.items()
            if why.startswith("auto: ")}
    if not auto:
        return ""
    values = []
    for key in auto:
        value: object = result.scene
        for part in key.split("."):
            value = getattr(value, part)
        values.append(f"{key} {value:g}" if isinstance(value, float) else f"{key} {value}")
    kinds = " / ".join(sorted(set(auto.values())))
    return f"settings chosen for {kinds}: " + ", ".join(values)


def data_files(result: RunResult, extra: Mapping[str, object] | None = None
               ) -> dict[str, bytes]:
    """Every output file of ``result`` but the PNGs, as bytes, by file name (``extra``:
    more keys of report.json)."""
    s = result.scene
    npz = io.BytesIO()
    np.savez_compressed(npz, raw=result.raw, filtered=result.filtered, thin=result.thin,
                        extent=np.asarray(s.extent), cell=np.asarray(s.cell))
    echoes = io.StringIO()
    result.echoes.write_csv(echoes)
    return {
        "report.json": (json.dumps({**result.report(), **(extra or {})}, indent=2,
                                   default=_json_default) + "\n").encode(),
        "stages.npz": npz.getvalue(),
        "profile.csv": profile_csv(result.profile.points).encode(),
        "echoes.csv": echoes.getvalue().encode(),
    }


def profile_title(result: RunResult) -> str:
    """profile.png's title: the scene and the run's error (:func:`error_summary`)."""
    return f"{result.scene.name}: profile, {error_summary(result.metrics)}"


def scene_job(scene: Scene, geometry: Geometry, sensors: SensorArray,
              echoes: EchoTable) -> Job:
    """scene.png as a :data:`~clsonar.drawing.Job`: ``scene`` as asked for (it draws its
    name, extent and kind of placement, which no setting the pipeline chooses changes)."""
    return ("scene_png", (scene, geometry, sensors, echoes.point))


def plot_jobs(result: RunResult) -> dict[str, Job]:
    """scene.png and profile.png of ``result`` as :data:`~clsonar.drawing.Job` s (a
    :mod:`clsonar.plots` function and its arguments), drawn in process or by a worker."""
    s, g = result.scene, result.geometry
    return {"scene.png": scene_job(result.asked or s, g, result.sensors, result.echoes),
            "profile.png": ("profile_png", (s, g, result.thin, profile_title(result),
                                            result.profile, result.sensors))}


def profile_png(result: RunResult) -> bytes:
    """``profile.png``: the thinned map with the profile, its corners and edges, titled
    with the run's error (:func:`error_summary`)."""
    return draw({"profile.png": plot_jobs(result)["profile.png"]})["profile.png"]


def plot_worker(png: str, *, if_busy: bool = False) -> PlotWorker | None:
    """A worker drawing scene.png and profile.png on another core (:mod:`clsonar.drawing`)
    where ``png`` asks for them and one can help (a core free now, unless ``if_busy``);
    start it before the run's OpenCL context exists, close it on every exit path (a
    context manager)."""
    return drawing.start(if_busy=if_busy) if png == "all" else None


class EarlyPlots(StageCache):
    """A stage cache that keeps nothing (every stage is computed, the same results) and
    sends scene.png to ``worker`` as soon as the pipeline puts the echoes it draws: the
    worker draws it while the later stages run. ``scene``: the scene as asked for (preset
    applied), which the pipeline's ``RunResult.asked`` equals."""

    def __init__(self, worker: PlotWorker, scene: Scene) -> None:
        super().__init__()
        self.worker, self.scene = worker, scene
        self._placed: tuple[Geometry, SensorArray] | None = None

    def get(self, stage: str, key: str) -> object | None:
        return None

    def put(self, stage: str, key: str, value: object) -> None:
        found: Any = value[0] if isinstance(value, tuple) and value else None
        if stage == "sensors" and isinstance(found, tuple) and len(found) == 2:
            self._placed = found
        elif stage == "echoes" and hasattr(found, "point") and self._placed:
            self.worker.submit({"scene.png": scene_job(self.scene, *self._placed, found)})


def early_plots(worker: PlotWorker | None, scene: Scene, preset: str | None = None
                ) -> EarlyPlots | None:
    """The ``cache`` of a run of ``scene`` with ``preset`` whose ``worker`` draws
    scene.png as soon as it can (:class:`EarlyPlots`; None without a worker)."""
    return None if worker is None else EarlyPlots(worker, apply_preset(scene, preset))


def map_pngs(result: RunResult, png: str = "all") -> dict[str, bytes]:
    """raw.png, filtered.png and thin.png of ``result`` unless ``png`` is ``none``."""
    from . import pictures

    if png == "none":
        return {}
    s, g = result.scene, result.geometry
    return {"raw.png": pictures.map_picture(s, g, result.raw),
            "filtered.png": pictures.map_picture(s, g, result.filtered),
            "thin.png": pictures.map_picture(s, g, result.thin, binary=True)}


def stage_pngs(result: RunResult, png: str = "all") -> dict[str, bytes]:
    """The PNGs of ``result`` that ``png`` (:data:`~clsonar.files.PNG_CHOICES`) asks
    for, by file name; scene.png and profile.png only where matplotlib is installed."""
    out = map_pngs(result, png)
    if png == "all" and plots_available():
        out.update(draw(plot_jobs(result)))
    return out


def check_out(out: str | os.PathLike[str]) -> Path:
    """``out`` as a folder the outputs can be written to, checked before any work: an
    existing folder we may write in, or a new one whose nearest existing parent is such a
    folder. :class:`ClsonarError` (one line) otherwise."""
    path = Path(out)
    if path.exists() and not path.is_dir():
        raise ClsonarError(f"{out}: --out is a file, not a folder")
    parent = path if path.exists() else next(p for p in path.parents if p.exists())
    if not parent.is_dir():
        raise ClsonarError(f"{out}: cannot create the folder: {parent} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise ClsonarError(f"{out}: cannot write in {parent} (permission denied)")
    return path


def write_outputs(result: RunResult, out: str | os.PathLike[str], *,
                  png: str = "all", extra: Mapping[str, object] | None = None,
                  worker: PlotWorker | None = None) -> list[Path]:
    """Write every output of ``result`` into folder ``out``, with the PNGs ``png`` asks
    for (:func:`stage_pngs`) and ``extra`` keys in report.json; returns the paths
    written. A ``worker`` (:func:`plot_worker`) draws scene.png and profile.png while
    this process builds the other files (a map above :data:`~clsonar.drawing.MAX_CELLS`
    is drawn here); where it fails they are drawn here, the same bytes.

    The folder is written whole or not at all (:func:`clsonar.files.write_folder`): a new
    one, or one holding only an earlier run's outputs, is replaced in one step; in a folder
    with other files too, the outputs are replaced one by one. A folder that cannot be
    written (or a full disk) is one :class:`~clsonar.errors.WriteError` line; nothing
    half-written is left.
    """
    path = check_out(out)
    jobs = plot_jobs(result) if png == "all" and plots_available() else {}
    if worker is not None:
        worker.submit({name: job for name, job in jobs.items()
                       if drawing.cells({name: job}) <= drawing.MAX_CELLS})
    files = data_files(result, extra)
    files.update(map_pngs(result, png))
    if jobs:
        drawn = (worker.collect() if worker is not None else None) or {}
        drawn.update(draw({name: job for name, job in jobs.items() if name not in drawn}))
        files.update({name: drawn[name] for name in jobs})
    write_folder(path, files, OUTPUT_NAMES)
    return [path / name for name in files]
