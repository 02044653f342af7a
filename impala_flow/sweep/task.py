"""What runs on a worker: simulate a mission, run one task's graph, return its row.

Nothing here imports Dask: these are plain functions the runner submits, and a test or a
plain loop can call them directly. Missions are never shipped through the scheduler: a
simulated one is written by the worker to the sweep's folder (shared storage on a
cluster) and only its path travels; a recorded one is read from its path.
"""

from __future__ import annotations

import contextlib
import ctypes
import io
import json
import math
import os
import socket
import sys
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .folder import remove_own
from .spec import SweepError, Task

__all__ = ["SweepContext", "simulate_mission", "run_task", "one_line", "RUN_LOG", "RUN_SUMMARY"]

#: files the sweep writes in each task's folder, beside what the graph writes there (${out})
RUN_LOG, RUN_SUMMARY = "run.log", "run-summary.json"


@dataclass(frozen=True)
class SweepContext:
    """What every task of a sweep shares (absolute paths: the workers' working folder is theirs)."""

    graph: str
    out_dir: str
    metrics: tuple[str, ...]
    variables: dict[str, Any] = field(default_factory=dict)

    def task_dir(self, task: Task) -> Path:
        return Path(self.out_dir) / "tasks" / task.id


#: what Dask's nanny sets MALLOC_TRIM_THRESHOLD_ to in the workers it starts (distributed.yaml)
_DASK_MALLOC_TRIM = "65536"
_malloc_tuned = False


def undo_dask_malloc_trim() -> bool:
    """Give glibc's allocator back its speed in a Dask worker (once per process; True if done).

    Dask's nanny starts workers with ``MALLOC_TRIM_THRESHOLD_=65536``; glibc then stops
    adapting its mmap threshold, so every large numpy array is mmap'd and page-faulted anew:
    the radar graphs run about twice slower (R-SLAM's matching 130 ms per turn instead of
    50). This sets the ceiling the adaptive threshold would reach (mmap above 32 MiB, trim
    above 64 MiB). A local sweep's cluster does not set the variable at all; this covers
    workers started by ``dask worker`` with Dask's default configuration. Another value,
    set on purpose, is left alone. Memory use per worker may stay up to 64 MiB higher."""
    global _malloc_tuned
    if _malloc_tuned or os.environ.get("MALLOC_TRIM_THRESHOLD_") != _DASK_MALLOC_TRIM \
            or not sys.platform.startswith("linux"):
        return False
    _malloc_tuned = True
    try:
        mallopt = ctypes.CDLL(None).mallopt  # the process's C library
    except (OSError, AttributeError):  # not glibc: nothing to undo
        return False
    m_trim_threshold, m_mmap_threshold = -1, -3  # <malloc.h>
    return bool(mallopt(m_mmap_threshold, 32 << 20)) and bool(mallopt(m_trim_threshold, 64 << 20))


def one_line(e: BaseException | str) -> str:
    """An error as one line: its message (type name when empty), line breaks joined by '; '."""
    if isinstance(e, str):
        text = e
    else:
        problems = getattr(e, "problems", None)  # a GraphError: every problem, located
        text = "; ".join(str(p) for p in problems) if problems else (str(e).strip() or type(e).__name__)
        if not problems and type(e).__name__ not in text and not isinstance(e, (ValueError, RuntimeError)):
            text = f"{type(e).__name__}: {text}"
    return "; ".join(s.strip() for s in text.strip().splitlines() if s.strip())


@contextlib.contextmanager
def _captured(log: Path) -> Iterator[io.TextIOBase]:
    """Send what the task prints (summaries, warnings) to its log file, not the worker's
    terminal: a local cluster's workers share the user's. One thread per worker keeps
    tasks' logs apart (the default); with more threads a line may land in a neighbour's log."""
    with open(log, "a", encoding="utf-8") as f, contextlib.redirect_stderr(f), contextlib.redirect_stdout(f):
        yield f


def simulate_mission(scenario: str, seed: int | None, duration_s: float | None, path: str) -> dict[str, Any]:
    """Simulate a scenario into ``path`` through the ``simulate`` command the radar plugin
    installs, exactly as ``impala-flow simulate SCENARIO -o PATH --seed N --duration Xs`` does
    (so the file is byte for byte the command's). A file already there is reused: several
    variants share a mission, and a rescheduled task finds it. Returns ``{"path", "error",
    "wall_s"}``; never raises for a simulation that fails (the tasks of that mission report it)."""
    t0 = time.perf_counter()
    undo_dask_malloc_trim()
    out = Path(path)
    if out.is_file():
        return {"path": str(out), "error": None, "wall_s": 0.0}
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.{os.getpid()}-{threading.get_ident()}.part")  # renamed when complete
    argv = ["simulate", scenario, "-o", str(tmp), "--no-progress"]
    if seed is not None:
        argv += ["--seed", str(seed)]
    if duration_s is not None:
        argv += ["--duration", f"{duration_s!r}s"]
    error = None
    with _captured(out.with_suffix(".log")) as log:
        try:
            code = _call_command(argv, log)
            if code != 0:
                error = f"impala-flow {' '.join(argv[:2])}: exit {code}"
            else:
                os.replace(tmp, out)
        except Exception as e:
            error = f"simulating {scenario} (seed {seed}): {one_line(e)}"
        finally:
            tmp.unlink(missing_ok=True)
    return {"path": str(out), "error": error, "wall_s": time.perf_counter() - t0}


