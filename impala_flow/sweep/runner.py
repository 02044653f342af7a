"""Run a sweep on Dask distributed: a local cluster by default, any scheduler when given.

Each task (mission, variant, seed, repeat) is one :func:`~.task.run_task` on a worker; a
simulated mission is first one :func:`~.task.simulate_mission` there (once per mission, shared
by its variants through Dask's dependencies), so only file paths and result rows go through
the scheduler. Rows are written as they arrive; a worker that dies has its tasks run again
by Dask; Ctrl-C (or SIGTERM) cancels what is left and keeps what is done.

``distributed`` is imported inside :func:`run_sweep` only: nothing else of impala-flow
imports Dask.
"""

from __future__ import annotations

import contextlib
import hashlib
import logging
import os
import signal
import socket
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .results import STATUS_OK, Results
from .spec import SweepSpec, Task
from .task import SweepContext, failed_row, one_line, run_task, simulate_mission

__all__ = ["run_sweep", "SweepOutcome", "mission_file"]


@dataclass
class SweepOutcome:
    total: int  # tasks of the sweep
    skipped: int  # already ok in a resumed folder
    ok: int
    failed: int
    interrupted: bool
    wall_s: float
    dashboard: str | None = None


def mission_file(out_dir: str | Path, task: Task) -> Path:
    """Where a simulated mission of ``task`` is written: ``DIR/missions/<scenario>_s<seed>[_<d>s].mcap``."""
    scenario = task.scenario or "mission"
    name = Path(scenario).stem
    if scenario != name:  # a scenario file: two files of one name in two folders are two missions
        name += "-" + hashlib.sha1(scenario.encode()).hexdigest()[:6]
    parts = [name] + ([f"s{task.seed}"] if task.seed is not None else []) \
        + ([f"{task.duration_s:g}s"] if task.duration_s is not None else [])
    return Path(out_dir) / "missions" / ("_".join(parts) + ".mcap")


def _free_port(port: int) -> bool:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        try:
            s.bind(("127.0.0.1", port))
        except OSError:
            return False
    return True


@contextlib.contextmanager
def _sigterm_interrupts() -> Iterator[None]:
    """SIGTERM stops the sweep like Ctrl-C (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    old = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, old)


class _Progress:
    """tqdm bar (tasks done, ok/failed) on a terminal; one line per task otherwise."""

    def __init__(self, total: int, enabled: bool | None) -> None:
        self.total = total
        self.tty = sys.stderr.isatty() if enabled is None else enabled
        self.quiet = enabled is False
        self.bar: Any = None
        self.ok = self.failed = 0
        if self.tty and not self.quiet:
            from tqdm import tqdm

            self.bar = tqdm(total=total, unit="task", desc="sweep", file=sys.stderr, leave=True, dynamic_ncols=True)
            self.bar.set_postfix_str("ok=0 failed=0")

    def write(self, text: str) -> None:
        """A line of news (the cluster, resuming, interrupted): shown even without progress."""
        if self.bar is not None:
            self.bar.write(text, file=sys.stderr)
        else:
            print(text, file=sys.stderr, flush=True)

    def update(self, row: dict[str, str]) -> None:
        if row.get("status") == STATUS_OK:
            self.ok += 1
        else:
            self.failed += 1
        if self.bar is not None:
            if row.get("status") != STATUS_OK:
                self.bar.write(f"FAILED {row['task']}: {row.get('error')}", file=sys.stderr)
            self.bar.set_postfix_str(f"ok={self.ok} failed={self.failed}", refresh=False)
            self.bar.update(1)
        elif not self.quiet:
            n = self.ok + self.failed
            wall = f" {float(row['wall_s']):.1f} s" if row.get("wall_s") else ""
            err = f": {row.get('error')}" if row.get("status") != STATUS_OK else ""
            print(f"[{n}/{self.total}] {row.get('status')} {row['task']}{wall}{err}", file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def run_sweep(spec: SweepSpec, out_dir: str | Path, *, scheduler: str | None = None,
              scheduler_file: str | None = None, workers: int | None = None, threads_per_worker: int = 1,
              resume: bool = False, progress: bool | None = None,
              on_client: Callable[[Any], None] | None = None) -> SweepOutcome:
    """Run every task of ``spec`` not already done in ``out_dir`` and write the outputs.

    Without ``scheduler``/``scheduler_file``, a ``distributed.LocalCluster`` of ``workers``
    processes (default: one per CPU) with ``threads_per_worker`` threads each is started and
    closed at the end. ``on_client(client)`` is called once connected (tests, benchmarks)."""
    from distributed import as_completed

    t0 = time.perf_counter()
    out = Path(out_dir).resolve()
    results = Results(spec, out, resume=resume)
    done = results.done()
    todo = [t for t in spec.tasks if t.id not in done]
    bar = _Progress(len(todo), progress)
    if done:
        bar.write(f"resuming {out}: {len(done)} of {len(spec.tasks)} tasks already done, {len(todo)} to run")
    ctx = SweepContext(graph=str(spec.graph.resolve()), out_dir=str(out), metrics=tuple(spec.metrics),
                       variables=dict(spec.variables))
    outcome = SweepOutcome(len(spec.tasks), len(done), 0, 0, False, 0.0)
    cluster = client = None
    futures: list[Any] = []
    try:
        with _dask_logs_quiet():
            try:
                with _sigterm_interrupts():
                    if todo:
                        client, cluster, where = _connect(scheduler, scheduler_file, workers, threads_per_worker)
                        outcome.dashboard = client.dashboard_link if client.scheduler_info().get(
                            "services", {}).get("dashboard") else None
                        bar.write(f"sweep: {len(todo)} tasks on a {where}; dashboard: {outcome.dashboard or 'none'}")
                        if on_client is not None:
                            on_client(client)
                        futures = _submit(client, todo, ctx, out)
                        task_of = {f.key: t for f, t in zip(futures, todo, strict=True)}
                        for f in as_completed(futures):
                            task = task_of[f.key]
                            try:
                                row = f.result()
                            except Exception as e:  # the task could not run (e.g. its workers kept dying)
                                row = failed_row(task, f"{type(e).__name__}: {one_line(e)}")
                            bar.update(results.add(row))
            except KeyboardInterrupt:
                outcome.interrupted = True
                bar.write("sweep: interrupted, cancelling the tasks left (what is done is kept)")
                if client is not None and futures:
                    with contextlib.suppress(Exception):
                        client.cancel(futures)
            finally:
                bar.close()
                with _quiet_close():
                    if client is not None:
                        client.close()
                    if cluster is not None:
                        cluster.close()
    finally:
        results.finalize()
        for part in (out / "missions").glob(".*.part"):  # a simulation cut short by a dead worker
            part.unlink(missing_ok=True)
        outcome.ok, outcome.failed = results.counts()
        outcome.wall_s = time.perf_counter() - t0
        note = (f"Interrupted: {len(spec.tasks) - outcome.ok - outcome.failed} tasks not run "
                f"(`impala-flow sweep {spec.path} --resume {out}` runs them)." if outcome.interrupted else "")
        results.write_summary(note)
        results.write_figure()
    return outcome


def quiet_dask() -> bool:
    return not logging.getLogger().isEnabledFor(logging.DEBUG)


@contextlib.contextmanager
def _dask_logs_quiet() -> Iterator[None]:
    """Dask logs every scheduler and worker event at INFO: shown with ``--debug`` only."""
    log = logging.getLogger("distributed")
    old = log.level
    if quiet_dask():
        log.setLevel(logging.WARNING)
    try:
        yield
    finally:
        log.setLevel(old)


@contextlib.contextmanager
def _children_ignore_sigint() -> Iterator[None]:
    """Worker processes started inside ignore SIGINT (an ignored signal stays ignored in a
    child): Ctrl-C in a terminal reaches the whole process group, and the sweep, not each
    worker, decides what to stop. A Ctrl-C while the cluster starts is ignored too."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


