"""The desktop GUI (issue 7) under pytest-qt, offscreen (tests/conftest.py sets
QT_QPA_PLATFORM): open a bundled scene, add and drag a wall, undo and redo, place a ring,
run to completion (waiting on a signal), check the four stage views, re-run only
post-processing after a filter change, save and reload; crash recovery, the unsaved-changes
prompt, dock layout, export, the worker's cancel and errors; and that the core imports no Qt.
"""

from __future__ import annotations

import gc
import importlib.resources
import json
import pkgutil
import subprocess
import sys
import threading

import numpy as np
import pyqtgraph as pg
import pytest
from clsonar.gui import edits
from clsonar.gui.app import MainWindow, main
from clsonar.gui.worker import GuiThreadCollector, Job
from PySide6.QtCore import QEvent, QPointF, QSettings, Qt
from PySide6.QtGui import QMouseEvent
from PySide6.QtWidgets import QApplication, QMessageBox

import clsonar
from clsonar.pipeline import STAGES
from clsonar.scene import Circular, Polyline, load_scene, scene_to_dict

ROOM = str(importlib.resources.files("clsonar.scenes") / "room.json")
POST = list(STAGES[4:])  # sight, filter, thinning, profile, metrics
RUN_TIMEOUT_MS = 120_000


# --------------------------------------------------------------------------- helpers


def make_window(qtbot, tmp_path, monkeypatch=None, path=None) -> MainWindow:
    settings = QSettings(str(tmp_path / "settings.ini"), QSettings.Format.IniFormat)
    w = MainWindow(path, settings=settings, recovery_dir=tmp_path / "recovery")
    qtbot.addWidget(w)
    w.resize(1400, 900)
    w.snap.setValue(0.5)  # coarser than a pixel of the canvas: clicks land exactly
    w.show()
    qtbot.waitExposed(w)
    return w


@pytest.fixture(autouse=True)
def every_mouse_move():
    """pyqtgraph drops mouse moves closer than 10 ms apart (``mouseRateLimit``); a test's
    synthetic drag sends them back to back."""
    old = pg.getConfigOption("mouseRateLimit")
    pg.setConfigOptions(mouseRateLimit=0)
    yield
    pg.setConfigOptions(mouseRateLimit=old)


@pytest.fixture(autouse=True)
def collection_restored():
    """Once a test's windows are closed (pytest-qt closes them before fixtures tear down),
    Python's automatic garbage collection is on again: the later tests' cycles are
    collected."""
    yield
    assert gc.isenabled() and GuiThreadCollector._started == 0


@pytest.fixture
def window(qtbot, tmp_path, monkeypatch):
    # never block on a dialog: discard on close, decline recovery unless a test says so
    monkeypatch.setattr(MainWindow, "ask_save", lambda self: QMessageBox.StandardButton.Discard)
    monkeypatch.setattr(MainWindow, "ask", lambda self, title, text: False)
    w = make_window(qtbot, tmp_path)
    yield w
    if w.job is not None:
        w.job.cancel()
        w.job.wait()


def mouse(widget, kind, pos: QPointF, buttons=Qt.MouseButton.LeftButton,
          button=Qt.MouseButton.LeftButton) -> None:
    ev = QMouseEvent(kind, pos, widget.mapToGlobal(pos), button, buttons,
                     Qt.KeyboardModifier.NoModifier)
    QApplication.sendEvent(widget, ev)


def drag(canvas, a: tuple[float, float], b: tuple[float, float], steps: int = 8) -> None:
    """Press at ``a`` (metres), move to ``b`` in steps and release: a real mouse drag."""
    vp = canvas.viewport()
    pa, pb = canvas.view_to_widget(a), canvas.view_to_widget(b)
    # pyqtgraph picks the dragged item from the last hover: move over it first
    mouse(vp, QEvent.Type.MouseMove, pa, buttons=Qt.MouseButton.NoButton,
          button=Qt.MouseButton.NoButton)
    mouse(vp, QEvent.Type.MouseButtonPress, pa)
    for k in range(1, steps + 1):
        p = pa + (pb - pa) * (k / steps)
        mouse(vp, QEvent.Type.MouseMove, p, button=Qt.MouseButton.NoButton)
    mouse(vp, QEvent.Type.MouseButtonRelease, pb, buttons=Qt.MouseButton.NoButton)


