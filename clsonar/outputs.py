"""The files ``clsonar run SCENE --out DIR`` writes (docs/design.md, "Command line — a
contract").

``report.json`` (scene, device, settings, counts, per-stage seconds, metrics),
``stages.npz`` (``raw``, ``filtered``, ``thin`` ``[iy, ix]`` with ``extent`` and ``cell``),
``profile.csv`` (``x,y``), ``echoes.csv`` (``tx,rx,tof_s,amplitude,kind,order``) and one PNG
per stage with the true geometry drawn over it (``--png``,
:data:`~clsonar.files.PNG_CHOICES`). Every file is built in memory first, then the whole set
is written as one folder (:func:`clsonar.files.write_folder`): a run's outputs appear whole
or not at all, and two runs writing the same DIR leave one run's outputs, never a mix.

Every PNG is drawn straight from the arrays (:mod:`clsonar.pictures`, no matplotlib).
``clsonar run`` has scene.png and profile.png drawn by a worker process on a free core
while the pipeline runs (:func:`clsonar.drawing.run_worker`): the same bytes.
matplotlib (``clsonar[plots]``) draws only the tools' figures (:func:`require_plots`).
"""

from __future__ import annotations

import importlib.util
import io
import json
import os
import threading
import zipfile
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from . import drawing
from .drawing import Job, PlotWorker, draw
from .errors import ClsonarError
from .files import write_folder
from .pipeline import RunResult, StageCache, apply_preset
from .pipeline import metrics as run_metrics  # the module whose lit_truth the run scores by

if TYPE_CHECKING:  # the pipeline's own imports of them
    from .pipeline import EchoTable, Geometry, Scene, SensorArray

#: The data files of a run, and every picture it may draw (:func:`stage_pngs`).
DATA_NAMES = ("report.json", "stages.npz", "profile.csv", "echoes.csv")
MAP_PNG_NAMES = ("raw.png", "filtered.png", "thin.png")  # the maps' (:func:`map_pngs`)
PNG_NAMES = (*MAP_PNG_NAMES, "scene.png", "profile.png")
#: Every file ``clsonar run`` may write: a folder holding only these is a run's outputs,
#: replaced whole by the next run's.
OUTPUT_NAMES = frozenset(DATA_NAMES + PNG_NAMES)

#: How to install what the tools' figures need.
PLOTS_INSTALL = "pip install 'clsonar[plots]'"


def plots_available() -> bool:
    """Whether matplotlib, which the tools' figures need, is installed."""
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
        text = f"{value:g}" if isinstance(value, float) else "per pose" if value is None else value
        values.append(f"{key} {text}")
    kinds = " / ".join(sorted(set(auto.values())))
    return f"settings chosen for {kinds}: " + ", ".join(values)


#: Deflate's level for stages.npz: its fastest. ``np.savez_compressed`` (level 6) takes
#: 80–110 ms for the bundled room's maps (13 MB, mostly zeros), level 1 25 ms, for a file
#: of 99 kB instead of 40 kB; ``np.load`` reads either.
NPZ_LEVEL = 1


def stages_npz(scene: Scene, raw: np.ndarray, filtered: np.ndarray, thin: np.ndarray
               ) -> bytes:
    """``stages.npz``: the three maps with ``scene``'s extent and cell, each an ``.npy``
    deflated at :data:`NPZ_LEVEL` in one zip, as ``np.savez_compressed`` writes them."""
    arrays = {"raw": raw, "filtered": filtered, "thin": thin,
              "extent": np.asarray(scene.extent), "cell": np.asarray(scene.cell)}
    npz = io.BytesIO()
    with zipfile.ZipFile(npz, "w", zipfile.ZIP_DEFLATED, compresslevel=NPZ_LEVEL) as z:
        for name, array in arrays.items():
            with z.open(f"{name}.npy", "w", force_zip64=True) as f:
                np.lib.format.write_array(f, np.asanyarray(array), allow_pickle=False)
    return npz.getvalue()


