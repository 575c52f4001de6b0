"""``python -m clsonar.tools.faults``: the fault-injection table (docs/faults.md)."""

from . import main

if __name__ == "__main__":  # importing the module (tests walk every module) runs nothing
    raise SystemExit(main())
