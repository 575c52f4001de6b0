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

#: The scenes ``clsonar bench --methods`` compares every mapping mode on by default
#: (:mod:`.methods`): the thesis' shapes at one distance each, the bundled rooms
#: (rectangular, L-shaped, with a cylinder), and one case of each kind of the scene zoo of
#: seed 0 (``zoo:SEED:KIND:INDEX``) that is cheap for every mode — a wall, a corner and an
#: edge seen by arrays, a cylinder by a ``random-lines`` placement, a sinusoid, a thin post,
#: a room and a corridor scanned by rings written by hand. (Not the cylinder of 80 elements,
#: zoo:0:cylinder:1: triangulation takes about 9 minutes there.)
METHODS_SCENES = ("plane-2m", "corner-4m", "edge-1m", "cylinder-2.1m", "sinusoid-1m",
                  "room", "room-l", "room-cylinder",
                  "zoo:0:wall:0", "zoo:0:corner:5", "zoo:0:edge:4", "zoo:0:cylinder:3",
                  "zoo:0:sinusoid:1", "zoo:0:post:2", "zoo:0:room:4", "zoo:0:corridor:7")

#: Noise σ of the received signals in ``clsonar bench --methods`` (``signal.noise_std``).
METHODS_NOISE = (0.0, 0.6, 1.2)
