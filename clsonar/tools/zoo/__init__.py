"""The scene zoo (issue 14 item 6): scenes of every kind a user writes — rooms scanned by
rings placed by hand or by ``wall-following``, ``per-wall`` arrays, corridors, walls,
corners, edges, cylinders, sinusoids and thin posts seen by linear arrays at any angle —
each run with the default settings and scored against :data:`THRESHOLDS`.

- :func:`zoo`: the cases drawn from a seed (:mod:`.cases`, :mod:`.rooms`, :mod:`.targets`);
- :func:`score`: a run's map given, accuracy, completeness within 3 cm, worst vertex in view
  and seconds, each against its threshold (:mod:`.score`, :mod:`.thresholds`);
- :func:`run_zoo`: every case on one OpenCL context, written to ``zoo.md`` and ``zoo.json``
  (:mod:`.report`; ``clsonar zoo``). docs/zoo.md describes it.
"""

from .cases import COUNTS, MAX_CELLS, ZooCase, zoo
from .thresholds import CRITERIA, KINDS, NOISES, SCANS, THRESHOLDS, Thresholds

__all__ = ["COUNTS", "CRITERIA", "KINDS", "MAX_CELLS", "NOISES", "SCANS", "THRESHOLDS",
           "Thresholds", "ZooCase", "zoo"]
