"""The tools' figures (matplotlib's object API, Agg): ``Figure`` + Agg canvas
(:func:`figure`), never ``pyplot``, so it keeps no global state and needs no display. This
is the one module that imports matplotlib (the ``clsonar[plots]`` extra): the tools draw
their figures with :func:`figure` and :func:`png_bytes`, and import this module only when
they draw. A run's own pictures need no matplotlib (:mod:`clsonar.pictures`).
"""

from __future__ import annotations

import io
from typing import Literal

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


def figure(figsize: tuple[float, float], dpi: int,
           layout: Literal["constrained", "compressed", "tight"] | None = "constrained"
           ) -> Figure:
    """A new figure on its own Agg canvas, laid out with ``layout`` (no pyplot)."""
    fig = Figure(figsize=figsize, dpi=dpi, layout=layout)
    FigureCanvasAgg(fig)
    return fig


def png_bytes(fig: Figure) -> bytes:
    """The figure as PNG bytes."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()
