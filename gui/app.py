"""The main window and ``clsonar-gui [SCENE.json] [--screenshot PNG]`` (:func:`main`).

Central scene canvas (:mod:`.canvas`), docks for the parameters (:mod:`.params`), the map
stages (:mod:`.stages`) and the plots (:mod:`.plots`); the pipeline runs in a
:class:`~.worker.Job` with progress and cancel. Dock layout and window geometry are kept in
``QSettings`` between runs; unsaved edits are kept in a recovery file (:mod:`.editor`).
"""

from __future__ import annotations

import argparse
import functools
import os
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import (
    QBuffer,
    QByteArray,
    QEvent,
    QEventLoop,
    QSettings,
    QStandardPaths,
    Qt,
    Signal,
)
from PySide6.QtGui import QAction, QActionGroup, QKeySequence
from PySide6.QtWidgets import (
    QApplication,
    QComboBox,
    QDockWidget,
    QDoubleSpinBox,
    QFileDialog,
    QLabel,
    QMainWindow,
    QMenu,
    QMessageBox,
    QProgressBar,
    QToolBar,
    QWidget,
)

from .. import opencl, pipeline
from ..cli import EXIT_USAGE
from ..errors import ClsonarError, SceneError
from ..files import write_atomic
from ..outputs import error_summary, metric, profile_csv
from ..scene import Scene
from . import edits
from .canvas import TOOLS, SceneCanvas
from .editor import Document
from .params import ParamsPanel
from .plots import PlotsPanel
from .stages import NO_RUN, STAGE_VIEWS, StagesPanel
from .worker import GuiThreadCollector, Job

APP_NAME = "clsonar-gui"
ORGANISATION = "clsonar"


def new_scene() -> Scene:
    """An empty 10 m × 10 m scene at a 2 cm cell."""
    return Scene(name="untitled", extent=(0.0, 0.0, 10.0, 10.0), cell=0.02)


def png_of(widget: QWidget) -> bytes:
    """What ``widget`` shows, rendered by the app itself (``QWidget.grab``), as PNG bytes."""
    data = QByteArray()
    buf = QBuffer(data)
    buf.open(QBuffer.OpenModeFlag.WriteOnly)
    widget.grab().save(buf, "PNG")
    buf.close()
    return bytes(data.data())


def default_recovery_dir() -> Path:
    """Where unsaved edits are kept (the app's local data folder)."""
    base = QStandardPaths.writableLocation(QStandardPaths.StandardLocation.AppLocalDataLocation)
    return Path(base or Path.home() / ".clsonar") / "recovery"