def data_files(result: RunResult, extra: Mapping[str, object] | None = None,
               early: Mapping[str, bytes] | None = None) -> dict[str, bytes]:
    """Every output file of ``result`` but the PNGs, as bytes, by file name (``extra``:
    more keys of report.json; ``early``: stages.npz already built, :class:`EarlyFiles`)."""
    early = early or {}
    npz = early.get("stages.npz") or stages_npz(result.scene, result.raw, result.filtered,
                                                result.thin)
    echoes = io.StringIO()
    result.echoes.write_csv(echoes)
    return {
        "report.json": (json.dumps({**result.report(), **(extra or {})}, indent=2,
                                   default=_json_default) + "\n").encode(),
        "stages.npz": npz,
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
    :mod:`clsonar.pictures` function and its arguments), drawn in process or by a worker."""
    s, g = result.scene, result.geometry
    return {"scene.png": scene_job(result.asked or s, g, result.sensors, result.echoes),
            "profile.png": ("profile_png", (s, g, result.thin, profile_title(result),
                                            result.profile, result.sensors))}


def profile_png(result: RunResult) -> bytes:
    """``profile.png``: the thinned map with the profile, its corners and edges, titled
    with the run's error (:func:`error_summary`)."""
    return draw({"profile.png": plot_jobs(result)["profile.png"]})["profile.png"]


class EarlyPlots(StageCache):
    """A stage cache that keeps nothing (every stage is computed, the same results) and,
    as soon as the pipeline puts the echoes, sends ``worker`` what needs only them and the
    placement: scene.png where it draws, else the truth the metrics score against
    (``metrics.lit_truth``, which reads the echoes and the cell, no setting the pipeline
    chooses; :meth:`get` answers the pipeline's ask for it with the worker's, or None:
    computed there). The worker does it while the later stages run. ``scene``: the scene as
    asked for (preset applied), which the pipeline's ``RunResult.asked`` equals."""

    def __init__(self, worker: PlotWorker, scene: Scene) -> None:
        super().__init__()
        self.worker, self.scene = worker, scene
        self._placed: tuple[Geometry, SensorArray] | None = None
        self._truth = False  # sent to the worker, not yet asked for

    def get(self, stage: str, key: str) -> object | None:
        if stage != "truth" or not self._truth:
            return None
        self._truth = False
        return self.worker.value()

    def put(self, stage: str, key: str, value: object) -> None:
        found: Any = value[0] if isinstance(value, tuple) and value else None
        if stage == "sensors" and isinstance(found, tuple) and len(found) == 2:
            self._placed = found
        elif stage == "echoes" and hasattr(found, "point") and self._placed:
            if self.worker.plots:
                self.worker.submit({"scene.png": scene_job(self.scene, *self._placed, found)})
            else:
                self._truth = self.worker.call(run_metrics.lit_truth, self.scene,
                                               *self._placed, found)


def early_plots(worker: PlotWorker | None, scene: Scene, preset: str | None = None
                ) -> EarlyPlots | None:
    """The ``cache`` of a run of ``scene`` with ``preset`` whose ``worker`` draws
    scene.png, or scores the truth, as soon as it can (:class:`EarlyPlots`; None without a
    worker)."""
    return None if worker is None else EarlyPlots(worker, apply_preset(scene, preset))


def map_pngs(result: RunResult, png: str = "all",
             built: Mapping[str, bytes] | None = None) -> dict[str, bytes]:
    """raw.png, filtered.png and thin.png of ``result`` unless ``png`` is ``none``: those
    in ``built`` (:meth:`EarlyFiles.files`, of the same ``png``) where it has them."""
    if built and "raw.png" in built:
        return {name: built[name] for name in MAP_PNG_NAMES}
    return _map_pngs(result.scene, result.geometry, result.raw, result.filtered,
                     result.thin, png)


def _map_pngs(s: Scene, g: Geometry, raw: np.ndarray, filtered: np.ndarray,
              thin: np.ndarray, png: str) -> dict[str, bytes]:
    if png == "none":  # (nor are the pictures imported)
        return {}
    from . import pictures

    return {"raw.png": pictures.map_picture(s, g, raw),
            "filtered.png": pictures.map_picture(s, g, filtered),
            "thin.png": pictures.map_picture(s, g, thin, binary=True)}


