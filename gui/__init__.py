"""The desktop GUI (PySide6 + pyqtgraph): scene editor, sensor placement, runs, stage views.

A thin shell over the core API (DESIGN.md: "The GUI and the CLI are thin shells: no physics
lives in them"). The core package never imports this one; ``clsonar-gui`` starts
:func:`clsonar.gui.app.main`.
"""