def click(qtbot, canvas, p: tuple[float, float], double: bool = False) -> None:
    pos = canvas.view_to_widget(p).toPoint()
    if double:
        qtbot.mouseDClick(canvas.viewport(), Qt.MouseButton.LeftButton, pos=pos)
    else:
        qtbot.mouseClick(canvas.viewport(), Qt.MouseButton.LeftButton, pos=pos)


def run_and_wait(qtbot, w: MainWindow, start=None):
    with qtbot.waitSignal(w.runFinished, timeout=RUN_TIMEOUT_MS) as blocker:
        (start or w.run_action.trigger)()
    return blocker.args[0]


# --------------------------------------------------------------------------- the test plan


def test_edit_run_stages_post_save(qtbot, window, tmp_path):
    """The issue's "Must show" list, in one session on the bundled closed room."""
    w, canvas = window, window.canvas
    assert w.open_file(ROOM)
    scene0 = w.doc.scene
    n0 = len(scene0.surfaces)

    # add a wall with the mouse: two clicks (snapped to the 0.5 m grid), then Enter
    w.tool_actions["wall"].trigger()
    click(qtbot, canvas, (3.07, 4.06))
    click(qtbot, canvas, (5.95, 3.96))
    qtbot.keyClick(canvas, Qt.Key.Key_Return)
    assert len(w.doc.scene.surfaces) == n0 + 1
    assert w.doc.scene.surfaces[n0] == Polyline(((3.0, 4.0), (6.0, 4.0)), closed=False)
    qtbot.waitUntil(lambda: canvas.roi_for(("surface", n0)) is not None)

    # drag its end with the mouse: one undo step, snapped
    w.tool_actions["select"].trigger()
    steps = w.doc.undo.count()
    drag(canvas, (6.0, 4.0), (6.54, 5.05))
    assert w.doc.undo.count() == steps + 1
    assert w.doc.scene.surfaces[n0].points == ((3.0, 4.0), (6.5, 5.0))
    dragged = w.doc.scene

    # undo the drag, then the wall; redo both
    w.undo_action.trigger()
    assert w.doc.scene.surfaces[n0].points == ((3.0, 4.0), (6.0, 4.0))
    w.undo_action.trigger()
    assert w.doc.scene == scene0
    w.redo_action.trigger()
    w.redo_action.trigger()
    assert w.doc.scene == dragged

    # a circular ring from the parameters panel, placed with the ring tool
    w.params.set("placement", "type", "circular")
    qtbot.waitUntil(lambda: w.params.params.child("placement", "type").value() == "circular")
    w.tool_actions["ring"].trigger()
    click(qtbot, canvas, (5.04, 6.95))
    placement = w.doc.scene.sensors.placement
    assert isinstance(placement, Circular) and placement.center == (5.0, 7.0)
    # the canvas shows the ring's 8 transducers (redrawn on the next turn of the loop)
    qtbot.waitUntil(lambda: canvas.sensors is not None and len(canvas.sensors) == 8)

    # run to completion, waiting on the signal; every stage ran once
    result = run_and_wait(qtbot, w)
    assert w.runs == {"full": 1, "post": 0}
    assert w.last_stages == list(STAGES)
    assert result.asked == w.doc.scene
    shape = w.doc.scene.grid_shape
    views = w.stages.views
    for key, view in views.items():
        assert view.data is not None and view.data.shape == shape, key
    assert views["raw"].data.max() > 0
    assert views["filtered"].data.max() > 0
    assert views["thin"].data.sum() > 0
    assert len(result.profile.points) > 0
    px, _ = views["profile"].profile.getData()
    assert np.isfinite(px).sum() == len(result.profile.points)
    # one stage at a time, or all four side by side
    w.stages.set_mode("thin")
    assert [k for k, v in views.items() if not v.isHidden()] == ["thin"]
    w.stages.set_mode("side by side")
    assert all(not v.isHidden() for v in views.values())
    # the readout names the votes of the cell under the cursor, [iy, ix] the right way up
    iy, ix = np.unravel_index(np.argmax(result.raw), result.raw.shape)
    xmin, ymin = w.doc.scene.extent[:2]
    x, y = xmin + (ix + 0.5) * w.doc.scene.cell, ymin + (iy + 0.5) * w.doc.scene.cell
    text = w.stages.readout_text("raw", x, y)
    assert f"[iy={iy}, ix={ix}]" in text and f"votes {result.raw[iy, ix]:g}" in text
    rect = views["raw"].image.mapRectToParent(views["raw"].image.boundingRect())
    assert rect.top() == pytest.approx(ymin) and rect.bottom() > rect.top()

    # change the filter: only post-processing runs again, on the same raw map
    with qtbot.waitSignal(w.runFinished, timeout=RUN_TIMEOUT_MS) as blocker:
        w.params.set("post", "filter", "none")
    again = blocker.args[0]
    assert w.runs == {"full": 1, "post": 1}
    assert w.last_stages == POST
    assert again.votes is result.votes and again.echoes is result.echoes
    assert again.scene.post.filter == "none"
    np.testing.assert_array_equal(again.filtered, result.raw.astype(float))
    assert {k: again.seconds[k] for k in STAGES[:4]} == {k: result.seconds[k]
                                                          for k in STAGES[:4]}

    # save and reload: the identical scene
    path = tmp_path / "edited.json"
    assert w._save(str(path))
    assert not w.doc.modified and not w.isWindowModified()
    assert load_scene(path) == w.doc.scene
    saved = w.doc.scene
    assert w.open_file(str(path))
    assert w.doc.scene == saved
    assert scene_to_dict(load_scene(path)) == json.loads(path.read_text())