class MainWindow(QMainWindow):
    """clsonar's main window; see the module docstring."""

    runFinished = Signal(object)  # RunResult (a full run or a post-processing re-run)
    runFailed = Signal(str)
    runCancelled = Signal()

    def __init__(self, path: str | None = None, *, settings: QSettings | None = None,
                 recovery_dir: str | os.PathLike[str] | None = None,
                 device: str | None = None) -> None:
        super().__init__()
        self.settings = settings if settings is not None else QSettings(ORGANISATION, APP_NAME)
        self.recovery_dir = recovery_dir if recovery_dir is not None else default_recovery_dir()
        self.device = device
        self.result: pipeline.RunResult | None = None
        self.job: Job | None = None
        self.runs = {"full": 0, "post": 0}  # finished runs of each kind
        self.last_stages: list[str] = []  # the stages the last finished job ran
        self._post_again = False
        self._generation = 0  # bumped when another scene is opened: older runs are dropped
        self.collector = GuiThreadCollector(self)  # stopped when the window closes

        self.doc = Document(new_scene(), None, self.recovery_dir)
        self.doc.setParent(self)
        self.canvas = SceneCanvas(self.doc)
        self.setCentralWidget(self.canvas)
        self.params = ParamsPanel(self.doc)
        self.stages = StagesPanel()
        self.plots = PlotsPanel(self)
        self.docks = {
            "parameters": self._dock("Parameters", self.params.tree,
                                     Qt.DockWidgetArea.LeftDockWidgetArea),
            "stages": self._dock("Stages", self.stages, Qt.DockWidgetArea.RightDockWidgetArea),
            "plots": self._dock("Plots", self.plots, Qt.DockWidgetArea.BottomDockWidgetArea),
        }
        self._status()
        self._actions()
        for source in (self.canvas, self.params, self.plots):
            source.message.connect(self.show_message)
        self.canvas.selectionChanged.connect(self.params.set_selection)
        self._connect_doc()
        self._opened()
        self.resize(1500, 950)
        self.resizeDocks([self.docks["parameters"], self.docks["stages"]], [300, 760],
                         Qt.Orientation.Horizontal)
        self.resizeDocks([self.docks["plots"]], [230], Qt.Orientation.Vertical)
        self._restore_layout()
        if path is not None:
            self.open_file(path)

    # ------------------------------------------------------------------ building
    def _dock(self, title: str, widget: QWidget, area) -> QDockWidget:
        dock = QDockWidget(title, self)
        dock.setObjectName(f"dock-{title.lower()}")
        dock.setWidget(widget)
        self.addDockWidget(area, dock)
        return dock

    def _status(self) -> None:
        self.progress = QProgressBar()
        self.progress.setMaximumWidth(220)
        self.progress.setVisible(False)
        self.stage_label = QLabel("")
        self.stage_text = ""  # the stage the running job reported last
        self.statusBar().addPermanentWidget(self.stage_label)
        self.statusBar().addPermanentWidget(self.progress)

    def _action(self, menu: QMenu | QToolBar, text: str, slot: Callable[..., object],
                shortcut: QKeySequence.StandardKey | str | None = None) -> QAction:
        """An action with ``text`` and ``shortcut`` calling ``slot``, added to ``menu``."""
        a = QAction(text, self)
        if shortcut is not None:
            a.setShortcut(QKeySequence(shortcut))
        a.triggered.connect(slot)
        menu.addAction(a)
        return a

    def _actions(self) -> None:
        """The menus and tool bars."""
        self._file_menu()
        self._edit_menu()
        self._tool_bar()
        self._run_bar()
        self._view_menu()

    def _file_menu(self) -> None:
        SK = QKeySequence.StandardKey
        f = self.menuBar().addMenu("&File")
        self._action(f, "&New", self.new_file, SK.New)
        self._action(f, "&Open…", self.open_dialog, SK.Open)
        self._action(f, "&Save", self.save, SK.Save)
        self._action(f, "Save &As…", self.save_as, SK.SaveAs)
        f.addSeparator()
        self._action(f, "Export view as &PNG…", self.export_png_dialog, "Ctrl+E")
        self._action(f, "Export profile as &CSV…", self.export_csv_dialog)
        f.addSeparator()
        self._action(f, "&Quit", self.close, SK.Quit)

    def _edit_menu(self) -> None:
        SK = QKeySequence.StandardKey
        e = self.menuBar().addMenu("&Edit")
        undo = self.doc.undo.createUndoAction(self, "&Undo")
        redo = self.doc.undo.createRedoAction(self, "&Redo")
        self.undo_action, self.redo_action = undo, redo
        undo.setShortcut(QKeySequence(SK.Undo))
        redo.setShortcut(QKeySequence(SK.Redo))
        e.addActions([undo, redo])
        self._action(e, "&Delete selection", lambda: self.canvas.delete(), SK.Delete)

    def _tool_bar(self) -> None:
        """One checkable action per canvas tool (Ctrl+1 …), and the snap step."""
        tools = self.addToolBar("Tools")
        tools.setObjectName("toolbar-tools")
        group = QActionGroup(self)
        self.tool_actions: dict[str, QAction] = {}
        for n, tool in enumerate(TOOLS):
            a = QAction(tool, self, checkable=True)
            a.setShortcut(QKeySequence(f"Ctrl+{n + 1}"))
            a.triggered.connect(lambda _=False, t=tool: self.canvas.set_tool(t))
            group.addAction(a)
            tools.addAction(a)
            self.tool_actions[tool] = a
        self.tool_actions["select"].setChecked(True)
        tools.addWidget(QLabel(" snap (m): "))
        self.snap = QDoubleSpinBox(decimals=3, minimum=0.0, maximum=10.0, singleStep=0.05)
        self.snap.setValue(self.canvas.grid)
        self.snap.valueChanged.connect(lambda v: setattr(self.canvas, "grid", v))
        tools.addWidget(self.snap)

    def _run_bar(self) -> None:
        """Run and Cancel, in the Run menu and a tool bar, and the OpenCL device."""
        runbar = self.addToolBar("Run")
        runbar.setObjectName("toolbar-run")
        r = self.menuBar().addMenu("&Run")
        self.run_action = self._action(r, "&Run", self.run, "F5")
        self.cancel_action = self._action(r, "&Cancel", self.cancel, "Esc")
        self.cancel_action.setEnabled(False)
        runbar.addActions([self.run_action, self.cancel_action])
        runbar.addWidget(QLabel(" device: "))
        self.device_box = QComboBox()
        self.device_box.addItem("default", None)
        try:
            for d in opencl.list_devices():
                label = f"{d.index} {d.name} ({d.kind})" + ("" if d.usable else " – unusable")
                self.device_box.addItem(label, d.index)
        except ClsonarError as e:
            self.show_message(str(e))
        self.device_box.currentIndexChanged.connect(
            lambda _: setattr(self, "device", self.device_box.currentData()))
        runbar.addWidget(self.device_box)

    def _view_menu(self) -> None:
        v = self.menuBar().addMenu("&View")
        for dock in self.docks.values():
            v.addAction(dock.toggleViewAction())
        v.addSeparator()
        for mode in ("side by side", *STAGE_VIEWS):
            self._action(v, f"Stages: {mode}", lambda _=False, m=mode: self.stages.set_mode(m))

    # ------------------------------------------------------------------ document
    def _connect_doc(self) -> None:
        self.doc.sceneChanged.connect(self._scene_changed)
        self.doc.recoveryFailed.connect(lambda text: self.show_message(text, error=True))
        self.doc.undo.cleanChanged.connect(self._clean_changed)
        self._title()

    def _clean_changed(self, clean: bool) -> None:
        self.setWindowModified(not clean)

    def _title(self) -> None:
        name = Path(self.doc.path).name if self.doc.path else "untitled"
        self.setWindowTitle(f"{name}[*] – clsonar")
        self.setWindowModified(self.doc.modified)

    def _opened(self) -> None:
        """After a new or opened scene: drop the old run, offer to recover unsaved work."""
        self.cancel()
        self._generation += 1
        self.result = None
        self.stages.readout.setText(NO_RUN)
        self._title()
        doc = self.doc
        recovered = doc.recovered()
        if recovered is not None and recovered != doc.scene and self.ask(
                "Recover unsaved changes",
                f"clsonar found unsaved changes to {doc.path or 'an untitled scene'} from a "
                "session that did not end cleanly. Recover them?"):
            doc.apply(recovered, "recover unsaved changes")

    def open_file(self, path: str) -> bool:
        try:
            self.doc.open(path)
        except SceneError as e:
            self.show_message(str(e), error=True)
            return False
        self._opened()
        self.show_message(f"opened {path}")
        return True

    def new_file(self) -> None:
        if self.maybe_save():
            self.doc.reset(new_scene())
            self._opened()

    def open_dialog(self) -> None:
        if not self.maybe_save():
            return
        path, _ = QFileDialog.getOpenFileName(self, "Open scene", "", "Scenes (*.json)")
        if path:
            self.open_file(path)

    def save(self) -> bool:
        if self.doc.path is None:
            return self.save_as()
        return self._save(self.doc.path)

    def save_as(self) -> bool:
        path, _ = QFileDialog.getSaveFileName(self, "Save scene", self.doc.path or "",
                                              "Scenes (*.json)")
        return bool(path) and self._save(path)

    def _save(self, path: str) -> bool:
        try:
            self.doc.save(path)
        except (OSError, ValueError) as e:
            self.show_message(f"cannot save {path}: {e}", error=True)
            return False
        self._title()
        self.show_message(f"saved {path}")
        return True

    def maybe_save(self) -> bool:
        """True when the window may drop the current scene (saved, discarded or unchanged)."""
        if not self.doc.modified:
            return True
        answer = self.ask_save()
        if answer == QMessageBox.StandardButton.Save:
            return self.save()
        if answer == QMessageBox.StandardButton.Discard:
            self.doc.discard_recovery()
            return True
        return False

    def ask_save(self) -> QMessageBox.StandardButton:
        B = QMessageBox.StandardButton
        return QMessageBox.question(self, "Unsaved changes",
                                    "The scene has unsaved changes. Save them?",
                                    B.Save | B.Discard | B.Cancel, B.Save)

    def ask(self, title: str, text: str) -> bool:
        B = QMessageBox.StandardButton
        return QMessageBox.question(self, title, text, B.Yes | B.No, B.Yes) == B.Yes

    def show_message(self, text: str, error: bool = False) -> None:
        """A message in the status bar (and a box for errors when the window is shown)."""
        self.statusBar().showMessage(text, 0 if error else 8000)
        if error and self.isVisible() and QApplication.platformName() != "offscreen":
            QMessageBox.warning(self, "clsonar", text)

    # ------------------------------------------------------------------ layout
    def _restore_layout(self) -> None:
        geom, state = self.settings.value("geometry"), self.settings.value("state")
        if geom is not None:
            self.restoreGeometry(geom)
        if state is not None:
            self.restoreState(state)

    def save_layout(self) -> None:
        self.settings.setValue("geometry", self.saveGeometry())
        self.settings.setValue("state", self.saveState())
        self.settings.sync()

    def closeEvent(self, event) -> None:
        if not self.maybe_save():
            event.ignore()
            return
        self.cancel()
        if self.job is not None:
            self.job.wait()
        self.doc.discard_recovery()
        self.save_layout()
        self.collector.stop()
        event.accept()

    # ------------------------------------------------------------------ running
    @property
    def busy(self) -> bool:
        return self.job is not None and self.job.isRunning()

    def run(self) -> bool:
        """Run the whole pipeline on the scene in a worker thread (False if busy)."""
        scene, spec = self.doc.scene, self.device
        return self._start("full", lambda progress: pipeline.run(
            scene, context=opencl.get_context(spec), progress=progress))

    def rerun_post(self) -> bool:
        """Re-run only post-processing of the last run with the scene's post settings."""
        result, post = self.result, self.doc.scene.post
        if result is None:
            return False
        return self._start("post", lambda progress: pipeline.rerun_post(result, post,
                                                                        progress=progress))

    def _start(self, kind: str, fn: Callable[[pipeline.Progress], pipeline.RunResult]) -> bool:
        if self.busy:
            return False
        job = Job(fn, kind, self)
        job.progressed.connect(self._progress)
        job.stepped.connect(self._step)
        job.succeeded.connect(functools.partial(self._done, job, self._generation))
        job.failed.connect(lambda m, j=job: self._failed(j, m))
        job.cancelled.connect(lambda j=job: self._cancelled(j))
        self.job = job
        self.progress.setRange(0, len(pipeline.STAGES))
        self.progress.setValue(0 if kind == "full" else pipeline.STAGES.index("filter"))
        self.progress.setVisible(True)
        self.run_action.setEnabled(False)
        self.cancel_action.setEnabled(True)
        job.start()
        return True

    def cancel(self) -> None:
        if self.job is not None and self.job.isRunning():
            self.job.cancel()

    def _progress(self, stage: str, i: int, n: int) -> None:
        self.progress.setValue(i - 1)
        self.stage_text = f"{stage} ({i}/{n})"
        self.stage_label.setText(self.stage_text)

    def _step(self, what: str, done: int, total: int) -> None:
        """Progress inside the stage (:mod:`clsonar.steps`), beside its name."""
        self.stage_label.setText(f"{self.stage_text}: {what} {done:,}/{total:,}")

    def _finish(self, job: Job) -> None:
        job.wait()
        self.progress.setVisible(False)
        self.stage_label.setText("")
        self.run_action.setEnabled(True)
        self.cancel_action.setEnabled(False)
        self.last_stages = list(job.stages)
        if self.job is job:
            self.job = None

    def _done(self, job: Job, generation: int, result: pipeline.RunResult) -> None:
        self._finish(job)
        if generation != self._generation:
            return  # a run of a scene that is no longer open
        self.runs[job.name] += 1
        self.result = result
        self.stages.show_result(result)
        self.plots.set_result(result)
        total = sum(result.seconds.values())
        self.show_message(f"{job.name} run of {result.scene.name} in {total:.2f} s: "
                          f"{summary(result)}"
                          + "".join(f" — warning: {w}" for w in result.warnings))
        self.runFinished.emit(result)
        if self._post_again:
            self._post_again = False
            self._scene_changed(self.doc.scene)

    def _failed(self, job: Job, message: str) -> None:
        self._finish(job)
        self.show_message(f"run failed: {message}", error=True)
        self.runFailed.emit(message)

    def _cancelled(self, job: Job) -> None:
        self._finish(job)
        self.show_message("run cancelled")
        self.runCancelled.emit()

    def _scene_changed(self, scene: Scene) -> None:
        """Re-run post-processing when only its settings changed since the last run."""
        if self.result is None:
            return
        changed = edits.changed_groups(self.result.asked or self.result.scene, scene)
        if changed == {"post"}:
            if self.busy:
                self._post_again = True
            else:
                self.rerun_post()
        elif changed:
            self.stage_label.setText("map out of date: press Run (F5)")

    # ------------------------------------------------------------------ export
    def views(self) -> dict[str, QWidget]:
        """Every view that can be exported as a PNG, by name."""
        out: dict[str, QWidget] = {"scene": self.canvas, "stages": self.stages}
        out.update({f"stage-{k}": v for k, v in self.stages.views.items()})
        out.update(self.plots.views())
        out["window"] = self
        return out

    def export_png(self, name: str, path: str) -> None:
        write_atomic(path, png_of(self.views()[name]))

    def export_csv(self, path: str) -> bool:
        if self.result is None:
            self.show_message("no run to export: press Run (F5) first", error=True)
            return False
        write_atomic(path, profile_csv(self.result.profile.points).encode())
        return True

    def export_png_dialog(self) -> None:
        from PySide6.QtWidgets import QInputDialog

        names = list(self.views())
        name, ok = QInputDialog.getItem(self, "Export PNG", "view:", names, 0, False)
        if not ok:
            return
        path, _ = QFileDialog.getSaveFileName(self, "Export PNG", f"{name}.png", "PNG (*.png)")
        if path:
            try:
                self.export_png(name, path)
            except OSError as e:
                self.show_message(f"cannot write {path}: {e}", error=True)

    def export_csv_dialog(self) -> None:
        path, _ = QFileDialog.getSaveFileName(self, "Export profile", "profile.csv",
                                              "CSV (*.csv)")
        if path:
            try:
                self.export_csv(path)
            except OSError as e:
                self.show_message(f"cannot write {path}: {e}", error=True)


