"""Sweeps: one graph over many missions, seeds and parameter variants, on Dask distributed.

    spec = load_sweep("graphs/sweeps/rslam-search.yaml")   # the sweep file, validated, located
    outcome = run_sweep(spec, "out/sweep")                  # a LocalCluster; scheduler="tcp://..." for a cluster

The engine knows nothing of this package; only :mod:`.runner` imports ``distributed``, and
only when a sweep runs (``impala-flow sweep``).
"""

from __future__ import annotations

from typing import Any

from .check import check_sweep
from .results import FIGURE, RESULTS, SUMMARY, Results, columns
from .spec import SweepError, SweepSpec, Task, load_sweep
from .task import SweepContext, run_task, simulate_mission

__all__ = ["load_sweep", "SweepSpec", "SweepError", "Task", "check_sweep", "run_sweep", "SweepOutcome",
           "SweepContext", "run_task", "simulate_mission", "Results", "columns", "RESULTS", "SUMMARY", "FIGURE"]


def __getattr__(name: str) -> Any:  # the runner (and so Dask) only when asked for
    if name in ("run_sweep", "SweepOutcome", "mission_file"):
        from . import runner

        return getattr(runner, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
