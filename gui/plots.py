"""The plots dock: the A-scan of a chosen pair, RMS against distance and against noise
(sweeps run in a worker with progress), and run time against error for the benchmark
settings (``clsonar bench``: the thesis' methods and ours)."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Signal
from PySide6.QtWidgets import (
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QProgressBar,
    QPushButton,
    QSpinBox,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from .. import opencl, pipeline, signals
from ..outputs import headline_error
from ..scene import Scene
from ..tools import bench, variants
from .editor import Document
from .worker import Job

#: Where ``clsonar bench`` keeps its committed report, next to the package in a checkout.
BENCH_JSON = Path(__file__).resolve().parents[1] / "docs" / "bench" / "bench.json"
SETTING_PENS = {"thesis": pg.mkBrush(220, 120, 30), "best": pg.mkBrush(30, 100, 220)}


def error_m(result: pipeline.RunResult) -> float | None:
    """The run's error in metres: RMS of eq. 2.6 where it applies, else the accuracy RMS
    (:func:`clsonar.outputs.headline_error`)."""
    _, value = headline_error(result.metrics)
    return None if value is None else float(value)


def detections(result: pipeline.RunResult) -> signals.Detections:
    """The run's detections (``RunResult.detections`` is typed ``object``)."""
    d = result.detections
    assert isinstance(d, signals.Detections)
    return d


def numbers(text: str) -> list[float]:
    """``"1, 2, 4"`` → ``[1.0, 2.0, 4.0]`` (ValueError names the bad item)."""
    out = []
    for item in text.replace(";", ",").split(","):
        item = item.strip()
        if item:
            try:
                out.append(float(item))
            except ValueError:
                raise ValueError(f"not a number: {item!r}") from None
    if not out:
        raise ValueError("no values")
    return out


def scene_distance(scene: Scene) -> float | None:
    """The distance a thesis scene's name gives (``plane-2m`` → 2.0), else None."""
    m = re.search(r"-(\d+(?:\.\d+)?)m$", scene.name)
    return float(m.group(1)) if m else None


def sweep_distance(scene: Scene, d0: float, distances: list[float], context,
                   progress: pipeline.Progress) -> list[tuple[float, float | None]]:
    """``(distance, error)`` of the scene's arrays moved to each distance
    (:func:`clsonar.tools.variants.at_distance`; thesis Figs 3.5, 3.19)."""
    out = []
    for i, d in enumerate(distances):
        progress(f"{d:g} m", i + 1, len(distances))
        out.append((d, error_m(pipeline.run(variants.at_distance(scene, d0, d),
                                            context=context))))
    return out


def sweep_noise(scene: Scene, levels: list[float], context, progress: pipeline.Progress
                ) -> list[tuple[float, float | None]]:
    """``(noise σ, error)`` of the scene at each noise level (thesis Figs 3.6, 3.20)."""
    out = []
    for i, sd in enumerate(levels):
        progress(f"noise {sd:g}", i + 1, len(levels))
        out.append((sd, error_m(pipeline.run(variants.with_seed(scene, 0, sd),
                                             context=context))))
    return out


def bench_rows(path: Path) -> list[dict[str, Any]]:
    """The pipeline rows of a ``clsonar bench`` report (``bench.json``)."""
    return json.loads(Path(path).read_text())["pipeline"]


class Shell(Protocol):
    """What the plots need of the main window: the edited scene and the OpenCL device."""

    doc: Document
    device: str | None