def test_delete_and_undo_transducer_heading(qtbot, window):
    """Place a transducer by clicking, turn it by dragging its heading handle, delete it;
    each step is one undo step."""
    w, canvas = window, window.canvas
    w.tool_actions["transducer"].trigger()
    click(qtbot, canvas, (2.04, 1.96))
    assert w.doc.scene.sensors.transducers[0].position == (2.0, 2.0)
    assert w.doc.scene.sensors.transducers[0].heading_deg == 0.0
    qtbot.waitUntil(lambda: canvas.roi_for(("transducer", 0)) is not None)
    w.tool_actions["select"].trigger()
    tip = canvas.roi_points(canvas.roi_for(("transducer", 0)))[1]
    drag(canvas, tip, (2.0, 2.0 + tip[0] - 2.0))  # swing the tip to straight up
    assert w.doc.scene.sensors.transducers[0].heading_deg == pytest.approx(90.0, abs=5.0)
    assert w.doc.undo.count() == 2
    canvas.select(("transducer", 0))
    qtbot.keyClick(canvas, Qt.Key.Key_Delete)
    assert w.doc.scene.sensors.transducers == ()
    w.undo_action.trigger()
    assert len(w.doc.scene.sensors.transducers) == 1


def test_draw_room_circle_sinusoid(qtbot, window):
    w, canvas = window, window.canvas
    canvas.set_tool("room")
    for p in ((1.0, 1.0), (4.0, 1.0), (4.0, 3.0)):
        canvas.click(p)
    canvas.click((4.0, 3.0), double=True)
    canvas.set_tool("circle")
    canvas.click((6.0, 6.0))
    canvas.click((6.5, 6.0))
    canvas.set_tool("sinusoid")
    canvas.click((8.0, 1.0))
    canvas.click((8.0, 9.0))
    s = w.doc.scene.surfaces
    assert s[0] == Polyline(((1.0, 1.0), (4.0, 1.0), (4.0, 3.0)), closed=True)
    assert s[1].center == (6.0, 6.0) and s[1].radius == 0.5
    assert (s[2].start, s[2].end) == ((8.0, 1.0), (8.0, 9.0))
    assert w.doc.undo.count() == 3


