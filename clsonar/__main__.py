"""``python -m clsonar`` is the ``clsonar`` command."""

from .cli import main

raise SystemExit(main())