def summary(result: pipeline.RunResult) -> str:
    """One line of the run's error (:func:`clsonar.outputs.error_summary`: RMS of eq. 2.6
    where it applies, else the accuracy RMS) and its completeness within 2 cm."""
    comp = metric(result.metrics, "completeness.2cm")
    return error_summary(result.metrics) + ("" if comp is None
                                            else f", completeness(2 cm) {comp:.0%}")


def wait_for_run(window: MainWindow) -> None:
    """Start a run and block (running the event loop) until it ends."""
    loop = QEventLoop()
    for sig in (window.runFinished, window.runFailed, window.runCancelled):
        sig.connect(loop.quit)
    if window.run():
        loop.exec()


def screenshot(window: MainWindow, path: str) -> None:
    """Run the scene, show every stage side by side and save what the window renders."""
    window.stages.set_mode("side by side")
    window.show()
    wait_for_run(window)
    QApplication.processEvents()
    window.export_png("window", path)


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="clsonar-gui", description="clsonar's desktop GUI")
    p.add_argument("scene", nargs="?", help="scene file (format v1) to open")
    p.add_argument("--device", help="OpenCL device, as for clsonar run")
    p.add_argument("--screenshot", metavar="PNG",
                   help="run the scene, save a picture of the window to PNG and exit")
    return p


