"""Typed access to a parsed JSON scene: every read checks the value and fails with a
:class:`~clsonar.errors.SceneError` naming the file and the key path of the bad value, e.g.
``room.json: surfaces[2].radius: must be > 0``."""

from __future__ import annotations

import math
import typing
from typing import Any, TypeVar, cast

from ..errors import SceneError
from .limits import MAX_MAGNITUDE
from .model import Point

#: Marks a key without a default: missing, it is an error.
_MISSING: Any = object()

#: The values of one ``Literal`` setting (clsonar.scene.settings).
Choice = TypeVar("Choice", bound=str)


def join(key: str, name: str | int) -> str:
    """The key path of ``name`` inside ``key``: ``a.b``, or ``a[3]`` for a list index."""
    if isinstance(name, int):
        return f"{key}[{name}]"
    return f"{key}.{name}" if key else name


def type_name(v: Any) -> str:
    """What a JSON value is, in words (``an object``, ``a list``, ``null``, …)."""
    return {dict: "an object", list: "a list", str: "a string", bool: "a boolean",
            type(None): "null", int: "a number", float: "a number"}.get(type(v), type(v).__name__)


class JsonReader:
    """Typed access to a parsed JSON tree that fails with the key path of the bad value."""

    def __init__(self, source: str) -> None:
        self.source = source

    def fail(self, key: str, message: str) -> SceneError:
        return SceneError(message, key, self.source)

    def obj(self, value: Any, key: str, allowed: tuple[str, ...],
            required: tuple[str, ...] = ()) -> dict[str, Any]:
        if not isinstance(value, dict):
            raise self.fail(key, f"must be an object, not {type_name(value)}")
        for k in value:
            if k not in allowed:
                raise self.fail(join(key, k), f"unknown key (allowed: {', '.join(allowed)})")
        for k in required:
            if k not in value:
                raise self.fail(join(key, k), "missing required key")
        return value

    def _absent(self, d: dict[str, Any], name: str, path: str, default: Any) -> bool:
        """Whether ``name`` is absent from ``d`` (its ``default`` then stands); absent
        without a default, it is an error."""
        if name in d:
            return False
        if default is _MISSING:
            raise self.fail(path, "missing required key")
        return True

    def number(self, d: dict[str, Any], name: str, key: str, default: Any = _MISSING, *,
               gt: float | None = None, ge: float | None = None, le: float | None = None,
               lt: float | None = None) -> float:
        path = join(key, name)
        if self._absent(d, name, path, default):
            return default
        return self._bounded(self.check_number(d[name], path, gt=gt, ge=ge, le=le, lt=lt), path)

    def optional_number(self, d: dict[str, Any], name: str, key: str, *,
                        gt: float | None = None, ge: float | None = None,
                        le: float | None = None) -> float | None:
        """``d[name]``, or None where it is absent or null (a setting chosen from the
        scene)."""
        if d.get(name) is None:
            return None
        return self.number(d, name, key, gt=gt, ge=ge, le=le)

    def _bounded(self, v: float, path: str) -> float:
        if abs(v) > MAX_MAGNITUDE:
            raise self.fail(path, f"{v:.3g} is out of range (at most ±{MAX_MAGNITUDE:.0e})")
        return v

    def check_number(self, v: Any, path: str, *, gt: float | None = None,
                     ge: float | None = None, le: float | None = None,
                     lt: float | None = None) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            raise self.fail(path, f"must be a number, not {type_name(v)}")
        v = float(v)
        if not math.isfinite(v):
            raise self.fail(path, "must be a finite number")
        checks = ((gt, ">", v > (gt or 0.0)), (ge, ">=", v >= (ge or 0.0)),
                  (lt, "<", v < (lt or 0.0)), (le, "<=", v <= (le or 0.0)))
        for bound, word, ok in checks:
            if bound is not None and not ok:
                raise self.fail(path, f"must be {word} {bound:g}")
        return v

    def integer(self, d: dict[str, Any], name: str, key: str, default: Any = _MISSING, *,
                ge: int | None = None, le: int | None = None) -> int:
        path = join(key, name)
        if self._absent(d, name, path, default):
            return default
        v = d[name]
        if isinstance(v, float) and v.is_integer() and abs(v) < 2**53:
            v = int(v)
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.fail(path, f"must be an integer, not {type_name(v)}")
        if ge is not None and v < ge:
            raise self.fail(path, f"must be >= {ge}")
        if le is not None and v > le:
            raise self.fail(path, f"must be <= {le}")
        return v

    def boolean(self, d: dict[str, Any], name: str, key: str, default: bool) -> bool:
        v = d.get(name, default)
        if not isinstance(v, bool):
            raise self.fail(join(key, name), f"must be true or false, not {type_name(v)}")
        return v

    def choice(self, d: dict[str, Any], name: str, key: str, options: tuple[str, ...],
               default: Any = _MISSING) -> str:
        path = join(key, name)
        if self._absent(d, name, path, default):
            return default
        v = d[name]
        if v not in options or not isinstance(v, str):
            raise self.fail(path, f"must be one of {', '.join(map(repr, options))}, not {v!r:.40}")
        return v

    def literal(self, d: dict[str, Any], name: str, key: str, alias: Any,
                default: Choice) -> Choice:
        """The setting ``d[name]`` (``default`` if absent), one of the values of the
        ``Literal`` ``alias`` (clsonar.scene.settings), which the value then has."""
        return cast(Choice, self.choice(d, name, key, typing.get_args(alias), default))

    def optional_literal(self, d: dict[str, Any], name: str, key: str, alias: Any
                         ) -> Any:
        """:meth:`literal`, or None where ``d[name]`` is absent or null (a setting chosen
        from the scene)."""
        if d.get(name) is None:
            return None
        return self.choice(d, name, key, typing.get_args(alias))

    def vector(self, v: Any, path: str, length: int) -> tuple[float, ...]:
        if not isinstance(v, list) or len(v) != length:
            raise self.fail(path, f"must be a list of {length} numbers")
        return tuple(self._bounded(self.check_number(x, f"{path}[{i}]"), f"{path}[{i}]")
                     for i, x in enumerate(v))

    def xy(self, v: Any, path: str) -> Point:
        """The point ``[x, y]`` ``v``."""
        x, y = self.vector(v, path, 2)
        return (x, y)

    def point(self, d: dict[str, Any], name: str, key: str, default: Any = _MISSING) -> Point:
        path = join(key, name)
        if self._absent(d, name, path, default) or (d[name] is None and default is None):
            return default
        return self.xy(d[name], path)

    def interval(self, d: dict[str, Any], name: str, key: str, default: tuple[float, float],
                 *, gt: float | None = None) -> tuple[float, float]:
        path = join(key, name)
        if name not in d:
            return default
        lo, hi = self.vector(d[name], path, 2)
        if gt is not None and lo <= gt:
            raise self.fail(f"{path}[0]", f"must be > {gt:g}")
        if hi < lo:
            raise self.fail(path, "upper bound must be >= lower bound")
        return (lo, hi)