def test_recovery_after_crash(qtbot, tmp_path, monkeypatch):
    """Unsaved edits survive a session that never closed; the next one offers them."""
    scene_file = tmp_path / "room.json"
    scene_file.write_text(open(ROOM).read())
    first = make_window(qtbot, tmp_path, path=str(scene_file))
    edited = edits.add_transducer(first.doc.scene, (5.0, 5.0), 45.0)
    first.doc.apply(edited, "place transducer")
    assert first.doc.recovery_file.exists()
    # "crash": the first window never closes; a second session opens the same file
    monkeypatch.setattr(MainWindow, "ask", lambda self, title, text: True)
    second = make_window(qtbot, tmp_path, path=str(scene_file))
    assert second.doc.scene == first.doc.scene
    assert second.doc.modified
    monkeypatch.setattr(MainWindow, "ask_save",
                        lambda self: QMessageBox.StandardButton.Discard)
    first.close()
    second.close()
    assert not second.doc.recovery_file.exists()


def test_unsaved_prompt_and_layout(qtbot, tmp_path, monkeypatch):
    w = make_window(qtbot, tmp_path)
    w.doc.apply(edits.add_transducer(w.doc.scene, (1.0, 1.0)), "place transducer")
    assert w.isWindowModified()
    monkeypatch.setattr(MainWindow, "ask_save", lambda self: QMessageBox.StandardButton.Cancel)
    assert not w.close() and w.isVisible()
    w.docks["plots"].hide()
    monkeypatch.setattr(MainWindow, "ask_save", lambda self: QMessageBox.StandardButton.Discard)
    assert w.close()
    again = make_window(qtbot, tmp_path)
    assert not again.docks["plots"].isVisible()
    assert again.docks["stages"].isVisible()
    again.close()


def test_export_png_and_csv(qtbot, window, tmp_path):
    w = window
    assert w.open_file(ROOM)
    w.doc.apply(edits.place_ring(edits.set_placement(w.doc.scene, "circular",
                                                     center=(5.0, 5.0)), (5.0, 5.0)), "ring")
    result = run_and_wait(qtbot, w)
    for name in ("scene", "stage-raw", "stage-profile", "a-scan", "window"):
        png = tmp_path / f"{name}.png"
        w.export_png(name, str(png))
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    csv = tmp_path / "profile.csv"
    assert w.export_csv(str(csv))
    lines = csv.read_text().splitlines()
    assert lines[0] == "x,y" and len(lines) == 1 + len(result.profile.points)


def test_run_error_is_a_message(qtbot, window):
    w = window
    w.device = "no-such-device"
    with qtbot.waitSignal(w.runFailed, timeout=RUN_TIMEOUT_MS) as blocker:
        w.run_action.trigger()
    assert "no-such-device" in blocker.args[0]
    assert "run failed" in w.statusBar().currentMessage()
    assert w.run_action.isEnabled() and not w.busy


def test_job_cancel_between_stages(qtbot):
    gate = threading.Event()

    def fn(progress):
        progress("first", 1, 2)
        gate.wait(30)
        progress("second", 2, 2)
        return "done"

    job = Job(fn)
    with qtbot.waitSignal(job.progressed, timeout=10_000):
        job.start()
    with qtbot.waitSignal(job.cancelled, timeout=10_000):
        job.cancel()
        gate.set()
    job.wait()
    assert job.stages == ["first"]


