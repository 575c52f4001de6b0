"""Tools that use the pipeline: benchmarks (:mod:`.bench`, :mod:`.tradeoff`, :mod:`.floors`),
the thesis' experiments (:mod:`.reproduce`), Monte-Carlo sweeps (:mod:`.sweep`,
:mod:`.sweepplot`), numerical stability (:mod:`.stability`, :mod:`.stress`) and the scene
loader's fuzzer (:mod:`.fuzz`). The pipeline never imports them; they never import the GUI.
"""