class PlotsPanel(QWidget):
    """Tabs of plots; ``message(str)`` reports problems, sweeps report progress."""

    message = Signal(str)
    sweepFinished = Signal(str, object)  # kind, [(x, error)]

    def __init__(self, main: Shell) -> None:
        super().__init__()
        self.main = main  # the scene and the device come from the main window
        self.result: pipeline.RunResult | None = None
        self.job: Job | None = None
        self.sweep_plots: dict[str, pg.PlotWidget] = {}  # by kind: distance, noise
        self.tabs = QTabWidget()
        self.tabs.addTab(self._ascan_tab(), "A-scan")
        self.tabs.addTab(self._sweep_tab("distance"), "RMS vs distance")
        self.tabs.addTab(self._sweep_tab("noise"), "RMS vs noise")
        self.tabs.addTab(self._bench_tab(), "time vs error")
        self.progress = QProgressBar()
        self.progress.setVisible(False)
        self.cancel_button = QPushButton("Cancel sweep")
        self.cancel_button.setVisible(False)
        self.cancel_button.clicked.connect(self.cancel)
        row = QHBoxLayout()
        row.addWidget(self.progress, 1)
        row.addWidget(self.cancel_button)
        layout = QVBoxLayout(self)
        layout.addWidget(self.tabs, 1)
        layout.addLayout(row)
        self.load_bench(BENCH_JSON)

    def views(self) -> dict[str, QWidget]:
        return {"a-scan": self.ascan, "rms-distance": self.sweep_plots["distance"],
                "rms-noise": self.sweep_plots["noise"], "time-error": self.bench_plot}

    # ------------------------------------------------------------------ A-scan
    def _ascan_tab(self) -> QWidget:
        w = QWidget()
        self.tx, self.rx = QSpinBox(), QSpinBox()
        show = QPushButton("Show")
        show.clicked.connect(self.show_ascan)
        row = QHBoxLayout()
        for label, box in (("tx", self.tx), ("rx", self.rx)):
            row.addWidget(QLabel(label))
            row.addWidget(box)
        row.addWidget(show)
        row.addStretch(1)
        self.ascan = pg.PlotWidget()
        self.ascan.setLabel("bottom", "t", units="s")
        self.ascan.setLabel("left", "s (units)")
        self.ascan.addLegend()
        v = QVBoxLayout(w)
        v.addLayout(row)
        v.addWidget(self.ascan, 1)
        return w

    def set_result(self, result: pipeline.RunResult) -> None:
        self.result = result
        n = max(0, len(result.sensors) - 1)
        self.tx.setMaximum(n)
        self.rx.setMaximum(n)
        d = detections(result)
        if len(d):
            self.tx.setValue(int(d.tx[0]))
            self.rx.setValue(int(d.rx[0]))
        self.show_ascan()

    def show_ascan(self) -> None:
        """Plot pair (tx, rx): the received signal (pulses of eq. 2.3 plus noise), the
        noise band ±σ, the threshold, the true echo arrivals and the detected times of flight."""
        r = self.result
        self.ascan.clear()
        if r is None or not len(r.sensors):
            return
        tx, rx = self.tx.value(), self.rx.value()
        if r.sensors.groups[tx] != r.sensors.groups[rx]:
            self.message.emit(f"pair ({tx}, {rx}) does not fire: different groups")
            return
        t, s = signals.a_scan(r.scene, r.sensors, r.echoes, tx, rx)
        self.ascan.plot(t, s, pen=pg.mkPen((90, 90, 90)), name="signal")
        sd, thr = r.scene.signal.noise_std, r.scene.signal.threshold
        if sd > 0:
            for y in (-sd, sd):
                self.ascan.addItem(pg.InfiniteLine(y, angle=0, pen=pg.mkPen((30, 160, 60),
                                                                           style=pg.QtCore.Qt.PenStyle.DotLine)))
        self.ascan.plot([t[0], t[-1]], [thr, thr], pen=pg.mkPen((220, 30, 30)),
                        name=f"threshold {thr:g}")
        pair = (r.echoes.tx == tx) & (r.echoes.rx == rx)
        for tof in r.echoes.tof_s[pair]:
            self.ascan.addItem(pg.InfiniteLine(tof, pen=pg.mkPen((30, 100, 220),
                                                                 style=pg.QtCore.Qt.PenStyle.DashLine)))
        d = detections(r)
        tofs = d.tof_s[(d.tx == tx) & (d.rx == rx)]
        self.ascan.plot(tofs, np.full(len(tofs), thr), pen=None, symbol="t", symbolSize=12,
                        symbolBrush=(220, 30, 30), name="detected time of flight")
        times = np.concatenate([r.echoes.tof_s[pair], tofs])
        if len(times):
            self.ascan.setXRange(max(0.0, times.min() - 1e-3), times.max() + 2e-3)
        self.ascan.setTitle(f"pair ({tx}, {rx}): {int(pair.sum())} echoes (dashed), "
                            f"{len(tofs)} detections")

    # ------------------------------------------------------------------ sweeps
    def _sweep_tab(self, kind: str) -> QWidget:
        w = QWidget()
        form = QFormLayout()
        values = QLineEdit("1, 2, 4, 6, 8" if kind == "distance" else "0, 0.2, 0.4, 0.8, 1.2")
        form.addRow("distances (m)" if kind == "distance" else "noise σ (units)", values)
        if kind == "distance":
            self.d0 = QDoubleSpinBox(decimals=2, minimum=0.0, maximum=1000.0, value=2.0)
            form.addRow("scene's own distance (m)", self.d0)
        go = QPushButton("Run sweep")
        go.clicked.connect(lambda: self.sweep(kind, numbers(values.text())))
        plot = pg.PlotWidget()
        plot.setLabel("bottom", "distance (m)" if kind == "distance" else "noise σ")
        plot.setLabel("left", "RMS error (eq. 2.6)", units="m")
        self.sweep_plots[kind] = plot
        v = QVBoxLayout(w)
        v.addLayout(form)
        v.addWidget(go)
        v.addWidget(plot, 1)
        return w

    @property
    def busy(self) -> bool:
        return self.job is not None and self.job.isRunning()

    def sweep(self, kind: str, values: list[float]) -> bool:
        """Run the sweep ``kind`` (``distance`` | ``noise``) over ``values`` in a worker."""
        if self.busy:
            return False
        scene, spec = self.main.doc.scene, self.main.device
        if kind == "distance":
            d0 = scene_distance(scene) or self.d0.value()
            self.d0.setValue(d0)
            fn = lambda p: sweep_distance(scene, d0, values, opencl.get_context(spec), p)  # noqa: E731
        else:
            fn = lambda p: sweep_noise(scene, values, opencl.get_context(spec), p)  # noqa: E731
        return self._start(kind, fn)

    def run_bench(self) -> bool:
        """Time the pipeline on the scene under the thesis' settings and ours (bench)."""
        if self.busy:
            return False
        scene, spec = self.main.doc.scene, self.main.device

        def fn(progress: pipeline.Progress) -> list[dict[str, Any]]:
            rows = []
            for i, (name, preset) in enumerate(bench.SETTINGS):
                progress(name, i + 1, len(bench.SETTINGS))
                rows.append(bench.bench_pipeline(scene, name, preset,
                                                 opencl.get_context(spec), 1).__dict__)
            return rows
        return self._start("bench", fn)

    def _start(self, kind: str, fn) -> bool:
        job = Job(fn, kind, self)
        job.progressed.connect(self._progress)
        job.succeeded.connect(lambda out, j=job: self._done(j, out))
        job.failed.connect(lambda m, j=job: self._ended(j, f"{kind} failed: {m}"))
        job.cancelled.connect(lambda j=job: self._ended(j, f"{kind} cancelled"))
        self.job = job
        self.progress.setVisible(True)
        self.cancel_button.setVisible(True)
        self.progress.setValue(0)
        job.start()
        return True

    def cancel(self) -> None:
        if self.job is not None and self.job.isRunning():
            self.job.cancel()

    def _progress(self, what: str, i: int, n: int) -> None:
        self.progress.setRange(0, n)
        self.progress.setValue(i - 1)
        self.progress.setFormat(f"{what} ({i}/{n})")

    def _ended(self, job: Job, text: str | None) -> None:
        job.wait()
        self.progress.setVisible(False)
        self.cancel_button.setVisible(False)
        if self.job is job:
            self.job = None
        if text:
            self.message.emit(text)

    def _done(self, job: Job, out) -> None:
        self._ended(job, None)
        if job.name == "bench":
            self.show_bench(out, f"{self.main.doc.scene.name} (this device)", clear=False)
        else:
            self.show_sweep(job.name, out)
        self.sweepFinished.emit(job.name, out)

    def show_sweep(self, kind: str, points: list[tuple[float, float | None]]) -> None:
        plot = self.sweep_plots[kind]
        plot.clear()
        xy = np.array([(x, e) for x, e in points if e is not None], dtype=float).reshape(-1, 2)
        plot.plot(xy[:, 0], xy[:, 1], pen=pg.mkPen((30, 100, 220), width=2), symbol="o")
        missing = [x for x, e in points if e is None]
        plot.setTitle(f"{self.main.doc.scene.name}" +
                      (f" (no error at {', '.join(f'{x:g}' for x in missing)})" if missing
                       else ""))

    # ------------------------------------------------------------------ bench
    def _bench_tab(self) -> QWidget:
        w = QWidget()
        row = QHBoxLayout()
        load = QPushButton("Load bench.json…")
        load.clicked.connect(self._load_dialog)
        here = QPushButton("Time this scene (thesis and ours)")
        here.clicked.connect(self.run_bench)
        row.addWidget(load)
        row.addWidget(here)
        row.addStretch(1)
        self.bench_plot = pg.PlotWidget()
        self.bench_plot.setLogMode(x=True, y=True)
        self.bench_plot.setLabel("bottom", "run time (s)")
        self.bench_plot.setLabel("left", "error (m)")
        self.bench_plot.addLegend()
        v = QVBoxLayout(w)
        v.addLayout(row)
        v.addWidget(self.bench_plot, 1)
        return w

    def _load_dialog(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "bench.json", "", "JSON (*.json)")
        if path:
            self.load_bench(Path(path))

    def load_bench(self, path: Path) -> None:
        if not Path(path).exists():
            return
        try:
            rows = bench_rows(path)
        except (OSError, ValueError, KeyError) as e:
            self.message.emit(f"{path}: not a clsonar bench report ({e})")
            return
        self.bench_plot.clear()
        self.show_bench(rows, Path(path).name, clear=True)

    def show_bench(self, rows: list[dict[str, Any]], source: str, clear: bool) -> None:
        """Run time against error, one point per (scene, settings); the error is the RMS of
        eq. 2.6 where it applies, else the accuracy RMS."""
        for setting, brush in SETTING_PENS.items():
            pts = [(r["total_s"], r["rms_m"] if r["rms_m"] is not None else r["accuracy_m"],
                    r["scene"]) for r in rows if r["settings"] == setting]
            pts = [p for p in pts if p[1] is not None and p[1] > 0]
            if not pts:
                continue
            xy = np.array([p[:2] for p in pts], dtype=float)
            self.bench_plot.plot(xy[:, 0], xy[:, 1], pen=None, symbol="o" if clear else "s",
                                 symbolBrush=brush, symbolSize=9 if clear else 13,
                                 name=f"{setting} ({source})")
            for (x, y, name) in pts:
                label = pg.TextItem(name, color=(80, 80, 80), anchor=(0, 1))
                label.setPos(np.log10(x), np.log10(y))
                self.bench_plot.addItem(label)
