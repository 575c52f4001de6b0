"""Raster drawing of the run's plots with axes (scene.png, profile.png) on an RGB array:
anti-aliased lines, markers and text, a frame with ticks and labels, a legend — the look
matplotlib gave them, without importing it (issue 16: its import and two figures were
1.3 s of CPU a run, more than the pipeline).

Coverage, not paths: each line or marker is the set of pixels whose centre lies within
half its width of it, each pixel's share (0–1) falling off over one pixel at the edge
(:func:`cover`); an artist's pixels take the largest share any of its parts gives them and
are blended over the picture once (:meth:`Canvas.paint`). Text is stamped from a glyph atlas
drawn by matplotlib's Agg renderer once (``clsonar/glyphs.npz``,
:mod:`clsonar.tools.glyphs`). Pixel (row i, column j) spans x ∈ [j, j + 1), y ∈ [i, i + 1)
with y down; an :class:`Axes` maps metres onto them, north up.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from functools import cache
from importlib import resources

import numpy as np

#: Dots per inch, and the points of each font size in the atlas.
DPI = 150
SIZES = {"normal": 10.0, "small": 7.0}

#: matplotlib's "tab" colours and the others the plots use, 8-bit RGB.
COLOURS = {
    "black": (0, 0, 0), "grey": (128, 128, 128), "red": (255, 0, 0),
    "tab:red": (214, 39, 40), "tab:blue": (31, 119, 180), "tab:green": (44, 160, 44),
    "tab:orange": (255, 127, 14),
}


def px(points: float) -> float:
    """``points`` (1/72 in) in pixels."""
    return points * DPI / 72


def _segment_distance(x: np.ndarray, y: np.ndarray, a: np.ndarray, b: np.ndarray
                      ) -> np.ndarray:
    """Distance from points ``(x, y)`` to the segments ``a`` → ``b`` ([..., 2] each)."""
    d = b - a
    dd = np.maximum(d[..., 0] * d[..., 0] + d[..., 1] * d[..., 1], 1e-12)
    x, y = x - a[..., 0], y - a[..., 1]
    t = np.clip((x * d[..., 0] + y * d[..., 1]) / dd, 0.0, 1.0)
    return np.hypot(x - t * d[..., 0], y - t * d[..., 1])


def cover(distance: np.ndarray, half_width: float) -> np.ndarray:
    """The share of a pixel a stroke covers whose centre is ``distance`` from its middle
    line: 1 inside, falling to 0 over one pixel at the edge; a stroke thinner than a pixel
    covers its width's share at most."""
    w = max(half_width, 0.5)
    return np.clip(w + 0.5 - distance, 0.0, 1.0) * min(1.0, 2.0 * half_width)


def segment_pixels(a: np.ndarray, b: np.ndarray, width: float
                   ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(rows, cols, share)`` of the pixels the segments ``a`` → ``b`` ([n, 2] pixel
    coordinates) cover at ``width`` pixels, by scanlines: along each segment's major axis
    (x, or y where it is steeper than 45°), every pixel line whose centre lies within
    reach of the stroke, and across it the pixels within E·√2 of the segment there (E the
    stroke's half width plus the pixel of falling share: across a line at most 45° off
    the axis its band is E/cos ≤ E·√2 high, and its round caps no higher), each share
    from the distance of the pixel's centre to the segment itself."""
    a = np.asarray(a, dtype=np.float64).reshape(-1, 2)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 2)
    if len(a) == 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0, np.float32)
    reach = max(0.5 * width, 0.5) + 0.5  # no share beyond this from the middle line
    steep = np.abs(b[:, 1] - a[:, 1]) > np.abs(b[:, 0] - a[:, 0])
    au, av = np.where(steep, a[:, 1], a[:, 0]), np.where(steep, a[:, 0], a[:, 1])
    bu, bv = np.where(steep, b[:, 1], b[:, 0]), np.where(steep, b[:, 0], b[:, 1])
    first = np.ceil(np.minimum(au, bu) - reach - 0.5).astype(np.int64)
    count = np.maximum(np.floor(np.maximum(au, bu) + reach - 0.5).astype(np.int64) - first + 1, 0)
    seg = np.repeat(np.arange(len(a)), count)
    line = first[seg] + np.arange(len(seg)) - np.repeat(np.cumsum(count) - count, count)
    du = bu - au
    t = np.clip((line + 0.5 - au[seg]) / np.where(du == 0, 1.0, du)[seg], 0.0, 1.0)
    band = reach * math.sqrt(2.0)
    low = np.floor(av[seg] + t * (bv - av)[seg] - band).astype(np.int64)
    across = low[:, None] + np.arange(math.ceil(2.0 * band + 1.5))[None, :]
    along = np.broadcast_to(line[:, None], across.shape)
    steep_k = steep[seg][:, None]
    rows = np.where(steep_k, along, across)
    cols = np.where(steep_k, across, along)
    # in float32 about the segment's start (pixel coordinates: a few thousand at most)
    start = a[seg].astype(np.float32)[:, None]
    d = _segment_distance((cols + 0.5).astype(np.float32) - start[..., 0],
                          (rows + 0.5).astype(np.float32) - start[..., 1], np.zeros(2, np.float32),
                          (b - a)[seg].astype(np.float32)[:, None])
    share = cover(d, 0.5 * width)
    keep = share > 0
    return rows[keep], cols[keep], share[keep]


