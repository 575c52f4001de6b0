"""Work the pipeline leaves out because a scene does not need it (:class:`Skips`), and the
names ``clsonar run --no-skip`` takes. Kept apart from :mod:`clsonar.pipeline` so that the
command line can offer the names without importing the pipeline."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass


@dataclass(frozen=True)
class Skips:
    """Work the pipeline leaves out because the scene does not need it; none of it changes
    the result. A switch set False does that work anyway, so ``clsonar bench`` can show
    what each saves; ``report.json`` counts what was skipped (``counts``)."""

    #: echoes: pairs whose beams meet no surface are not evaluated (echoes.pairs_in_view)
    empty_pairs: bool = True
    #: detection: pairs without an echo are not scanned (signals.scanned_slots), where no
    #: threshold can be reached by the noise (signals.noise_stays_quiet: noise-free, or
    #: every threshold 10 noise scales up)
    silent_pairs: bool = True
    #: detection: there, only the chunks of samples an echo reaches are synthesised and
    #: scanned (the rest of every signal is 0, or noise that reaches no threshold)
    quiet_samples: bool = True
    #: accumulation: loci drawn tile by tile, empty tiles skipped (mapping.accumulate)
    tiles: bool = True
    #: post-processing: only the box of the voted cells is filtered and thinned
    #: (post.voted_box; line of sight's own pass too)
    empty_cells: bool = True
    #: separate closed rooms mapped one by one (regions.split_rooms): no pair across rooms,
    #: no wall of another room, no cell outside every room
    rooms: bool = True

    @classmethod
    def none(cls) -> Skips:
        """Every switch off: the work a scene does not need is done anyway."""
        return cls(**{f.name: False for f in dataclasses.fields(cls)})


SKIP_NAMES = tuple(f.name for f in dataclasses.fields(Skips))


__all__ = ["SKIP_NAMES", "Skips"]
