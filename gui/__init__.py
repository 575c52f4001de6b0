"""The desktop GUI (PySide6 + pyqtgraph): scene editor, sensor placement, runs, stage views.

A thin shell over the core API (docs/design.md: "The GUI and the CLI are thin shells: no
physics lives in them"). The core package never imports this one. ``clsonar-gui`` starts
:func:`main`, which imports no Qt until it has checked that the ``clsonar[gui]`` extra is
installed, then runs :func:`clsonar.gui.app.main`.
"""

from __future__ import annotations

import importlib.util
import sys

#: The packages the desktop app needs (the ``clsonar[gui]`` extra).
QT_PACKAGES = ("PySide6", "pyqtgraph")


def main(argv: list[str] | None = None) -> int:
    """``clsonar-gui``: one error line and status 2 when PySide6 or pyqtgraph is missing,
    else the app (:func:`clsonar.gui.app.main`)."""
    if any(importlib.util.find_spec(name) is None for name in QT_PACKAGES):
        from ..cli import EXIT_USAGE

        print("clsonar-gui: error: the desktop app needs PySide6 and pyqtgraph: "
              "pip install 'clsonar[gui]'", file=sys.stderr)
        return EXIT_USAGE
    from .app import main as app_main

    return app_main(argv)
