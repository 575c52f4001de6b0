"""Numbers in the tools' markdown tables: a dash where there is none."""

from __future__ import annotations

#: What a table shows where a value is missing.
NONE = "–"


def cm(value: float | None) -> str:
    """Metres as centimetres with two decimals (``0.0123`` → ``1.23``)."""
    return NONE if value is None else f"{value * 100:.2f}"


def percent(share: float | None, decimals: int = 0) -> str:
    """A share as a percentage (``0.5`` → ``50 %``)."""
    return NONE if share is None else f"{share * 100:.{decimals}f} %"
