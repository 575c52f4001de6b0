"""The parameters panel: a pyqtgraph ``ParameterTree`` over the scene's settings.

One group per settings block of scene format v1 (``medium``, ``transducer``, ``signal``,
``echo``, ``detection``, ``mapping``, ``post``; see docs/scene-format.md), plus the scene's
``name``/``cell`` and the sensor ``placement``. Values live in the scene, so they are saved
in the scene file; each change is one undoable edit through :meth:`Document.apply`.
Optional numbers show ``auto`` for null; points and ranges are ``x, y``.
"""

from __future__ import annotations

import dataclasses
from typing import Any

from pyqtgraph.parametertree import Parameter, ParameterTree
from PySide6.QtCore import QObject, QTimer, Signal

from ..errors import SceneError
from ..scene import Scene
from . import edits
from .editor import Document

NONE_TEXT = "auto"
NO_PLACEMENT = "none"
SELECTED = "selected"


def to_param(name: str, value: Any, options: tuple[Any, ...] | None,
             may_be_none: bool = False) -> dict[str, Any]:
    """The pyqtgraph parameter spec showing one scene value (a number that may be None is
    text, so that "auto" can be typed back)."""
    if options is not None:  # None among them: "auto", chosen from the scene
        shown = [NONE_TEXT if o is None else o for o in options]
        return {"name": name, "type": "list", "limits": shown,
                "value": NONE_TEXT if value is None else value}
    if may_be_none and isinstance(value, float):
        return {"name": name, "type": "str", "value": repr(value)}
    if isinstance(value, bool):
        return {"name": name, "type": "bool", "value": value}
    if isinstance(value, int):
        return {"name": name, "type": "int", "value": value}
    if isinstance(value, float):
        return {"name": name, "type": "float", "value": value, "decimals": 8}
    if isinstance(value, tuple):
        return {"name": name, "type": "str", "value": ", ".join(f"{v:g}" for v in value)}
    if value is None:
        return {"name": name, "type": "str", "value": NONE_TEXT}
    return {"name": name, "type": "str", "value": str(value)}


def from_text(text: str, old: Any) -> Any:
    """A value typed as text back in the type the scene keeps (``auto`` → None)."""
    t = text.strip()
    if t.lower() in (NONE_TEXT, "none", "null", "random", ""):
        return None
    if t.lower() in ("true", "false"):  # an optional switch (a polyline's ``solid``)
        return t.lower() == "true"
    if "," in t:
        return tuple(float(v) for v in t.split(","))
    if isinstance(old, str):
        return t
    try:
        return float(t)
    except ValueError:
        return t  # a choice of an optional setting (old None); the scene reader checks it


def group_spec(name: str, obj: Any, skip: tuple[str, ...] = ("type",)) -> dict[str, Any]:
    """A parameter group for one settings dataclass (fields in ``skip`` left out)."""
    children = [to_param(f.name, getattr(obj, f.name), edits.choices(type(obj), f.name),
                         edits.optional(type(obj), f.name))
                for f in dataclasses.fields(obj) if f.name not in skip]
    return {"name": name, "type": "group", "children": children}


def placement_spec(scene: Scene) -> dict[str, Any]:
    """The ``placement`` group: its ``type`` (or none) and the placement's own keys."""
    p = scene.sensors.placement
    kinds = [NO_PLACEMENT, *edits.PLACEMENTS]
    children = [{"name": "type", "type": "list", "limits": kinds,
                 "value": NO_PLACEMENT if p is None else p.type}]
    if p is not None:
        children += group_spec("p", p)["children"]
    return {"name": "placement", "type": "group", "children": children}


def selected_object(scene: Scene, key: tuple[str, int] | None) -> Any:
    """The surface or explicit transducer that ``key`` names in ``scene`` (None if gone)."""
    if key is None:
        return None
    kind, i = key
    items = scene.surfaces if kind == "surface" else scene.sensors.transducers
    return items[i] if i < len(items) else None


def selection_spec(scene: Scene, key: tuple[str, int] | None) -> dict[str, Any] | None:
    """A group with the numbers of the selected surface or transducer (a sinusoid's
    amplitude and period, a circle's radius, a polyline's ``closed``, a heading…)."""
    obj = selected_object(scene, key)
    if key is None or obj is None:
        return None
    spec = group_spec(SELECTED, obj, skip=("points",))  # vertices: drag their handles
    spec["title"] = f"selected: {key[0]} {key[1]} ({type(obj).__name__.lower()})"
    return spec


