"""The tools' defaults, where the command line can read them without importing the tools
(and the pipeline they import): the command's ``--help`` and its argument checks."""

#: The scenes ``clsonar bench`` runs by default: the thesis' shapes at their first distance
#: and rooms.
BENCH_SCENES = ("plane-2m", "corner-4m", "edge-1m", "cylinder-2.1m", "sinusoid-1m", "room",
                "room-cylinder")

#: Timed runs of each benchmark measurement (the best is kept).
BENCH_REPEAT = 3

#: Sizes in metres of the multi-room floors benchmarked by default (:mod:`.floors`).
BENCH_FLOORS = (50.0,)

#: Runs per experiment of ``clsonar reproduce`` (placement and noise seeds 0, 1, … added).
REPRODUCE_SEEDS = 5

#: The kinds of scene of ``clsonar zoo``, in the order its report lists them.
ZOO_KINDS = ("room", "corridor", "wall", "corner", "edge", "cylinder", "sinusoid", "post")
