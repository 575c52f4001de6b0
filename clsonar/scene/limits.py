"""The reader's limits (docs/scene-format.md, "Limits"): a file beyond them is refused with
one line naming the key, before it could exhaust memory or take longer than a second to
check. (The largest file read is :data:`clsonar.files.MAX_FILE_BYTES`.)"""

from __future__ import annotations

#: Deepest JSON nesting accepted (the format needs 5 levels).
MAX_DEPTH = 16

#: Most JSON objects and lists (``{``/``[``, counted before parsing, strings included) and
#: most list items (``,``) a scene may have: 50 000 points of polylines, so that any file is
#: parsed and checked well within a second.
MAX_CONTAINERS = 50_000
MAX_SEPARATORS = 200_000

#: Largest magnitude of a real-valued setting or coordinate (metres, seconds, hertz, …):
#: anything beyond is a typo, and would overflow the geometry's float64 products.
MAX_MAGNITUDE = 1e9

#: Shortest wall segment, sinusoid base line and circle radius, metres (shorter ones
#: underflow the geometry's squared lengths).
MIN_LENGTH_M = 1e-6

#: Most cells a map may have along x or y: more is refused on reading (a grid too large for
#: any memory; mapping.check_map_memory judges the device and this machine).
MAX_CELLS_PER_SIDE = 1e9

#: Most wall sequences (walls to the power echo.max_order) and explicitly fired pairs
#: (the sum of each group's size squared) a scene may ask for: more would not fit in memory.
MAX_WALL_SEQUENCES = 10**7
MAX_EXPLICIT_PAIRS = 10**7

#: Most sampling intervals of all sinusoids together (their lengths / echo.curve_step_m).
MAX_CURVE_SAMPLES = 10**6

#: Most circles in a scene (sensor placement tests every pose against every surface).
MAX_CIRCLES = 1000
