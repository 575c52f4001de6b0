"""``python -m clsonar.tools.faults``: the fault-injection table (docs/faults.md)."""

from . import main

raise SystemExit(main())