@contextlib.contextmanager
def _quiet_close() -> Iterator[None]:
    """Closing a cluster after Ctrl-C may raise a second interrupt or a timeout: swallowed,
    the results are written whatever happens."""
    try:
        yield
    except (KeyboardInterrupt, Exception):
        pass


def _connect(scheduler: str | None, scheduler_file: str | None, workers: int | None,
             threads_per_worker: int) -> tuple[Any, Any, str]:
    """(client, local cluster or None, a description)."""
    from distributed import Client, LocalCluster

    if scheduler or scheduler_file:
        client = Client(scheduler, scheduler_file=scheduler_file, timeout="30s")
        return client, None, f"scheduler {client.scheduler.address}"
    import dask

    n = workers or os.cpu_count() or 1
    # Dask's default MALLOC_TRIM_THRESHOLD_=65536 makes numpy-heavy graphs about 2x slower
    # (see task.undo_dask_malloc_trim): the local cluster's workers do without it
    no_trim = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}
    with _children_ignore_sigint(), dask.config.set(no_trim):
        cluster = LocalCluster(n_workers=n, threads_per_worker=threads_per_worker, processes=True,
                               dashboard_address=":8787" if _free_port(8787) else ":0",
                               silence_logs=logging.ERROR if quiet_dask() else False)
    try:
        client = Client(cluster)
    except BaseException:
        cluster.close()
        raise
    return client, cluster, f"local cluster of {n} worker process(es) x {threads_per_worker} thread(s)"


def _submit(client: Any, todo: list[Task], ctx: SweepContext, out: Path) -> list[Any]:
    sims: dict[Path, Any] = {}
    futures = []
    for t in todo:
        sim = None
        if t.simulated:
            path = mission_file(out, t)
            sim = sims.get(path)
            if sim is None:
                sim = sims[path] = client.submit(simulate_mission, t.scenario, t.seed, t.duration_s, str(path),
                                                 pure=False, key=f"simulate-{path.stem}")
        futures.append(client.submit(run_task, t, ctx, sim, pure=False, key=f"task-{t.id}"))
    return futures
