"""``python -m clsonar.tools.glyphs``: the glyph atlas (``clsonar/glyphs.npz``) that
:mod:`clsonar.canvas` writes its text with: every character of :data:`CHARS`, DejaVu Sans
(matplotlib's default font, Bitstream Vera licence) at each of :data:`SIZES` points and
:data:`~clsonar.canvas.DPI`, anti-aliased by matplotlib's Agg renderer — so a run draws
scene.png and profile.png with matplotlib's letters without importing matplotlib.

Each size is stored as ``<size>_alpha`` [characters, rows, columns] (8-bit coverage; each
glyph drawn with its origin at column ``<size>_origin`` on row ``<size>_baseline``) and
``<size>_advance`` [characters] (pixels the pen moves on); ``chars`` lists the characters.
"""

from __future__ import annotations

import argparse
import io
import math
import sys
from pathlib import Path

import numpy as np

from ..canvas import DPI, SIZES

#: The characters drawn: printable ASCII and the few others the plots' titles may hold.
CHARS = "".join(chr(c) for c in range(32, 127)) + "°µσ×–−·²±≤≥"


def atlas(size_pt: float) -> dict[str, np.ndarray]:
    """Every character of :data:`CHARS` at ``size_pt`` points (:func:`glyph` each)."""
    from matplotlib.backends.backend_agg import RendererAgg
    from matplotlib.font_manager import FontProperties, findfont, get_font

    prop = FontProperties(family="DejaVu Sans", size=size_pt)
    font = get_font(findfont(prop))
    font.set_size(size_pt, DPI)
    px = size_pt * DPI / 72
    origin, baseline = math.ceil(0.3 * px), math.ceil(1.2 * px)
    rows, cols = baseline + math.ceil(0.45 * px), origin + math.ceil(1.6 * px)
    alpha = np.zeros((len(CHARS), rows, cols), dtype=np.uint8)
    advance = np.zeros(len(CHARS))
    for k, ch in enumerate(CHARS):
        renderer = RendererAgg(cols, rows, DPI)
        gc = renderer.new_gc()
        gc.set_foreground("black")
        renderer.draw_text(gc, origin, baseline, ch, prop, 0)
        alpha[k] = np.asarray(renderer.buffer_rgba())[:, :, 3]
        advance[k] = font.load_char(ord(ch)).horiAdvance / 64
    return {"alpha": alpha, "advance": advance, "origin": np.array(origin),
            "baseline": np.array(baseline)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m clsonar.tools.glyphs",
                                     description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default=str(Path(__file__).parents[1] / "glyphs.npz"))
    args = parser.parse_args(argv)
    arrays: dict[str, np.ndarray] = {"chars": np.array(CHARS)}
    for name, size_pt in SIZES.items():
        arrays.update({f"{name}_{key}": value for key, value in atlas(size_pt).items()})
    buf = io.BytesIO()
    np.savez_compressed(buf, allow_pickle=False, **arrays)
    Path(args.out).write_bytes(buf.getvalue())
    print(f"{args.out}: {len(CHARS)} characters at {', '.join(map(str, SIZES.values()))} pt, "
          f"{len(buf.getvalue()) // 1024} kB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
