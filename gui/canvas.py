"""The scene canvas: surfaces and transducers as draggable pyqtgraph ROIs, in metres.

Tools (:data:`TOOLS`): ``select`` (drag handles, click to select, Delete to remove),
``wall`` / ``room`` (click points, double-click or Enter to finish an open or closed
polyline), ``circle`` (centre, then a point on the rim), ``sinusoid`` (from, then to),
``transducer`` (click to place; drag the end of its heading line to turn it) and ``ring``
(click to place the circular ring, or the start of the wall-following ring). Points snap to
a grid. Every edit goes through :meth:`Document.apply`, one undo step per click or drag.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import QPointF, Qt, QTimer, Signal

from ..errors import SceneError
from ..geometry import build_geometry
from ..scene import Circle, Circular, Polyline, Scene, Sinusoid, Surface, WallFollowing
from ..sensors import SensorArray, place_sensors
from . import edits
from .editor import Document
from .views import (
    BEAM_PEN,
    PATH_PEN,
    SENSOR_BRUSH,
    TRUTH_PEN,
    beam_length,
    beam_paths,
    heading_vector,
    pose_path,
    truth_paths,
)

TOOLS = ("select", "wall", "room", "circle", "sinusoid", "transducer", "ring")

#: Default shape of a new sinusoid (metres).
NEW_SINUSOID = {"amplitude": 0.2, "period": 1.0}

ROI_PEN = pg.mkPen((120, 30, 30), width=2)
SELECTED_PEN = pg.mkPen((255, 140, 0), width=3)
DRAFT_PEN = pg.mkPen((255, 140, 0), width=1.5, style=Qt.PenStyle.DashLine)


def _xy(p) -> tuple[float, float]:
    return (float(p.x()), float(p.y()))


class SceneCanvas(pg.PlotWidget):
    """Shows and edits :attr:`doc`'s scene; ``message(str)`` reports refused edits."""

    message = Signal(str)
    selectionChanged = Signal(object)  # ("surface" | "transducer", index) or None

    def __init__(self, doc: Document, parent=None) -> None:
        super().__init__(parent)
        self.setAspectLocked(True)
        self.showGrid(x=True, y=True, alpha=0.25)
        self.setLabel("bottom", "x", units="m")
        self.setLabel("left", "y", units="m")
        self.tool = "select"
        self.grid = 0.1  # snap step in metres (0: off)
        self.selected: tuple[str, int] | None = None
        self.rois: list[tuple[tuple[str, int], pg.ROI]] = []
        self.draft: list[tuple[float, float]] = []
        self.sensors: SensorArray | None = None  # preview of the current scene
        self._extent = pg.PlotCurveItem(pen=pg.mkPen((150, 150, 150), style=Qt.PenStyle.DotLine))
        self._curves = pg.PlotCurveItem(pen=TRUTH_PEN, connect="finite")
        self._beams = pg.PlotCurveItem(pen=BEAM_PEN, connect="finite")
        self._path = pg.PlotCurveItem(pen=PATH_PEN)
        self._sensor_dots = pg.ScatterPlotItem(size=5, brush=SENSOR_BRUSH, pen=None)
        self._draft = pg.PlotCurveItem(pen=DRAFT_PEN)
        self._ring = pg.TargetItem(size=14, movable=True, pen=pg.mkPen((30, 160, 60), width=2))
        self._ring.sigPositionChangeFinished.connect(self._ring_moved)
        for item in (self._extent, self._curves, self._beams, self._path, self._sensor_dots,
                     self._draft, self._ring):
            self.addItem(item)
        self._pending = False
        self._first_view = True
        self.scene().sigMouseClicked.connect(self._clicked)
        self.set_document(doc)

    # ------------------------------------------------------------------ document
    def set_document(self, doc: Document) -> None:
        self.doc = doc
        doc.sceneChanged.connect(self._schedule)
        self._first_view = True
        self.refresh()

    def _schedule(self, *_: object) -> None:
        # Rebuilt on the next turn of the event loop: an edit may come from the signal
        # handler of a ROI that the rebuild removes.
        if not self._pending:
            self._pending = True
            QTimer.singleShot(0, self.refresh)

    def refresh(self) -> None:
        """Redraw everything from the document's scene."""
        self._pending = False
        scene = self.doc.scene
        xmin, ymin, xmax, ymax = scene.extent
        self._extent.setData([xmin, xmax, xmax, xmin, xmin], [ymin, ymin, ymax, ymax, ymin])
        try:
            self._curves.setData(*truth_paths(build_geometry(scene)))
        except Exception:
            self._curves.setData([], [])
        try:
            self.sensors = place_sensors(scene)
        except SceneError as e:
            self.sensors = None
            self.message.emit(str(e))
        self._draw_sensors(scene)
        self._build_rois(scene)
        if self._first_view:
            self.setRange(xRange=(xmin, xmax), yRange=(ymin, ymax))
            self._first_view = False

    def _draw_sensors(self, scene: Scene) -> None:
        s = self.sensors
        if s is None or not len(s):
            self._beams.setData([], [])
            self._sensor_dots.setData([], [])
            self._path.setData([], [])
        else:
            self._beams.setData(*beam_paths(s.positions, s.headings_deg,
                                            scene.transducer.half_beam_deg, beam_length(scene)))
            self._sensor_dots.setData(s.positions[:, 0], s.positions[:, 1])
            self._path.setData(*pose_path(scene, s.poses))
        p = scene.sensors.placement
        centre = p.center if isinstance(p, Circular) else (
            p.start if isinstance(p, WallFollowing) else None)
        self._ring.setVisible(centre is not None)
        if centre is not None:
            self._ring.setPos(*centre)

    def _build_rois(self, scene: Scene) -> None:
        for _, roi in self.rois:
            self.removeItem(roi)
        self.rois = []
        if self.selected is not None and not self._exists(scene, self.selected):
            self.select(None)
        for i, s in enumerate(scene.surfaces):
            self._add_roi(("surface", i), self._surface_roi(s))
        length = 0.6 * beam_length(scene)
        for i, t in enumerate(scene.sensors.transducers):
            d = heading_vector(t.heading_deg)
            tip = (t.position[0] + length * d[0], t.position[1] + length * d[1])
            self._add_roi(("transducer", i), pg.LineSegmentROI([t.position, tip]))

    @staticmethod
    def _exists(scene: Scene, key: tuple[str, int]) -> bool:
        kind, i = key
        n = len(scene.surfaces) if kind == "surface" else len(scene.sensors.transducers)
        return i < n

    def _surface_roi(self, s) -> pg.ROI:
        if isinstance(s, Polyline):
            return pg.PolyLineROI([list(p) for p in s.points], closed=s.closed)
        if isinstance(s, Circle):
            r = s.radius
            return pg.CircleROI((s.center[0] - r, s.center[1] - r), (2 * r, 2 * r))
        return pg.LineSegmentROI([s.start, s.end])

    def _add_roi(self, key: tuple[str, int], roi: pg.ROI) -> None:
        roi.setAcceptedMouseButtons(Qt.MouseButton.LeftButton)
        roi.removable = True
        roi.sigRegionChangeFinished.connect(lambda r, key=key: self._roi_finished(key, r))
        roi.sigClicked.connect(lambda r, ev, key=key: self.select(key))
        roi.sigRemoveRequested.connect(lambda r, key=key: self.delete(key))
        roi.setPen(self._pen_for(key))
        self.addItem(roi)
        self.rois.append((key, roi))

    # ------------------------------------------------------------------ edits
    def _apply(self, scene: Scene, text: str) -> bool:
        try:
            return self.doc.apply(scene, text)
        except SceneError as e:
            self.message.emit(f"edit refused: {e}")
            self._schedule()  # put the ROIs back where the scene has them
            return False

    @staticmethod
    def roi_points(roi: pg.ROI) -> list[tuple[float, float]]:
        """The handle positions of ``roi`` in metres."""
        return [_xy(roi.mapToParent(p)) for _, p in roi.getLocalHandlePositions()]

    def _roi_finished(self, key: tuple[str, int], roi: pg.ROI) -> None:
        """A drag ended: the ROI's new shape becomes one undoable edit (snapped)."""
        scene = self.doc.scene
        kind, i = key
        if not self._exists(scene, key):
            return
        g = self.grid
        if kind == "transducer":
            a, b = self.roi_points(roi)
            a = edits.snap_point(a, g)
            new = edits.replace_transducer(scene, i, a, edits.heading_to(a, b))
            self._apply(new, "move transducer")
            return
        s = scene.surfaces[i]
        surface: Surface
        if isinstance(s, Polyline):
            pts = tuple(edits.snap_point(p, g) for p in self.roi_points(roi))
            surface = dataclasses.replace(s, points=pts)
        elif isinstance(s, Circle):
            pos, size = roi.pos(), roi.size()
            r = 0.5 * float(size.x())
            surface = edits.snap_surface(Circle((float(pos.x()) + r, float(pos.y()) + r), r), g)
        else:
            a, b = self.roi_points(roi)
            surface = Sinusoid(edits.snap_point(a, g), edits.snap_point(b, g), s.amplitude,
                               s.period)
        self._apply(edits.replace_surface(scene, i, surface), f"edit {edits.surface_label(s)}")

    def _ring_moved(self, *_: object) -> None:
        p = edits.snap_point(_xy(self._ring.pos()), self.grid)
        self._apply(edits.place_ring(self.doc.scene, p), "move ring")

    def select(self, key: tuple[str, int] | None) -> None:
        self.selected = key
        for k, roi in self.rois:
            roi.setPen(self._pen_for(k))
        self.selectionChanged.emit(key)

    def _pen_for(self, key: tuple[str, int]):
        if key == self.selected:
            return SELECTED_PEN
        if key[0] == "transducer":
            return pg.mkPen(SENSOR_BRUSH.color(), width=3)
        s = self.doc.scene.surfaces[key[1]]
        return pg.mkPen((120, 30, 30, 90), width=1) if isinstance(s, Sinusoid) else ROI_PEN

    def delete(self, key: tuple[str, int] | None = None) -> bool:
        """Delete ``key`` (default: the selection) as one undoable edit."""
        key = key or self.selected
        if key is None or not self._exists(self.doc.scene, key):
            return False
        kind, i = key
        scene = self.doc.scene
        if kind == "surface":
            new, text = edits.remove_surface(scene, i), \
                f"delete {edits.surface_label(scene.surfaces[i])}"
        else:
            new, text = edits.remove_transducer(scene, i), "delete transducer"
        self.select(None)
        return self._apply(new, text)

    # ------------------------------------------------------------------ tools
    def set_tool(self, tool: str) -> None:
        if tool not in TOOLS:
            raise ValueError(f"unknown tool {tool!r}")
        self.tool = tool
        self.cancel_draft()

    def cancel_draft(self) -> None:
        self.draft = []
        self._draft.setData([], [])

    def _clicked(self, ev) -> None:
        if ev.button() != Qt.MouseButton.LeftButton or self.tool == "select":
            return
        p = self.plotItem.vb.mapSceneToView(ev.scenePos())
        self.click(_xy(p), double=ev.double())
        ev.accept()

    def click(self, point: tuple[float, float], double: bool = False) -> None:
        """What a left click at ``point`` (metres) does with the current tool."""
        p = edits.snap_point(point, self.grid)
        scene = self.doc.scene
        tool = self.tool
        if tool == "transducer":
            self._apply(edits.add_transducer(scene, p), "place transducer")
        elif tool == "ring":
            self._apply(edits.place_ring(scene, p), "place ring")
        elif tool in ("wall", "room"):
            if double:
                self.finish_draft()
                return
            if not self.draft or self.draft[-1] != p:
                self.draft.append(p)
        elif tool in ("circle", "sinusoid"):
            self.draft.append(p)
            if len(self.draft) == 2:
                self.finish_draft()
        self._show_draft()

    def _show_draft(self) -> None:
        d = np.asarray(self.draft, dtype=float).reshape(-1, 2)
        self._draft.setData(d[:, 0], d[:, 1])

    def finish_draft(self) -> None:
        """End the shape being drawn and add it (one undo step)."""
        d, tool, scene = self.draft, self.tool, self.doc.scene
        self.cancel_draft()
        surface: Surface | None = None
        if tool == "wall" and len(d) >= 2:
            surface = Polyline(tuple(d), closed=False)
        elif tool == "room" and len(d) >= 3:
            surface = Polyline(tuple(d), closed=True)
        elif tool == "circle" and len(d) == 2:
            r = float(np.hypot(d[1][0] - d[0][0], d[1][1] - d[0][1]))
            surface = Circle(d[0], max(r, self.grid or 0.01))
        elif tool == "sinusoid" and len(d) == 2 and d[0] != d[1]:
            surface = Sinusoid(d[0], d[1], **NEW_SINUSOID)
        if surface is not None:
            self._apply(edits.add_surface(scene, surface), f"add {edits.surface_label(surface)}")

    def keyPressEvent(self, ev) -> None:
        key = ev.key()
        if key in (Qt.Key.Key_Return, Qt.Key.Key_Enter) and self.draft:
            self.finish_draft()
        elif key == Qt.Key.Key_Escape:
            self.cancel_draft()
        elif key in (Qt.Key.Key_Delete, Qt.Key.Key_Backspace):
            self.delete()
        else:
            super().keyPressEvent(ev)

    def roi_for(self, key: tuple[str, int]) -> pg.ROI | None:
        """The ROI that shows ``key`` (tests, tools)."""
        return next((roi for k, roi in self.rois if k == key), None)

    def view_to_widget(self, point: tuple[float, float]) -> QPointF:
        """Widget (viewport) coordinates of a point in metres."""
        return QPointF(self.mapFromScene(self.plotItem.vb.mapViewToScene(QPointF(*point))))
