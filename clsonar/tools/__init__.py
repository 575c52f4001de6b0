"""Tools that use the pipeline: benchmarks (:mod:`.bench`, :mod:`.tradeoff`, :mod:`.floors`),
the thesis' experiments (:mod:`.reproduce`, on scene variants from :mod:`.variants`),
Monte-Carlo sweeps (the :mod:`.sweep` package, :mod:`.sweepplot`), numerical stability (the
:mod:`.stability` package, :mod:`.stress`), the scene loader's fuzzer (:mod:`.fuzz`) and the
scene zoo that scores the default settings (the :mod:`.zoo` package);
:mod:`.progress` and :mod:`.markdown` are their shared progress line and table cells. The
pipeline never imports them; they never import the GUI, and import matplotlib (through
:mod:`clsonar.plots`) only when they draw.
"""