def marker_reach(size: float, width: float) -> int:
    """How many pixels around the pixel of a marker's centre hold every pixel it covers:
    its strokes reach half its size, half their width and the pixel of falling share
    from the centre along either axis (a cross's corners), plus half a pixel."""
    return math.ceil(0.5 * size + max(0.5 * width, 0.5) + 1.0)


def marker_pixels(centres: np.ndarray, marker: str, size: float, width: float
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(rows, cols, share)`` of markers at ``centres`` ([n, 2] pixels), ``size`` pixels
    across: ``"x"`` (a cross of strokes ``width`` wide), ``"o"`` (a ring), ``"disc"``,
    ``"s"`` (a filled square)."""
    r = marker_reach(size, width)
    off = np.arange(-r, r + 1)
    cols = np.floor(centres[:, 0])[:, None, None] + off[None, None, :]
    rows = np.floor(centres[:, 1])[:, None, None] + off[None, :, None]
    cols, rows = np.broadcast_arrays(cols, rows)
    dx = (cols + 0.5 - centres[:, 0, None, None]).astype(np.float32)
    dy = (rows + 0.5 - centres[:, 1, None, None]).astype(np.float32)
    h = np.float32(0.5 * size)
    if marker == "x":
        ends = np.array([[-h, -h], [h, h], [-h, h], [h, -h]], dtype=np.float32)
        d = np.minimum(_segment_distance(dx, dy, ends[0], ends[1]),
                       _segment_distance(dx, dy, ends[2], ends[3]))
        share = cover(d, 0.5 * width)
    elif marker == "o":
        share = cover(np.abs(np.hypot(dx, dy) - h), 0.5 * width)
    elif marker == "disc":
        share = np.clip(h + 0.5 - np.hypot(dx, dy), 0.0, 1.0)
    elif marker == "s":
        share = np.clip(h + 0.5 - np.maximum(np.abs(dx), np.abs(dy)), 0.0, 1.0)
    else:
        raise ValueError(f"unknown marker {marker!r}")
    keep = share > 0
    return rows[keep].astype(np.int64), cols[keep].astype(np.int64), share[keep]


@dataclass(frozen=True)
class Font:
    """One size of the glyph atlas: ``alpha`` [characters, rows, columns] 0–1, each glyph's
    origin at column ``origin`` on row ``baseline``; ``advance`` [characters] pixels."""

    alpha: np.ndarray
    advance: np.ndarray
    origin: int
    baseline: int
    index: dict[str, int]


@cache
def font(size: str = "normal") -> Font:
    """The atlas at ``size`` (a key of :data:`SIZES`)."""
    with resources.files("clsonar").joinpath("glyphs.npz").open("rb") as f, \
            np.load(f) as data:
        chars = str(data["chars"])
        return Font(data[f"{size}_alpha"].astype(np.float32) / 255.0,
                    np.asarray(data[f"{size}_advance"], dtype=np.float64),
                    int(data[f"{size}_origin"]), int(data[f"{size}_baseline"]),
                    {c: k for k, c in enumerate(chars)})


def text_alpha(text: str, size: str = "normal") -> tuple[np.ndarray, int, float]:
    """``(alpha [rows, columns], baseline row, width in pixels)`` of ``text`` set in one
    line (a character the atlas lacks is set as "?"); its origin at column
    ``font(size).origin``."""
    f = font(size)
    ids = [f.index.get(c, f.index["?"]) for c in text]
    pens = np.concatenate([[0.0], np.cumsum(f.advance[ids])])
    _, rows, cols = f.alpha.shape
    out = np.zeros((rows, math.ceil(pens[-1]) + cols), dtype=np.float32)
    for k, pen in zip(ids, np.rint(pens[:-1]).astype(int).tolist(), strict=True):
        np.maximum(out[:, pen:pen + cols], f.alpha[k], out=out[:, pen:pen + cols])
    return out, f.baseline, float(pens[-1])


#: The most pixels one part of an artist looks at (:meth:`Canvas.lines`,
#: :meth:`Canvas.markers`): its working arrays, about 50 bytes a pixel, stay near 50 MB
#: whatever the number of segments or markers (a floor's 10⁵ transducers and echoes).
PART_PIXELS = 1 << 20

#: Markers are drawn at their centres rounded to this fraction of a pixel, each place once
#: (a floor's echoes fall on the same reflection points thousands of times).
MARKER_GRID = 8.0


def distinct_rows(a: np.ndarray) -> np.ndarray:
    """The distinct rows of ``a`` [n, 2] (integral values), sorted."""
    if len(a) < 2:
        return a.reshape(-1, 2)
    order = np.lexsort((a[:, 1], a[:, 0]))
    a = a[order]
    new = np.r_[True, np.any(a[1:] != a[:-1], axis=1)]
    return a[new]


#: The ``(rows, cols, share)`` of the pixels a stroke or marker covers.
Pixels = tuple[np.ndarray, np.ndarray, np.ndarray]


def _parts(counts: np.ndarray, most: int) -> Iterator[slice]:
    """Consecutive slices of items whose ``counts`` add up to at most ``most`` each (an item
    alone where its own count is more)."""
    ends = np.cumsum(counts)
    start, done = 0, 0
    while start < len(ends):
        stop = max(int(np.searchsorted(ends, done + max(most, 1), side="right")), start + 1)
        yield slice(start, stop)
        done, start = int(ends[stop - 1]), stop


class Canvas:
    """An RGB picture ``width`` × ``height`` pixels, white, drawn on by blending."""

    def __init__(self, width: int, height: int) -> None:
        self.width, self.height = width, height
        self.rgb = np.full((height, width, 3), 255.0, dtype=np.float32)
        self._share = np.zeros(width * height, dtype=np.float32)  # zero between paints

    def paint(self, parts: Iterable[Pixels], colour: str, alpha: float = 1.0,
              clip: tuple[int, int, int, int] | None = None) -> None:
        """Blend ``colour`` over the pixels ``(rows, cols, share)`` of every part (one
        artist) at ``alpha`` × the largest share any part gives each (within ``clip`` =
        (row0, col0, row1, col1), else the picture)."""
        r0, c0, r1, c1 = clip or (0, 0, self.height, self.width)
        low, high = self.height, -1  # the rows touched
        for rows, cols, share in parts:
            inside = (rows >= r0) & (rows < r1) & (cols >= c0) & (cols < c1)
            if not inside.any():
                continue
            kept = rows[inside]
            np.maximum.at(self._share, kept * self.width + cols[inside],  # the largest share
                          share[inside].astype(np.float32))
            low, high = min(low, int(kept.min())), max(high, int(kept.max()))
        if high < 0:
            return
        flat = low * self.width + np.flatnonzero(
            self._share[low * self.width:(high + 1) * self.width])
        a = alpha * self._share[flat][:, None]
        self._share[flat] = 0.0
        pixels = self.rgb.reshape(-1, 3)
        pixels[flat] = (1.0 - a) * pixels[flat] + a * np.asarray(COLOURS[colour], np.float32)

    def lines(self, a: np.ndarray, b: np.ndarray, colour: str, width_pt: float,
              alpha: float = 1.0, clip: tuple[int, int, int, int] | None = None) -> None:
        """Segments ``a`` → ``b`` (pixels), ``width_pt`` wide, as one artist (in parts of
        at most :data:`PART_PIXELS` pixels to look at)."""
        width = px(width_pt)
        reach = max(0.5 * width, 0.5) + 0.5
        across = math.ceil(2.0 * reach * math.sqrt(2.0) + 1.5)
        lines = np.ceil(np.maximum(np.abs(b[:, 0] - a[:, 0]), np.abs(b[:, 1] - a[:, 1]))
                        + 2 * reach + 1).astype(np.int64)
        self.paint((segment_pixels(a[part], b[part], width)
                    for part in _parts(lines, PART_PIXELS // across)), colour, alpha, clip)

    def markers(self, centres: np.ndarray, marker: str, colour: str, size_pt: float,
                width_pt: float = 1.0, alpha: float = 1.0,
                clip: tuple[int, int, int, int] | None = None) -> None:
        """Markers at ``centres`` (pixels), as one artist: each centre rounded to
        1/:data:`MARKER_GRID` of a pixel, each place once, stamped with its fraction's
        :func:`marker_pixels` (computed once a fraction) in parts of at most
        :data:`PART_PIXELS` pixels."""
        size, width = px(size_pt), px(width_pt)
        grid = distinct_rows(np.round(np.asarray(centres, dtype=np.float64) * MARKER_GRID)
                             ).astype(np.int64)
        if len(grid) == 0:
            return
        pixel, fraction = np.divmod(grid, int(MARKER_GRID))
        variant = fraction[:, 0] * int(MARKER_GRID) + fraction[:, 1]
        order = np.argsort(variant, kind="stable")
        pixel, variant = pixel[order], variant[order]
        bounds = np.flatnonzero(np.r_[True, variant[1:] != variant[:-1], True])

        def parts() -> Iterator[Pixels]:
            for lo, hi in zip(bounds[:-1].tolist(), bounds[1:].tolist(), strict=True):
                f = np.divmod(int(variant[lo]), int(MARKER_GRID))
                rows, cols, share = marker_pixels(np.array([f]) / MARKER_GRID, marker, size,
                                                  width)
                for part in _parts(np.full(hi - lo, len(share)), PART_PIXELS):
                    base = pixel[lo:hi][part]
                    yield ((base[:, 1, None] + rows[None]).ravel(),
                           (base[:, 0, None] + cols[None]).ravel(),
                           np.broadcast_to(share, (len(base), len(share))).ravel())

        self.paint(parts(), colour, alpha, clip)

    def text(self, x: float, y: float, text: str, size: str = "normal", ha: str = "left",
             va: str = "baseline", vertical: bool = False, colour: str = "black") -> float:
        """Write ``text`` with its anchor at pixel ``(x, y)``: ``ha`` left, center or right
        of its width, ``va`` baseline, top or center of its letters' height (the atlas's
        line); ``vertical``: turned a quarter left, read upwards. Returns its width."""
        alpha, baseline, width = text_alpha(text, size)
        f = font(size)
        height = px(SIZES[size])
        left = x - {"left": 0.0, "center": 0.5, "right": 1.0}[ha] * width - f.origin
        top = y - baseline + {"baseline": 0.0, "top": 0.75 * height,
                              "center": 0.375 * height}[va]
        if vertical:  # turned about the anchor: rows become columns, read upwards
            alpha = np.rot90(alpha)
            dx, dy = left - x, top - y
            left, top = x + dy, y - dx - alpha.shape[0]
        r0, c0 = round(top), round(left)
        rows, cols = np.nonzero(alpha)
        self.paint([(rows + r0, cols + c0, alpha[rows, cols])], colour)
        return width


def nice_ticks(low: float, high: float, most: int) -> np.ndarray:
    """Ticks in [low, high] at a step of 1, 2, 2.5 or 5 × 10^k, the least giving at most
    ``most`` intervals over the span (matplotlib's ``MaxNLocator`` steps)."""
    span = high - low
    if not span > 0:
        return np.array([low])
    raw = span / max(most, 1)
    scale = 10.0 ** math.floor(math.log10(raw))
    step = next(s * scale for s in (1.0, 2.0, 2.5, 5.0, 10.0) if s * scale >= raw * (1 - 1e-9))
    first = math.ceil(low / step - 1e-9)
    last = math.floor(high / step + 1e-9)
    return np.arange(first, last + 1) * step


def tick_label(value: float, step: float) -> str:
    """``value`` with as many decimals as the ticks' ``step`` needs (a minus sign as
    matplotlib writes it)."""
    decimals = max(0, -math.floor(math.log10(step) + 1e-9)) if step > 0 else 0
    while decimals < 12 and abs(round(step, decimals) - step) > 1e-9 * step:
        decimals += 1  # 2.5 × 10^k needs one more
    text = f"{value:.{decimals}f}"
    return "0" if float(text) == 0 else text.replace("-", "−")


@dataclass(frozen=True)
class Axes:
    """Metres onto pixels: the extent ``(xmin, ymin, xmax, ymax)`` shown at equal scale in
    the largest box the figure's ``frame`` (left, right, bottom, top as shares of the
    figure, matplotlib's ``subplots_adjust``) holds, centred in it."""

    extent: tuple[float, float, float, float]
    left: float
    top: float
    scale: float  # pixels a metre
    width: float
    height: float

    @classmethod
    def fit(cls, canvas: Canvas, extent: tuple[float, float, float, float],
            frame: dict[str, float]) -> Axes:
        xmin, ymin, xmax, ymax = extent
        w = (frame["right"] - frame["left"]) * canvas.width
        h = (frame["top"] - frame["bottom"]) * canvas.height
        scale = min(w / (xmax - xmin), h / (ymax - ymin))
        bw, bh = scale * (xmax - xmin), scale * (ymax - ymin)
        left = frame["left"] * canvas.width + 0.5 * (w - bw)
        top = (1.0 - frame["top"]) * canvas.height + 0.5 * (h - bh)
        return cls(extent, left, top, scale, bw, bh)

    def pixels(self, xy: np.ndarray) -> np.ndarray:
        """Points [n, 2] in metres as pixel coordinates."""
        xy = np.asarray(xy, dtype=np.float64).reshape(-1, 2)
        return np.stack([self.left + (xy[:, 0] - self.extent[0]) * self.scale,
                         self.top + (self.extent[3] - xy[:, 1]) * self.scale], axis=1)

    @property
    def clip(self) -> tuple[int, int, int, int]:
        """The box's pixels (row0, col0, row1, col1)."""
        return (math.floor(self.top), math.floor(self.left),
                math.ceil(self.top + self.height), math.ceil(self.left + self.width))

    def segments(self, canvas: Canvas, a: np.ndarray, b: np.ndarray, colour: str,
                 width_pt: float, alpha: float = 1.0) -> None:
        """The segments ``a`` → ``b`` ([n, 2] metres each), clipped to the box."""
        canvas.lines(self.pixels(a), self.pixels(b), colour, width_pt, alpha, self.clip)

    def polyline(self, canvas: Canvas, xy: np.ndarray, colour: str, width_pt: float,
                 alpha: float = 1.0) -> None:
        """The polyline through ``xy`` [n, 2] metres, clipped to the box."""
        self.segments(canvas, xy[:-1], xy[1:], colour, width_pt, alpha)

    def markers(self, canvas: Canvas, xy: np.ndarray, marker: str, colour: str,
                size_pt: float, width_pt: float = 1.0, alpha: float = 1.0) -> None:
        """Markers at ``xy`` [n, 2] metres, clipped to the box."""
        canvas.markers(self.pixels(xy), marker, colour, size_pt, width_pt, alpha, self.clip)

    def frame(self, canvas: Canvas, xlabel: str, ylabel: str, title: str) -> None:
        """The box, its ticks outwards with their labels, the axis labels and the title,
        as matplotlib's defaults draw them (0.8 pt lines, 3.5 pt ticks, 10 pt text)."""
        x0, y0 = self.left, self.top
        x1, y1 = x0 + self.width, y0 + self.height
        corners = np.array([[x0, y1], [x1, y1], [x1, y0], [x0, y0], [x0, y1]])
        canvas.lines(corners[:-1], corners[1:], "black", 0.8)
        xmin, ymin, xmax, ymax = self.extent
        font_px, tick, pad = px(SIZES["normal"]), px(3.5), px(3.5)
        xt = nice_ticks(xmin, xmax, int(np.clip(self.width / (3 * font_px), 1, 9)))
        yt = nice_ticks(ymin, ymax, int(np.clip(self.height / (2 * font_px), 1, 9)))
        tx = self.pixels(np.stack([xt, np.full(len(xt), ymin)], axis=1))[:, 0]
        ty = self.pixels(np.stack([np.full(len(yt), xmin), yt], axis=1))[:, 1]
        canvas.lines(np.stack([tx, np.full(len(tx), y1)], 1),
                     np.stack([tx, np.full(len(tx), y1 + tick)], 1), "black", 0.8)
        canvas.lines(np.stack([np.full(len(ty), x0), ty], 1),
                     np.stack([np.full(len(ty), x0 - tick), ty], 1), "black", 0.8)
        xstep = xt[1] - xt[0] if len(xt) > 1 else 1.0
        ystep = yt[1] - yt[0] if len(yt) > 1 else 1.0
        for v, x in zip(xt, tx, strict=True):
            canvas.text(x, y1 + tick + pad, tick_label(v, xstep), ha="center", va="top")
        widest = max((canvas.text(x0 - tick - pad, y, tick_label(v, ystep), ha="right",
                                  va="center") for v, y in zip(yt, ty, strict=True)),
                     default=0.0)
        canvas.text(0.5 * (x0 + x1), y1 + tick + 2 * pad + 1.2 * font_px, xlabel,
                    ha="center", va="top")
        canvas.text(x0 - tick - 2 * pad - widest - 0.3 * font_px, 0.5 * (y0 + y1), ylabel,
                    ha="center", va="baseline", vertical=True)
        canvas.text(0.5 * (x0 + x1), y0 - px(6.0), title, ha="center", va="baseline")


@dataclass(frozen=True)
class Entry:
    """A legend entry: its ``label`` and how its sample is drawn (a line of ``colour``
    when ``line_pt`` > 0, a marker when ``marker``)."""

    label: str
    colour: str
    marker: str = ""
    size_pt: float = 0.0
    width_pt: float = 1.0
    line_pt: float = 0.0
    alpha: float = 1.0


def legend(canvas: Canvas, entries: list[Entry], centre_x: float, top: float) -> None:
    """The entries in one row centred at ``centre_x`` with their top at ``top`` (pixels),
    in the small font: a sample 2 em long, 0.8 em to its label, 2 em between entries
    (matplotlib's legend spacing, no frame)."""
    if not entries:
        return
    em = px(SIZES["small"])
    widths = [2.0 * em + 0.8 * em + text_alpha(e.label, "small")[2] for e in entries]
    x = centre_x - 0.5 * (sum(widths) + 2.0 * em * (len(entries) - 1))
    y = top + 0.7 * em  # the row's middle
    for e, w in zip(entries, widths, strict=True):
        if e.line_pt > 0:
            canvas.lines(np.array([[x, y]]), np.array([[x + 2.0 * em, y]]), e.colour,
                         e.line_pt, e.alpha)
        if e.marker:
            canvas.markers(np.array([[x + em, y]]), e.marker, e.colour, e.size_pt,
                           e.width_pt, e.alpha)
        canvas.text(x + 2.8 * em, y, e.label, "small", va="center")
        x += w + 2.0 * em


__all__ = ["COLOURS", "DPI", "PART_PIXELS", "SIZES", "Axes", "Canvas", "Entry", "cover", "font",
           "legend", "marker_pixels", "nice_ticks", "px", "segment_pixels", "text_alpha",
           "tick_label"]
