"""The map stages of a run side by side or one at a time: raw accumulation, filtered,
thinned and fitted profile (thesis §2.1.1 steps 3–5), each with the true geometry in red,
a colour bar, and a readout of the position and votes under the cursor."""

from __future__ import annotations

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QPointF, Signal
from PySide6.QtWidgets import QComboBox, QGridLayout, QHBoxLayout, QLabel, QVBoxLayout, QWidget

from ..pipeline import RunResult
from ..scene import Scene
from .views import PROFILE_PEN, map_rect, truth_paths

#: The true geometry over a map: thin and light, so the map under it stays visible.
TRUTH_OVER_MAP_PEN = pg.mkPen((220, 30, 30, 150), width=1)

#: The stage views, by key, with their titles.
STAGE_VIEWS = {"raw": "raw accumulation", "filtered": "low-pass filtered (eq. 2.4)",
               "thin": "thinned", "profile": "fitted profile"}
SIDE_BY_SIDE = "side by side"
NO_RUN = "no run yet: press Run (F5)"


def cell_at(result: RunResult, x: float, y: float) -> tuple[int, int] | None:
    """``(iy, ix)`` of the map cell holding point ``(x, y)`` (None outside the map)."""
    xmin, ymin = result.scene.extent[:2]
    ix = int(np.floor((x - xmin) / result.scene.cell))
    iy = int(np.floor((y - ymin) / result.scene.cell))
    ny, nx = result.raw.shape
    return (iy, ix) if 0 <= ix < nx and 0 <= iy < ny else None


def stage_image(result: RunResult, key: str) -> np.ndarray:
    """The ``[iy, ix]`` array a stage view shows (the profile view shows the thin map)."""
    image = {"raw": result.raw, "filtered": result.filtered, "thin": result.thin,
             "profile": result.thin}[key]
    return np.asarray(image, dtype=np.float32)