def main(argv: list[str] | None = None) -> int:
    """``clsonar-gui``: open the main window (or, with ``--screenshot``, save a picture of it
    after a run); returns the exit status. :func:`clsonar.gui.main` checks for Qt first."""
    args = _parser().parse_args(argv)
    if args.scene is not None:
        try:
            from ..scene import load_scene

            load_scene(args.scene)
        except SceneError as e:
            print(f"clsonar-gui: error: {e}", file=sys.stderr)
            return EXIT_USAGE
    app = QApplication.instance() or QApplication(sys.argv[:1])
    app.setOrganizationName(ORGANISATION)
    app.setApplicationName(APP_NAME)
    if args.screenshot:
        # the default layout, whatever a user's settings hold; no recovery file left behind
        with tempfile.TemporaryDirectory() as tmp:
            settings = QSettings(os.path.join(tmp, "settings.ini"), QSettings.Format.IniFormat)
            window = MainWindow(args.scene, device=args.device, settings=settings,
                                recovery_dir=tmp)
            window.resize(1600, 1000)
            screenshot(window, args.screenshot)
        status = 0
    else:
        window = MainWindow(args.scene, device=args.device)
        window.show()
        status = app.exec()
    # delete the window while Qt still runs, not in the interpreter's final collection
    window.collector.stop()
    window.deleteLater()
    QApplication.sendPostedEvents(None, QEvent.Type.DeferredDelete)
    return status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