def _call_command(argv: list[str], log: io.TextIOBase) -> int:
    """Run an ``impala-flow`` subcommand in this process (plugin commands included)."""
    from ..cli import CommandError, make_parser

    parser = make_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as e:  # argparse printed why to the log
        raise RuntimeError(f"impala-flow {argv[0]}: invalid arguments or command not installed "
                           f"(exit {e.code}; is the plugin providing '{argv[0]}' installed?)") from None
    try:
        return int(args.func(args) or 0)
    except CommandError as e:
        raise RuntimeError(str(e)) from None


def base_row(task: Task) -> dict[str, Any]:
    row: dict[str, Any] = {"task": task.id, "mission": task.mission, "seed": task.seed,
                           "duration_s": task.duration_s, "repeat": task.repeat, "variant": task.variant}
    row.update(dict(task.params))
    return row


def worker_name() -> str:
    """The process a task ran in: ``host:pid``."""
    return f"{socket.gethostname()}:{os.getpid()}"


def failed_row(task: Task, error: str, wall_s: float | None = None, worker: str | None = None) -> dict[str, Any]:
    return {**base_row(task), "status": "failed", "error": one_line(error), "wall_s": wall_s, "worker": worker}


def run_task(task: Task, ctx: SweepContext, mission: dict[str, Any] | None = None) -> dict[str, Any]:
    """Run ``task``'s graph in this process; return its row: the task's mission, seed and
    parameters, each metric, the counters (samples, lost, mission_s), wall_s, status and a
    one-line error and the worker (``host:pid``). A graph that is invalid or fails gives a ``failed`` row, never an
    exception. ``mission`` is :func:`simulate_mission`'s result for a simulated mission.

    The folder ``tasks/<id>/`` of the sweep is the graph's ``${out}``; it also gets
    :data:`RUN_SUMMARY` (the run summary as ``--summary-json`` writes it) and :data:`RUN_LOG`."""
    from .._session import Session
    from .._spec import GraphError
    from .._summary import ComponentError
    from .._yamlloc import YamlError

    t0 = time.perf_counter()
    undo_dask_malloc_trim()
    folder = ctx.task_dir(task)
    try:
        # a task run again (resumed, or rescheduled after a worker died) starts clean: only its
        # own folder, one safe name inside the sweep's tasks/ (folder.remove_own refuses the rest)
        remove_own(Path(ctx.out_dir), task.id, "tasks")
        folder.mkdir(parents=True)
    except (SweepError, OSError) as e:
        return failed_row(task, f"task folder {folder}: {one_line(e)}", worker=worker_name())
    if task.simulated:
        if mission is None:
            return failed_row(task, "no simulated mission given for a simulated task", worker=worker_name())
        if mission.get("error"):
            return failed_row(task, mission["error"], worker=worker_name())
        path = mission["path"]
    else:
        path = task.mission
    variables = {**ctx.variables, "mission": path, "out": str(folder)}
    summary = None
    error: str | None = None
    with _captured(folder / RUN_LOG):
        try:
            session = Session()
            spec = session.load(ctx.graph, task.overrides(), variables)
            net = session.build(spec)
            summary = session.run(net, speed="max", mode=spec.clock_mode)
            if summary.interrupted:
                error = "interrupted"
        except (GraphError, YamlError) as e:
            error = one_line(e)
        except ComponentError as e:
            summary, error = getattr(e, "summary", None), one_line(e)
        except Exception as e:
            error = one_line(e)
        if summary is not None:
            print(summary.format(), file=sys.stderr)
            (folder / RUN_SUMMARY).write_text(json.dumps(summary.to_json(), indent=2, default=str) + "\n",
                                              encoding="utf-8")
    wall_s = time.perf_counter() - t0
    if summary is None:
        return failed_row(task, error or "no run summary", wall_s, worker_name())
    row = base_row(task)
    row.update(samples=sum(summary.emitted.values()), lost=summary.total_lost,
               mission_s=round(summary.mission_s, 6), wall_s=wall_s, worker=worker_name())
    missing = []
    for m in ctx.metrics:
        comp, key = m.split(".", 1)
        value = (summary.extra.get(comp) or {}).get(key)
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            missing.append((m, value, sorted(summary.extra.get(comp) or {})))
            continue
        row[m] = value
    if error is None and missing:
        m, value, keys = missing[0]
        error = (f"metric {m}: not in the run summary ('{m.split('.')[0]}' reports: {', '.join(keys) or 'nothing'})"
                 if value is None else f"metric {m}: {value!r} is not a finite number")
        if len(missing) > 1:
            error += f" (and {len(missing) - 1} more metric(s) missing)"
    row["status"], row["error"] = ("failed", error) if error else ("ok", "")
    return row