def test_main_bad_scene(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"clsonar": 1, "extent": [0, 0, 1, 1], "cell": -1}))
    assert main([str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.json" in err[0] and "cell" in err[0]


def test_core_imports_no_qt_and_pictures_alone_import_matplotlib():
    """Every module of the package but the GUI (walked recursively) loads neither PySide6
    nor pyqtgraph; every one but the pictures (clsonar.plots) and the tools loads no
    matplotlib."""
    core = sorted(m.name for m in pkgutil.walk_packages(clsonar.__path__, "clsonar.")
                  if not m.name.startswith("clsonar.gui") and m.name != "clsonar.__main__")
    assert {"clsonar.pipeline", "clsonar.cli", "clsonar.outputs",
            "clsonar.tools.sweep.runners", "clsonar.tools.stability.map_judge"} <= set(core)
    no_pictures = [m for m in core if m != "clsonar.plots" and not m.startswith("clsonar.tools.")]
    code = ("import importlib, sys\n"
            f"for m in {no_pictures!r}: importlib.import_module(m)\n"
            "print('matplotlib' in sys.modules)\n"
            f"for m in {core!r}: importlib.import_module(m)\n"
            "print(sorted({k.split('.')[0] for k in sys.modules} & "
            "{'PySide6', 'pyqtgraph', 'shiboken6'}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120, check=True)
    assert out.stdout.split("\n")[:2] == ["False", "[]"]


@pytest.mark.parametrize("missing", ["PySide6", "pyqtgraph"])
def test_gui_entry_point_without_qt_is_one_line(missing):
    """``clsonar-gui`` (clsonar.gui:main) without PySide6 or pyqtgraph: one error line
    saying what to install, status 2, no traceback."""
    code = (f"import sys; sys.modules[{missing!r}] = None\n"
            "from clsonar.gui import main\n"
            "raise SystemExit(main([]))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr == ("clsonar-gui: error: the desktop app needs PySide6 and pyqtgraph: "
                        "pip install 'clsonar[gui]'\n")


def test_qt_item_change_keeps_references():
    """PySide6 6.12.0 drops a reference to None on every Python ``itemChange`` override
    call (every pyqtgraph item has one), so a long session aborts the interpreter; the
    installed PySide6 must not (pyproject.toml excludes 6.12.0)."""
    import gc

    item = pg.GraphicsObject()
    parent = pg.GraphicsObject()
    gc.collect()
    before = sys.getrefcount(None)
    for k in range(500):
        item.setPos(k, k)
        item.setParentItem(parent if k % 2 else None)
    gc.collect()
    assert sys.getrefcount(None) - before > -100


def test_selected_sinusoid_numbers_in_parameters(qtbot, window):
    """A selected surface's numbers (here a sinusoid's amplitude) are edited in the
    parameters panel, as one undo step."""
    w, canvas = window, window.canvas
    canvas.set_tool("sinusoid")
    canvas.click((2.0, 1.0))
    canvas.click((2.0, 9.0))
    canvas.select(("surface", 0))
    qtbot.waitUntil(lambda: "selected" in w.params.params.names)
    assert w.params.params.child("selected", "amplitude").value() == 0.2
    w.params.set("selected", "amplitude", 0.35)
    assert w.doc.scene.surfaces[0].amplitude == 0.35
    w.params.set("selected", "end", "3, 9")
    assert w.doc.scene.surfaces[0].end == (3.0, 9.0)
    assert w.doc.undo.count() == 3
    w.undo_action.trigger()
    w.undo_action.trigger()
    assert w.doc.scene.surfaces[0].amplitude == 0.2


PLANE = str(importlib.resources.files("clsonar.scenes") / "plane-2m.json")


def test_sweeps_bench_and_ascan(qtbot, window):
    """RMS against distance and noise, and run time against error, run in a worker; the
    numbers are those of the pipeline itself. The A-scan shows the chosen pair."""
    from clsonar import pipeline
    from clsonar.tools import variants

    w = window
    assert w.open_file(PLANE)
    scene = w.doc.scene
    with qtbot.waitSignal(w.plots.sweepFinished, timeout=RUN_TIMEOUT_MS) as blocker:
        assert w.plots.sweep("distance", [2.0, 4.0])
    kind, points = blocker.args
    assert kind == "distance" and [d for d, _ in points] == [2.0, 4.0]
    direct = pipeline.run(variants.at_distance(scene, 2.0, 4.0)).metrics["rms_m"]
    assert points[1][1] == pytest.approx(direct)
    xs, ys = w.plots.sweep_plots["distance"].getPlotItem().listDataItems()[0].getData()
    assert list(xs) == [2.0, 4.0] and ys[1] == pytest.approx(direct)

    with qtbot.waitSignal(w.plots.sweepFinished, timeout=RUN_TIMEOUT_MS) as blocker:
        assert w.plots.sweep("noise", [0.0, 0.5])
    _, points = blocker.args
    direct = pipeline.run(variants.with_seed(scene, 0, 0.5)).metrics["rms_m"]
    assert points[1] == (0.5, pytest.approx(direct))

    with qtbot.waitSignal(w.plots.sweepFinished, timeout=RUN_TIMEOUT_MS) as blocker:
        assert w.plots.run_bench()
    _, rows = blocker.args
    assert [r["settings"] for r in rows] == ["thesis", "best"]
    assert all(r["total_s"] > 0 and r["rms_m"] is not None for r in rows)

    result = run_and_wait(qtbot, w)
    tx, rx = int(result.detections.tx[0]), int(result.detections.rx[0])
    assert (w.plots.tx.value(), w.plots.rx.value()) == (tx, rx)
    n_det = int(np.count_nonzero((result.detections.tx == tx) & (result.detections.rx == rx)))
    assert w.plots.ascan.getPlotItem().titleLabel.text.endswith(f"{n_det} detections")


def test_block_max_keeps_single_cells():
    from clsonar.gui.stages import block_max

    image = np.zeros((5, 7), dtype=np.float32)
    image[4, 6] = 3.0  # the far corner: a partial block
    image[0, 1] = 1.0
    out = block_max(image, 2)
    assert out.shape == (3, 4)
    assert out[2, 3] == 3.0 and out[0, 0] == 1.0 and out.sum() == 4.0
    assert block_max(image, 10**9).shape == (1, 1)  # never larger than one block a side
    assert block_max(image, 1) is image


def test_placements_from_parameters(qtbot, window):
    """The three placements of the issue, chosen and tuned in the parameters panel; the
    canvas previews the transducers, their beams and the wall-following path."""
    w, canvas = window, window.canvas
    assert w.open_file(ROOM)

    def shown():
        qtbot.waitUntil(lambda: not canvas._pending)
        return len(canvas.sensors) if canvas.sensors is not None else 0

    w.params.set("placement", "type", "none")
    assert w.doc.scene.sensors.placement is None and shown() == 0
    w.params.set("placement", "type", "wall-following")
    qtbot.waitUntil(lambda: "step_m" in w.params.params.child("placement").names)
    w.params.set("placement", "step_m", 1.0)
    assert w.doc.scene.sensors.placement.step_m == 1.0
    n = shown()
    assert n > 0 and n % 8 == 0
    px, _ = canvas._path.getData()
    assert len(px) == n // 8 + 1  # the ring's poses, closed on the start
    bx, _ = canvas._beams.getData()
    assert np.isfinite(bx).sum() == n * 9  # a wedge of 9 points per transducer
    w.params.set("placement", "type", "random-lines")
    qtbot.waitUntil(lambda: "elements" in w.params.params.child("placement").names)
    w.params.set("placement", "elements", 4)
    assert w.doc.scene.sensors.placement.elements == 4
    n = shown()
    assert n > 0 and n % 4 == 0
    assert w.doc.undo.count() == 5


def test_settings_chosen_from_the_scene_show_auto(qtbot, window):
    """A setting chosen from the scene (null in the file) shows "auto" in the panel; a
    value chosen there is saved in the scene, and "auto" gives the choice back (issue 14)."""
    w = window
    fit = w.params.params.child("post", "fit")
    assert w.doc.scene.post.fit is None and fit.value() == "auto"
    assert "walls" in fit.opts["limits"] and "none" in fit.opts["limits"]
    w.params.set("post", "fit", "none")  # the fit "none", not "auto"
    assert w.doc.scene.post.fit == "none"
    w.params.set("post", "fit", "auto")
    assert w.doc.scene.post.fit is None
    w.params.set("post", "max_gap_m", "0.5")
    assert w.doc.scene.post.max_gap_m == 0.5
    w.params.set("post", "max_gap_m", "auto")
    assert w.doc.scene.post.max_gap_m is None



def test_the_mapping_selector_lists_every_method(window):
    """The parameters panel offers every mapping method of the registry (issue 15)."""
    from clsonar.mapping import METHODS

    mode = window.params.params.child("mapping", "mode")
    assert list(mode.opts["limits"]) == list(edits.choices(type(window.doc.scene.mapping),
                                                           "mode"))
    assert set(mode.opts["limits"]) == set(METHODS) and len(METHODS) == 10


def test_every_mapping_method_can_be_chosen(window):
    """Choosing each method in the panel sets the scene's ``mapping.mode`` (issue 15), and
    the panel shows the choice."""
    from clsonar.mapping import METHODS

    for name in METHODS:
        window.params.set("mapping", "mode", name)
        assert window.doc.scene.mapping.mode == name
        window.params.refresh()  # the panel rebuilt from the scene
        assert window.params.params.child("mapping", "mode").value() == name


def test_job_cancel_inside_a_stage(qtbot, monkeypatch):
    """Cancel stops a real run at the detection's next launch, not at the end of the stage:
    the launches are one pair each, and the first one cancels."""
    from clsonar import pipeline
    from clsonar.signals import host

    scene = load_scene(str(importlib.resources.files("clsonar.scenes") / "plane-2m.json"))
    job = Job(lambda progress: pipeline.run(scene, progress=progress))

    def one_pair_and_cancel(size, seconds, most):
        job.cancel()
        return 1

    monkeypatch.setattr(host, "FIRST_LAUNCH_SLOTS", 1)
    monkeypatch.setattr(host, "launch_size", one_pair_and_cancel)
    with qtbot.waitSignal(job.cancelled, timeout=RUN_TIMEOUT_MS):
        job.start()
    job.wait()
    assert job.stages[-1] == "detection"


def test_recovery_file_holds_every_edit_and_survives_a_full_disk(window, tmp_path):
    """After each edit the recovery file holds the scene as edited; where the disk is full
    the edit stays in the window, the status bar says so in one line, and the file keeps
    the last edit written, whole; the next edit with space writes it again."""
    from clsonar.tools.faults.harness import disk_full

    w = window
    first = edits.add_transducer(w.doc.scene, (5.0, 5.0), 45.0)
    w.doc.apply(first, "place transducer")
    assert load_scene(str(w.doc.recovery_file)) == w.doc.scene
    second = edits.add_transducer(w.doc.scene, (6.0, 5.0), 90.0)
    with disk_full(tmp_path / "recovery", 1):
        w.doc.apply(second, "place transducer")
    assert w.doc.scene == second
    assert "not kept for recovery" in w.statusBar().currentMessage()
    assert "No space left on device" in w.statusBar().currentMessage()
    assert load_scene(str(w.doc.recovery_file)) == first
    third = edits.add_transducer(w.doc.scene, (7.0, 5.0), 0.0)
    w.doc.apply(third, "place transducer")
    assert load_scene(str(w.doc.recovery_file)) == third
    assert [p.name for p in (tmp_path / "recovery").iterdir()] == [w.doc.recovery_file.name]


def test_garbage_is_collected_on_the_gui_thread_only(qtbot, window):
    """While a window is open, garbage cycles made in a job's thread (enough to cross
    Python's threshold many times) are collected by the window's timer on the GUI thread,
    never in the job's thread (a Qt object freed there can crash the process); once the
    window closes, collection is automatic again."""
    threads: list[int] = []

    def record(phase, info):
        if phase == "start":
            threads.append(threading.get_ident())

    def make_cycles(progress):
        for _ in range(5 * gc.get_threshold()[0]):
            cycle: list = []
            cycle.append(cycle)
        return threading.get_ident()

    assert not gc.isenabled()
    gc.callbacks.append(record)
    try:
        job = Job(make_cycles)
        with qtbot.waitSignal(job.succeeded, timeout=10_000) as blocker:
            job.start()
        job.wait()
        worker = blocker.args[0]
        qtbot.waitUntil(lambda: len(threads) > 0, timeout=5_000)
    finally:
        gc.callbacks.remove(record)
    assert worker != threading.get_ident()
    assert set(threads) == {threading.get_ident()}
    window.close()
    assert gc.isenabled()
