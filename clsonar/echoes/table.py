"""The echo table, and how the per-launch outputs of either implementation become one."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import TextIO

import numpy as np

from .. import steps
from .problem import EchoProblem

KINDS = ("specular", "corner", "edge", "curved")
SPECULAR, CORNER, EDGE, CURVED = range(4)

#: Work items per kernel launch (pairs are split into chunks of at most this many slots).
SLOTS_PER_LAUNCH = 1 << 21


@dataclass(frozen=True, eq=False)
class EchoTable:
    """One row per echo return, sorted by (tx, rx, tof_s, kind, element).

    ``element`` identifies the surface element so echoes can be matched one to one: for
    ``specular``/``corner`` the row of :func:`wall_sequences` (geometry walls, max_order),
    for a path through a corner's vertex ``len(wall_sequences)`` + the row of
    ``geometry.corners``, for ``edge`` the row of ``geometry.diffractors``, for ``curved``
    the circle index, or ``len(circles)`` + the index of the sinusoid's sampling interval.
    ``point`` is the last reflection point before the receiver (the vertex for corner-vertex
    and edge paths), in scene coordinates. ``phase`` is the echo's carrier phase against a
    mirror's at the same path (radians in (−π, π]; the pulse is ``amplitude·env(u)·sin(ωu +
    phase)``, physics.pulse): 0 for every reflection, ``arg G`` of
    :func:`~clsonar.physics.edge_diffraction` for an edge's diffraction under
    ``echo.edge_model`` ``"utd"`` (π on the lit side of a face's reflection boundary, where
    the edge's echo cancels half the face's, 0 on its shadow side, −π/4 or 3π/4 far from
    the boundaries).
    """

    tx: np.ndarray  # int64 index into SensorArray
    rx: np.ndarray  # int64
    tof_s: np.ndarray  # float64
    amplitude: np.ndarray  # float64
    kind: np.ndarray  # int8 code into KINDS
    order: np.ndarray  # int8 number of reflections
    point: np.ndarray  # [n, 2] float64
    element: np.ndarray  # int64
    phase: np.ndarray  # float64 radians, carrier phase against a mirror's

    def __len__(self) -> int:
        return len(self.tof_s)

    def kind_names(self) -> np.ndarray:
        """The ``kind`` column as strings (``KINDS``)."""
        return np.asarray(KINDS)[self.kind]

    def write_csv(self, file: TextIO) -> None:
        """Write ``tx,rx,tof_s,amplitude,kind,order`` rows (docs/design.md, ``echoes.csv``)."""
        file.write("tx,rx,tof_s,amplitude,kind,order\n")
        columns = (np.asarray(c).tolist() for c in (  # Python's numbers: the same text
            self.tx, self.rx, self.tof_s, self.amplitude, self.kind_names(), self.order))
        file.write("".join(f"{tx},{rx},{tof:.12g},{amp:.9g},{kind},{order}\n"
                           for tx, rx, tof, amp, kind, order in zip(*columns, strict=True)))


def _pair_chunks(n_pairs: int, width: int) -> Iterator[slice]:
    """Slices of the pairs so that each launch has at most SLOTS_PER_LAUNCH work items."""
    step = max(1, SLOTS_PER_LAUNCH // max(width, 1))
    for start in range(0, n_pairs, step):
        yield slice(start, min(start + step, n_pairs))


def _rows(pb: EchoProblem, family: str, first_pair: int, tof: np.ndarray, amp: np.ndarray,
          point: np.ndarray, phase: np.ndarray) -> dict[str, np.ndarray]:
    """The echoes (amplitude > 0) among one launch's [pairs, elements] output slots."""
    p, e = np.nonzero(amp > 0)
    pair = pb.pairs[first_pair + p]
    n = len(p)
    if family == "mirror":
        kind = np.where(pb.sequence_corner[e], CORNER, SPECULAR)
        order = pb.sequence_order[e]
        element = e
    elif family == "vertex":
        kind = np.full(n, CORNER)
        order = np.full(n, 2)
        element = e + len(pb.sequences)
    else:
        kind = np.full(n, EDGE if family == "edge" else CURVED)
        order = np.ones(n, dtype=np.int64)
        element = e + len(pb.circles) if family == "curve" else e
    return {
        "tx": pair[:, 0], "rx": pair[:, 1],
        "tof_s": tof[p, e].astype(np.float64), "amplitude": amp[p, e].astype(np.float64),
        "kind": kind.astype(np.int8), "order": order.astype(np.int8),
        "point": point[p, e].astype(np.float64) + pb.origin, "element": element.astype(np.int64),
        "phase": phase[p, e].astype(np.float64),
    }


def _table(parts: list[dict[str, np.ndarray]]) -> EchoTable:
    """Concatenate row blocks and sort them by (tx, rx, tof_s, kind, element)."""
    if not parts:
        return EchoTable(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0), np.zeros(0),
                         np.zeros(0, np.int8), np.zeros(0, np.int8), np.zeros((0, 2)),
                         np.zeros(0, np.int64), np.zeros(0))
    cols = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    idx = np.lexsort((cols["element"], cols["kind"], cols["tof_s"], cols["rx"], cols["tx"]))
    return EchoTable(**{k: v[idx] for k, v in cols.items()})


def solve(pb: EchoProblem, run: Callable[[str, slice], tuple]) -> EchoTable:
    """Run every non-empty family over chunks of pairs and collect the echoes."""
    launches = [(family, chunk) for family, width in pb.widths.items()
                if width and len(pb.pairs) for chunk in _pair_chunks(len(pb.pairs), width)]
    parts = []
    for family, chunk in steps.each("launches", launches):
        parts.append(_rows(pb, family, chunk.start, *run(family, chunk)))
    return _table(parts)