def tree_spec(scene: Scene, selected: tuple[str, int] | None = None) -> list[dict[str, Any]]:
    """Every group of the panel for ``scene`` (the selection's first, if any)."""
    top = {"name": "scene", "type": "group", "children": [
        to_param("name", scene.name, None), to_param("cell", scene.cell, None)]}
    groups = [top, *(group_spec(g, getattr(scene, g)) for g in edits.SETTING_GROUPS),
              placement_spec(scene)]
    sel = selection_spec(scene, selected)
    return groups if sel is None else [sel, *groups]


class ParamsPanel(QObject):
    """Keeps a ``ParameterTree`` and the document's scene in step."""

    message = Signal(str)
    params: Parameter  # the tree's parameters, rebuilt by refresh()

    def __init__(self, doc: Document) -> None:
        super().__init__()
        self.tree = ParameterTree(showHeader=False)
        self._updating = False
        self._pending = False
        self.selected: tuple[str, int] | None = None
        self.set_document(doc)

    def set_document(self, doc: Document) -> None:
        self.doc = doc
        doc.sceneChanged.connect(self._schedule)
        self.refresh()

    def _schedule(self, *_: object) -> None:
        # rebuilt on the next turn of the event loop, not inside the edited widget's signal
        if not self._pending:
            self._pending = True
            QTimer.singleShot(0, self.refresh)

    def refresh(self, *_: object) -> None:
        """Show the document's scene (rebuilt: groups follow the placement's type)."""
        self._pending = False
        self._updating = True
        try:
            self.params = Parameter.create(name="settings", type="group",
                                           children=tree_spec(self.doc.scene, self.selected))
            self.params.sigTreeStateChanged.connect(self._changed)
            self.tree.setParameters(self.params, showTop=False)
        finally:
            self._updating = False

    def set_selection(self, key: tuple[str, int] | None) -> None:
        """Show the numbers of the surface or transducer ``key`` (None: nothing selected)."""
        self.selected = key
        self._schedule()

    def set(self, group: str, key: str, value: Any) -> None:
        """Set one parameter as if typed in the panel (tests, scripts)."""
        if self._pending:
            self.refresh()  # the tree must show the current scene first
        self.params.child(group, key).setValue(value)

    def _changed(self, _param, changes) -> None:
        if self._updating:
            return
        for param, change, data in changes:
            if change != "value":
                continue
            group, key = param.parent().name(), param.name()
            try:
                scene = self._edited(group, key, data)
            except (ValueError, TypeError) as e:
                self.message.emit(f"{group}.{key}: {e}")
                self._schedule()
                return
            try:
                self.doc.apply(scene, f"set {group}.{key}")
            except SceneError as e:
                self.message.emit(f"edit refused: {e}")
                self._schedule()
            return

    def _edited(self, group: str, key: str, value: Any) -> Scene:
        scene = self.doc.scene
        if group == SELECTED:
            assert self.selected is not None  # the group is shown only for a selection
            obj = selected_object(scene, self.selected)
            old = getattr(obj, key)
            if isinstance(value, str) and not isinstance(old, str):
                value = from_text(value, old)
            new = dataclasses.replace(obj, **{key: value})
            kind, i = self.selected
            if kind == "surface":
                return edits.replace_surface(scene, i, new)
            return edits.replace_transducer(scene, i, new.position, new.heading_deg,
                                            new.group)
        if group == "placement":
            if key == "type":
                if value == NO_PLACEMENT:
                    return edits.set_placement(scene, None)
                return edits.set_placement(scene, value, **edits.default_placement(scene, value))
            placement = scene.sensors.placement
            assert placement is not None  # its keys are shown only when there is one
            old = getattr(placement, key)
            if isinstance(value, str):
                value = from_text(value, old)
            return edits.set_placement(scene, placement.type, **{key: value})
        target = scene if group == "scene" else getattr(scene, group)
        options = None if group == "scene" else edits.choices(type(target), key)
        if options is not None:  # a list: its "auto" is None (chosen from the scene)
            value = None if value == NONE_TEXT and None in options else value
        elif isinstance(value, str) and not isinstance(getattr(target, key), str):
            value = from_text(value, getattr(target, key))
        return edits.set_setting(scene, group, key, value)