def block_max(image: np.ndarray, k: int) -> np.ndarray:
    """``image`` reduced by maxima of ``k`` × ``k`` blocks (zero-padded at the far edges),
    so that one-cell curves and single votes stay visible when a map cell is smaller than
    a screen pixel (as pictures.map_picture does)."""
    k = min(k, max(image.shape))
    if k <= 1:
        return image
    ny, nx = image.shape
    pad = np.zeros((-(-ny // k) * k, -(-nx // k) * k), dtype=image.dtype)
    pad[:ny, :nx] = image
    return pad.reshape(pad.shape[0] // k, k, pad.shape[1] // k, k).max(axis=(1, 3))


def votes_colormap() -> pg.ColorMap:
    """viridis for votes, with empty cells white: sparse maps stay readable."""
    viridis = pg.colormap.get("viridis")
    colours = viridis.getLookupTable(nPts=64, alpha=False)
    stops = np.concatenate([[0.0], np.linspace(0.01, 1.0, 64)])
    return pg.ColorMap(stops, np.concatenate([[[255, 255, 255]], colours]))


def top_level(image: np.ndarray) -> float:
    """The colour bar's top: the 99th percentile of the non-zero cells (at least 1), so
    the few cells where many votes coincide do not leave the rest of the map dark."""
    set_cells = image[image > 0]
    return max(1.0, float(np.percentile(set_cells, 99))) if set_cells.size else 1.0


class StageView(pg.GraphicsLayoutWidget):
    """One stage: the map in metres, the truth over it, a colour bar."""

    hovered = Signal(str, float, float)  # stage, x, y

    def __init__(self, key: str, parent=None) -> None:
        super().__init__(parent)
        self.key = key
        self.plot = self.addPlot(title=STAGE_VIEWS[key])
        self.plot.setAspectLocked(True)
        self.plot.setLabel("bottom", "x", units="m")
        self.plot.setLabel("left", "y", units="m")
        self.image = pg.ImageItem(axisOrder="row-major")
        self.plot.addItem(self.image)
        binary = key in ("thin", "profile")
        cmap = (pg.ColorMap([0.0, 1.0], [(255, 255, 255), (0, 0, 0)]) if binary
                else votes_colormap())
        self.bar = pg.ColorBarItem(colorMap=cmap, label="cell set" if binary else "votes",
                                   interactive=not binary, width=12)
        self.bar.setImageItem(self.image, insert_in=self.plot)
        self.truth = pg.PlotCurveItem(pen=TRUTH_OVER_MAP_PEN, connect="finite")
        self.plot.addItem(self.truth)
        self.profile = pg.PlotCurveItem(pen=PROFILE_PEN, connect="finite")
        self.vertices = pg.ScatterPlotItem(symbol="x", size=10, pen=pg.mkPen("r", width=2))
        if key == "profile":
            self.plot.addItem(self.profile)
            self.plot.addItem(self.vertices)
        self.data: np.ndarray | None = None
        self.scene_: Scene | None = None
        self.k = 0  # block size of the image on screen
        self.scene().sigMouseMoved.connect(self._moved)
        self.plot.vb.sigRangeChanged.connect(self._render)
        self.plot.vb.sigResized.connect(self._render)

    def cells_per_pixel(self, cell: float) -> float:
        """Map cells of ``cell`` metres per screen pixel at the current zoom (≥ 1: a pixel
        holds many cells)."""
        (x0, x1), _ = self.plot.vb.viewRange()
        pixels = max(1.0, float(self.plot.vb.width()))
        return (x1 - x0) / cell / pixels

    def _render(self, *_: object) -> None:
        """Show the map with blocks of as many cells as one screen pixel holds."""
        if self.data is None or self.scene_ is None or self.plot.vb.width() < 2:
            return  # hidden or not laid out yet: drawn when it gets a size
        per_pixel = self.cells_per_pixel(self.scene_.cell)
        k = min(max(self.data.shape), max(1, int(np.ceil(per_pixel - 1e-9))))
        if k == self.k:
            return
        self.k = k
        view = block_max(self.data, k)
        self.image.setImage(view, autoLevels=False)
        self.image.setRect(map_rect(self.scene_, (view.shape[0] * k, view.shape[1] * k)))
        self.bar.setLevels((0.0, top_level(view)))

    def show_result(self, result: RunResult) -> None:
        image = stage_image(result, self.key)
        self.data = image
        self.scene_ = result.scene
        self.k = 0
        self._render()
        self.truth.setData(*truth_paths(result.geometry))
        if self.key == "profile":
            curves = result.profile.curves
            if curves:
                gap = np.full((1, 2), np.nan)
                xy = np.concatenate([q for c in curves for q in (c, gap)])
                self.profile.setData(xy[:, 0], xy[:, 1])
            else:
                self.profile.setData([], [])
            v = result.profile.vertices
            self.vertices.setData(v[:, 0], v[:, 1])

    def _moved(self, pos: QPointF) -> None:
        if self.plot.sceneBoundingRect().contains(pos):
            p = self.plot.vb.mapSceneToView(pos)
            self.hovered.emit(self.key, float(p.x()), float(p.y()))


class StagesPanel(QWidget):
    """The four stage views, switchable or side by side, with the cursor readout."""

    def __init__(self, parent=None) -> None:
        super().__init__(parent)
        self.result: RunResult | None = None
        self.mode = QComboBox()
        self.mode.addItems([SIDE_BY_SIDE, *STAGE_VIEWS])
        self.mode.currentTextChanged.connect(self.set_mode)
        self.readout = QLabel(NO_RUN)
        top = QHBoxLayout()
        top.addWidget(QLabel("show:"))
        top.addWidget(self.mode)
        top.addStretch(1)
        self.views = {k: StageView(k) for k in STAGE_VIEWS}
        grid = QGridLayout()
        first = None
        for n, (_k, v) in enumerate(self.views.items()):
            grid.addWidget(v, n // 2, n % 2)
            v.hovered.connect(self._readout)
            if first is None:
                first = v.plot
            else:
                v.plot.setXLink(first)
                v.plot.setYLink(first)
        layout = QVBoxLayout(self)
        layout.addLayout(top)
        layout.addLayout(grid, 1)
        layout.addWidget(self.readout)

    def set_mode(self, mode: str) -> None:
        """Show all four views (``side by side``) or only stage ``mode``."""
        if self.mode.currentText() != mode:
            self.mode.setCurrentText(mode)
        for k, v in self.views.items():
            v.setVisible(mode in (SIDE_BY_SIDE, k))

    def show_result(self, result: RunResult) -> None:
        first = self.result is None or self.result.scene.extent != result.scene.extent
        self.result = result
        self.readout.setText("point at a map for the position and the votes under the cursor")
        for v in self.views.values():
            v.show_result(result)
        if first:
            x0, y0, x1, y1 = result.scene.extent
            self.views["raw"].plot.setRange(xRange=(x0, x1), yRange=(y0, y1))

    def readout_text(self, key: str, x: float, y: float) -> str:
        """``x, y`` in metres and the value of stage ``key`` in the cell under them."""
        r = self.result
        text = f"x = {x:.3f} m, y = {y:.3f} m"
        cell = None if r is None else cell_at(r, x, y)
        if r is None or cell is None:
            return text
        iy, ix = cell
        v = self.views[key].data
        raw, filt = float(r.raw[iy, ix]), float(r.filtered[iy, ix])
        here = f"; {key}: {v[iy, ix]:g}" if v is not None and key in ("thin", "profile") else ""
        return f"{text}, cell [iy={iy}, ix={ix}]: votes {raw:g}, filtered {filt:.3g}{here}"

    def _readout(self, key: str, x: float, y: float) -> None:
        self.readout.setText(self.readout_text(key, x, y))
