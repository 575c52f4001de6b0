"""``clsonar sweep``: Monte-Carlo sweeps of the pipeline, locally or on a Dask cluster.

A **sweep spec** (TOML or JSON, ``docs/sweep.md``) names base scenes, a parameter grid and
seeds; every (scene, grid point, seed) is one run of :func:`clsonar.pipeline.run`, and every
run is one row of a tidy table (parameters, seed, metrics, per-stage seconds, device, host).
The statistics are those the thesis plots against distance and noise (chapter 3, Figs 3.5,
3.6, 3.19, 3.20: RMS of eq. 2.6 over seeds).

- Grid keys are scene-file key paths (scene format v1, ``docs/scene-format.md``):
  ``signal.noise_std``, ``sensors.placement.distance_m``, ``surfaces[0].radius``. Each value
  is set in the scene's full dict (:func:`~clsonar.scene.scene_to_dict`) and the result is
  validated by :func:`~clsonar.scene.scene_from_dict`, so a wrong value fails with the scene
  loader's own message. Two more keys are not scene keys: ``preset`` (``thesis``/``best``,
  :data:`clsonar.pipeline.PRESETS`) and ``distance_m`` (a ``random-lines`` placement moved
  to that distance from the surface, :func:`clsonar.tools.variants.at_distance`; the scene entry
  declares its own distance).
- Seed ``k`` advances the placement and noise seeds by ``k``
  (:func:`clsonar.tools.variants.with_seed`), as ``clsonar reproduce`` does.
- Every run has a stable id, a hash of its final scene, preset, parameters and seed. Rows go
  to ``DIR/runs.jsonl`` as they finish: one line each, written with ``O_APPEND`` and
  ``fsync``, and cut back when the write fails (a full disk: one line, exit 2); a line
  without its newline (a write cut short by a kill) is dropped when the table is read. So
  an interrupted sweep, run again, skips every finished run and redoes only the missing
  ones; ``DIR/table.csv`` (one row per planned run, in plan order) is rewritten atomically
  when a sweep stops, finished or not.
- Locally every run shares one OpenCL context (:func:`run_local`). With a Dask cluster
  (:func:`run_dask`) each worker builds its context once (:func:`worker_context`) and reuses
  it; rows stream back into the same table as runs finish; a worker that dies loses only its
  in-flight runs, which the scheduler gives to another worker (one that dies on every try,
  or a cluster that goes away, ends the sweep in one line, the finished rows kept).

The package: :mod:`.spec` reads and validates a spec, :mod:`.plan` expands it into runs,
:mod:`.table` keeps their rows, :mod:`.runners` runs them.
"""

from .plan import Run, load_spec, make_run, plan, run_id
from .runners import (
    CONTEXTS,
    ProgressBar,
    RunProgress,
    connect,
    run_dask,
    run_local,
    run_one,
    sweep,
    worker_context,
)
from .spec import (
    DEFAULT_METRICS,
    KNOWN_METRICS,
    PSEUDO_KEYS,
    SceneEntry,
    Spec,
    SpecError,
    parse_key_path,
    read_spec,
    set_key,
)
from .table import (
    SWEEP_JSON,
    TABLE_CSV,
    TABLE_JSONL,
    RunTable,
    SweepLock,
    columns,
    metric_value,
    read_sweep,
    row_of,
    table_csv,
)

__all__ = [
    "CONTEXTS", "DEFAULT_METRICS", "KNOWN_METRICS", "PSEUDO_KEYS", "SWEEP_JSON", "TABLE_CSV",
    "TABLE_JSONL", "ProgressBar", "Run", "RunProgress", "RunTable", "SceneEntry", "Spec",
    "SpecError", "SweepLock", "columns", "connect", "load_spec", "make_run", "metric_value",
    "parse_key_path", "plan", "read_spec", "read_sweep", "row_of", "run_dask", "run_id",
    "run_local", "run_one", "set_key", "sweep", "table_csv", "worker_context",
]