class EarlyFiles:
    """stages.npz and the map pictures ``png`` asks for, built in a thread from the moment
    the pipeline has its maps (:meth:`maps_done`, ``pipeline.run``'s) while this one
    computes the profile and the metrics (issue 16): zlib, most of their time, and NumPy's
    larger operations release the GIL, so a free core takes that work. The thread calls
    the functions :func:`data_files` and :func:`map_pngs` call, on the same arrays: the
    same bytes. :meth:`files` waits for it; its files are used only for the run whose
    maps it was told (:meth:`files` answers {} otherwise, or if the thread failed: the
    files are then built in order). Nothing is written here: the folder is still written
    whole by :func:`write_outputs`, or not at all. A context manager: a run that fails
    waits for the thread, so none outlives the command.

    Not beside a ``worker`` that draws the plots (:func:`clsonar.drawing.run_worker`):
    there the files are built after the run, while that worker draws profile.png, which
    keeps both cores busy; during the run the thread would take a core from this process
    or the worker, and one would idle at the end."""

    def __init__(self, png: str = "none", worker: PlotWorker | None = None) -> None:
        self.png = png
        self.off = worker is not None and worker.plots
        self._thread: threading.Thread | None = None
        self._told: tuple[Scene, Geometry, np.ndarray, np.ndarray, np.ndarray] | None = None
        self._built: dict[str, bytes] = {}

    def __enter__(self) -> EarlyFiles:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._thread is not None:
            self._thread.join()

    def maps_done(self, scene: Scene, geometry: Geometry, raw: np.ndarray,
                  filtered: np.ndarray, thin: np.ndarray) -> None:
        """Start building the files of these maps (once a run: a second call is ignored)."""
        if self._thread is not None or self.off:
            return
        self._told = (scene, geometry, raw, filtered, thin)
        self._thread = threading.Thread(target=self._build, name="clsonar-files",
                                        daemon=True)
        self._thread.start()

    def _build(self) -> None:
        assert self._told is not None
        scene, geometry, raw, filtered, thin = self._told
        try:
            built = {"stages.npz": stages_npz(scene, raw, filtered, thin)}
            built.update(_map_pngs(scene, geometry, raw, filtered, thin, self.png))
        except Exception:  # built again in order, where it raises as before
            return
        self._built = built

    def files(self, result: RunResult) -> dict[str, bytes]:
        """The files built for ``result`` (waiting for the thread); {} where it was not
        told ``result``'s own maps, or failed."""
        if self._thread is None:
            return {}
        self._thread.join()
        told = (result.scene, result.geometry, result.raw, result.filtered, result.thin)
        if self._told is None or any(a is not b for a, b in zip(self._told, told, strict=True)):
            return {}
        return dict(self._built)


def stage_pngs(result: RunResult, png: str = "all") -> dict[str, bytes]:
    """The PNGs of ``result`` that ``png`` (:data:`~clsonar.files.PNG_CHOICES`) asks
    for, by file name."""
    out = map_pngs(result, png)
    if png == "all":
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
                  worker: PlotWorker | None = None,
                  early: EarlyFiles | None = None) -> list[Path]:
    """Write every output of ``result`` into folder ``out``, with the PNGs ``png`` asks
    for (:func:`stage_pngs`) and ``extra`` keys in report.json; returns the paths
    written. A ``worker`` (:func:`clsonar.drawing.run_worker`) draws scene.png and profile.png while
    this process builds the other files (a map above :data:`~clsonar.drawing.MAX_CELLS`
    is drawn here); where it fails they are drawn here, the same bytes. ``early``: the
    files :class:`EarlyFiles` built during the run (the same bytes as building them here).

    The folder is written whole or not at all (:func:`clsonar.files.write_folder`): a new
    one, or one holding only an earlier run's outputs, is replaced in one step; in a folder
    with other files too, the outputs are replaced one by one. A folder that cannot be
    written (or a full disk) is one :class:`~clsonar.errors.WriteError` line; nothing
    half-written is left.
    """
    path = check_out(out)
    jobs = plot_jobs(result) if png == "all" else {}
    worker = worker if worker is not None and worker.plots else None
    if worker is not None:
        worker.submit({name: job for name, job in jobs.items()
                       if drawing.cells({name: job}) <= drawing.MAX_CELLS})
    built = early.files(result) if early is not None and early.png == png else {}
    files = data_files(result, extra, built)
    files.update(map_pngs(result, png, built))
    if jobs:
        drawn = (worker.collect() if worker is not None else None) or {}
        drawn.update(draw({name: job for name, job in jobs.items() if name not in drawn}))
        files.update({name: drawn[name] for name in jobs})
    write_folder(path, files, OUTPUT_NAMES)
    return [path / name for name in files]
