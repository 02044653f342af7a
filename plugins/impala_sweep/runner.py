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
import json
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

from .folder import mission_file, prepare_folder
from .results import STATUS_OK, Results
from .spec import SweepError, SweepSpec, Task
from .task import SweepContext, failed_row, one_line, run_task, simulate_mission

__all__ = ["run_sweep", "SweepOutcome", "DASHBOARD", "DASK_LOG", "check_scheduler"]

#: where the local cluster's dashboard listens unless told (loopback: nothing outside this machine reaches it)
DASHBOARD = "127.0.0.1:8787"
#: what Dask, its dashboard (bokeh, tornado) and asyncio log during a sweep: a file, not the terminal
DASK_LOG = "dask.log"
#: most bytes written to DIR/dask.log by one sweep (the records beyond are counted, not written)
MAX_LOG_BYTES = 10 << 20
#: seconds to wait for a scheduler's handshake
CONNECT_TIMEOUT_S = 10.0


@dataclass
class SweepOutcome:
    total: int  # tasks of the sweep
    skipped: int  # already ok in a resumed folder
    ok: int
    failed: int
    interrupted: bool
    wall_s: float
    dashboard: str | None = None
    #: warnings and errors Dask, the dashboard or asyncio logged (in DIR/dask.log)
    logged: int = 0


def _free_port(host: str, port: int) -> bool:
    try:
        with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_STREAM) as s:
            s.bind((host, port))
    except OSError:
        return False
    return True


def parse_dashboard(value: str | None) -> tuple[str, int] | None:
    """``HOST:PORT`` (``:PORT`` is loopback, port 0 any free one), or ``none``: (host, port) or None.
    Raises :class:`SweepError` naming the option."""
    if value is None or value.strip().lower() in ("none", "off", "no", ""):
        return None
    host, sep, port = value.strip().rpartition(":")
    host = host.strip("[]") or "127.0.0.1"
    if not sep or not port.isdigit() or not 0 <= int(port) <= 65535:
        raise SweepError(f"--dashboard {value}: expected HOST:PORT (e.g. 127.0.0.1:8787, 0.0.0.0:8787 to open it "
                         "to the network) or none")
    return host, int(port)


def parse_scheduler(address: str) -> tuple[str, str, int]:
    """(protocol, host, port) of ``tcp://host:port`` (or ``host:port``, ``tls://...``); raises
    :class:`SweepError` for anything else."""
    proto, sep, rest = address.strip().partition("://")
    if not sep:
        proto, rest = "tcp", address.strip()
    host, sep, port = rest.rstrip("/").rpartition(":")
    host = host.strip("[]")
    if proto not in ("tcp", "tls") or not sep or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise SweepError(f"--scheduler {address}: not a Dask scheduler address (tcp://HOST:PORT, e.g. "
                         "tcp://10.0.0.5:8786)")
    return proto, host, int(port)


def read_scheduler_file(path: str) -> str:
    """The scheduler's address from its file (``dask scheduler --scheduler-file``, JSON with
    ``address``); :class:`SweepError` naming the file otherwise."""
    where = f"--scheduler-file {path}"
    try:
        with open(path, "rb") as f:
            raw = f.read((1 << 20) + 1)
    except OSError as e:
        raise SweepError(f"{where}: cannot read: {e.strerror or e}") from None
    try:
        if len(raw) > 1 << 20:
            raise ValueError("over 1 MiB")
        address = json.loads(raw.decode("utf-8")).get("address")
    except (ValueError, UnicodeError, AttributeError) as e:
        raise SweepError(f"{where}: not a Dask scheduler file (JSON with an address): {e}") from None
    if not isinstance(address, str) or not address:
        raise SweepError(f"{where}: no scheduler address in it")
    return address


def check_scheduler(address: str, timeout_s: float | None = None) -> None:
    """Raise :class:`SweepError` (one line) unless a Dask server answers at ``address``: it
    must send a handshake whose framing is Dask's (a total length, then a few frames whose
    lengths add up) within ``timeout_s``. An HTTP server (the dashboard's port) waits for a
    request and sends nothing; other servers send text: neither gets a Dask client, which
    would read its first bytes as a length and try to allocate exabytes."""
    import struct

    timeout_s = CONNECT_TIMEOUT_S if timeout_s is None else timeout_s
    proto, host, port = parse_scheduler(address)
    if proto != "tcp":
        return  # TLS: the handshake is inside the TLS session; Dask's client checks it
    where = f"--scheduler {address}"
    try:
        with socket.create_connection((host, port), timeout=timeout_s) as s:
            s.settimeout(timeout_s)

            def read(n: int) -> bytes:
                buf = b""
                while len(buf) < n:
                    chunk = s.recv(n - len(buf))
                    if not chunk:
                        raise ConnectionError("closed the connection")
                    buf += chunk
                return buf

            try:
                (total,) = struct.unpack("<Q", read(8))
                if not 16 <= total <= 1 << 20:
                    raise ValueError
                body = read(total)
                (n,) = struct.unpack("<Q", body[:8])
                if not 1 <= n <= 64 or 8 + 8 * n > total:
                    raise ValueError
            except TimeoutError:
                raise SweepError(f"{where}: that address does not speak the Dask protocol (no handshake within "
                                 f"{timeout_s:g} s; an HTTP port such as the dashboard's? the scheduler's is "
                                 "usually 8786)") from None
            except (ValueError, ConnectionError):
                raise SweepError(f"{where}: that address does not speak the Dask protocol (it answered something "
                                 "else; the scheduler's port is usually 8786)") from None
    except SweepError:
        raise
    except TimeoutError:
        raise SweepError(f"{where}: no answer within {timeout_s:g} s (a firewall, or nothing listening)") from None
    except OSError as e:
        raise SweepError(f"{where}: cannot connect: {e.strerror or e}") from None


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
    """tqdm bar (tasks done, ok/failed) on a terminal; one line per task otherwise. A failure's
    error is printed the first time only: later tasks failing the same way are counted, and
    :meth:`close` says how many (the rows and summary.md have every one)."""

    def __init__(self, total: int, enabled: bool | None) -> None:
        self.total = total
        self.tty = sys.stderr.isatty() if enabled is None else enabled
        self.quiet = enabled is False
        self.bar: Any = None
        self.ok = self.failed = 0
        self.errors: dict[str, int] = {}  # error text -> tasks that failed with it
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

    def _error(self, row: dict[str, str]) -> str:
        """The row's error the first time it is seen, else a pointer to it."""
        text = row.get("error") or "?"
        self.errors[text] = self.errors.get(text, 0) + 1
        return text if self.errors[text] == 1 else "the same error as before"

    def update(self, row: dict[str, str]) -> None:
        failed = row.get("status") != STATUS_OK
        if failed:
            self.failed += 1
        else:
            self.ok += 1
        err = self._error(row) if failed else ""
        if self.bar is not None:
            if failed and self.errors[row.get("error") or "?"] == 1:
                self.bar.write(f"FAILED {row['task']}: {err}", file=sys.stderr)
            self.bar.set_postfix_str(f"ok={self.ok} failed={self.failed}", refresh=False)
            self.bar.update(1)
        elif not self.quiet:
            n = self.ok + self.failed
            wall = f" {float(row['wall_s']):.1f} s" if row.get("wall_s") else ""
            print(f"[{n}/{self.total}] {row.get('status')} {row['task']}{wall}" + (f": {err}" if failed else ""),
                  file=sys.stderr, flush=True)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        repeated = {e: n for e, n in self.errors.items() if n > 1}
        if repeated and not self.quiet:
            print(f"sweep: {sum(repeated.values()) - len(repeated)} more task(s) failed with an error already "
                  f"shown ({len(repeated)} kind(s); every one is in results.csv)", file=sys.stderr, flush=True)


def run_sweep(spec: SweepSpec, out_dir: str | Path, *, scheduler: str | None = None,
              scheduler_file: str | None = None, workers: int | None = None, threads_per_worker: int = 1,
              resume: bool = False, overwrite: bool = False, progress: bool | None = None,
              dashboard: str | None = DASHBOARD, on_client: Callable[[Any], None] | None = None) -> SweepOutcome:
    """Run every task of ``spec`` not already done in ``out_dir`` and write the outputs.

    The folder is first made this sweep's (:func:`~.folder.prepare_folder`: ``resume`` only
    the same sweep, ``overwrite`` removes only what a sweep made). Without
    ``scheduler``/``scheduler_file``, a ``distributed.LocalCluster`` of ``workers`` processes
    (default: one per CPU) with ``threads_per_worker`` threads each is started on the loopback
    interface and closed at the end; its dashboard listens on ``dashboard`` (``HOST:PORT``,
    loopback by default; None: no dashboard). ``on_client(client)`` is called once connected
    (tests, benchmarks)."""
    from distributed import as_completed

    t0 = time.perf_counter()
    board = parse_dashboard(dashboard)
    if scheduler_file:
        scheduler, scheduler_file = read_scheduler_file(scheduler_file), None
    if scheduler:
        check_scheduler(scheduler)
    out = prepare_folder(spec, out_dir, resume=resume, overwrite=overwrite)
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
        with _dask_logs_to(out / DASK_LOG) as logged:
            try:
                with _sigterm_interrupts():
                    if todo:
                        client, cluster, where = _connect(scheduler, scheduler_file, workers, threads_per_worker,
                                                          board)
                        outcome.dashboard, listens = _dashboard(client, cluster)
                        bar.write(f"sweep: {len(todo)} tasks on a {where}; dashboard: "
                                  + (f"{outcome.dashboard} ({listens})" if outcome.dashboard else "none"))
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
        outcome.logged = logged[0]
        if logged[0]:
            bar.write(f"sweep: {logged[0]} warning(s) or error(s) from Dask or its dashboard: see {out / DASK_LOG}")
    finally:
        results.finalize()
        for part in (out / "missions").glob(".*.mcap.*.part"):  # a simulation cut short by a dead worker
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


class _FileLog(logging.Handler):
    """Appends records to a file, opened on the first one. Not a ``logging.StreamHandler``:
    Dask's ``silence_logs`` re-levels those, and this one must keep every record."""

    def __init__(self, path: Path, max_bytes: int) -> None:
        super().__init__(logging.INFO)
        self.path = path
        self.file: Any = None
        self.left = max_bytes  # bounded: a flood of bad requests cannot fill the disk
        self.dropped = 0
        self.setFormatter(logging.Formatter("%(asctime)s %(name)s %(levelname)s %(message)s"))

    def emit(self, record: logging.LogRecord) -> None:
        try:
            text = self.format(record) + "\n"
            if len(text) > self.left:
                self.dropped += 1
                return
            self.left -= len(text)
            if self.file is None:
                self.file = open(self.path, "a", encoding="utf-8")  # noqa: SIM115 - closed by close()
            self.file.write(text)
            self.file.flush()
        except Exception:
            self.handleError(record)

    def close(self) -> None:
        if self.dropped and self.file is not None:
            self.file.write(f"... {self.dropped} more record(s) not written: the log's limit was reached\n")
        if self.file is not None:
            self.file.close()
            self.file = None
        super().close()


class _Counter(logging.Handler):
    def __init__(self, box: list[int]) -> None:
        super().__init__(logging.WARNING)
        self.box = box

    def emit(self, record: logging.LogRecord) -> None:
        self.box[0] += 1


#: loggers of Dask, its dashboard's web server and the event loop: what a remote request, a
#: closing cluster or an interrupt makes them say goes to DIR/dask.log, counted
_DASK_LOGGERS = ("distributed", "tornado", "bokeh", "asyncio")


@contextlib.contextmanager
def _dask_logs_to(path: Path) -> Iterator[list[int]]:
    """Route the loggers of :data:`_DASK_LOGGERS` to ``path`` (INFO and up) for the sweep,
    counting warnings and errors (the box yielded); with ``--debug`` they still reach the
    terminal too. Their handlers and levels are restored afterwards."""
    box = [0]
    file = _FileLog(path, MAX_LOG_BYTES)  # read at call time (tests lower it)
    counter = _Counter(box)
    debug = not quiet_dask()
    saved = []
    for name in _DASK_LOGGERS:
        log = logging.getLogger(name)
        saved.append((log, log.handlers[:], log.propagate, log.level))
        if not debug:
            log.handlers = []
            log.propagate = False
        log.addHandler(file)
        log.addHandler(counter)
        if log.level == logging.NOTSET or log.level > logging.INFO:
            log.setLevel(logging.INFO)
    try:
        yield box
    finally:
        for log, handlers, propagate, level in saved:
            log.handlers = handlers
            log.propagate = propagate
            log.setLevel(level)
        file.close()


@contextlib.contextmanager
def _children_ignore_sigint() -> Iterator[None]:
    """Worker processes started inside never see SIGINT: it is blocked in this thread (and so
    in the threads and processes started from it: a signal mask is inherited through fork and
    exec), since Ctrl-C in a terminal reaches the whole process group and the sweep, not each
    worker, decides what to stop. Not ignored (SIG_IGN) in this process: another thread
    (OpenBLAS's) would then receive and discard a Ctrl-C. A Ctrl-C while the cluster starts is
    noted and raised as KeyboardInterrupt once it has started, so it is neither lost nor cuts
    the start in half."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []

    def later(signum: int, frame: Any) -> None:
        caught.append(signum)

    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    old = signal.signal(signal.SIGINT, later)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
    if caught:
        raise KeyboardInterrupt


@contextlib.contextmanager
def _quiet_close() -> Iterator[None]:
    """Closing a cluster after Ctrl-C may raise a second interrupt or a timeout: swallowed,
    the results are written whatever happens."""
    try:
        yield
    except (KeyboardInterrupt, Exception):
        pass


@contextlib.contextmanager
def _leaked_sockets_collected() -> Iterator[None]:
    """When the dashboard's port is taken between our check and Dask's bind (another sweep starting at the same
    time), distributed binds another port but leaves the socket of its failed attempt open (node.py's retry): it
    is collected here, silently, rather than reported as an unclosed socket wherever the collector next runs."""
    import gc
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ResourceWarning)
        try:
            yield
        finally:
            gc.collect()


def _connect(scheduler: str | None, scheduler_file: str | None, workers: int | None,
             threads_per_worker: int, board: tuple[str, int] | None) -> tuple[Any, Any, str]:
    """(client, local cluster or None, a description)."""
    from distributed import Client, LocalCluster

    if scheduler or scheduler_file:
        client = Client(scheduler, scheduler_file=scheduler_file, timeout=f"{CONNECT_TIMEOUT_S:g}s")
        return client, None, f"scheduler {client.scheduler.address}"
    import dask

    n = workers or os.cpu_count() or 1
    # Dask's default MALLOC_TRIM_THRESHOLD_=65536 makes numpy-heavy graphs about 2x slower
    # (see task.undo_dask_malloc_trim): the local cluster's workers do without it
    config: dict[str, Any] = {"distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None}
    cluster = None
    for attempt in range(2):
        address = None
        if board is not None:
            host, port = board
            if port == 0 or not _free_port(host, port) or attempt:
                port = _any_free_port(host)
            address = f"{host}:{port}"
            if _loopback(host):
                # the dashboard's websockets only for pages served from this machine (not '*', bokeh's
                # default: a web page elsewhere could otherwise talk to it through the user's browser)
                config["distributed.scheduler.dashboard.bokeh-application.allow_websocket_origin"] = [
                    f"{h}:{port}" for h in ("127.0.0.1", "localhost", host)]
        try:
            with _children_ignore_sigint(), dask.config.set(config), _leaked_sockets_collected():
                # host: the scheduler, the nannies and the workers listen on the loopback interface only
                cluster = LocalCluster(n_workers=n, threads_per_worker=threads_per_worker, processes=True,
                                       host="127.0.0.1", dashboard_address=address,
                                       silence_logs=logging.CRITICAL if quiet_dask() else False)
            client = Client(cluster)
        except BaseException as e:  # an interrupt while starting included
            if cluster is not None:
                with _quiet_close():
                    cluster.close()
                cluster = None
            # the dashboard's port was free when checked and taken before Dask bound it (another
            # sweep starting at the same time): once more, on a port the system gives
            if attempt == 0 and address is not None and isinstance(e, Exception) and "already in use" in str(e):
                continue
            raise
        break
    return client, cluster, f"local cluster of {n} worker process(es) x {threads_per_worker} thread(s)"


def _loopback(host: str) -> bool:
    return host.startswith("127.") or host in ("::1", "localhost")


def _any_free_port(host: str) -> int:
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def _dashboard(client: Any, cluster: Any) -> tuple[str | None, str]:
    """(the dashboard's link, where it listens) of the cluster, or (None, "")."""
    services = client.scheduler_info().get("services", {})
    if not services.get("dashboard"):
        return None, ""
    if cluster is None:
        return client.dashboard_link, "the scheduler's"
    try:  # the sockets the dashboard's server really listens on (tornado's; private, so guarded)
        sockets = cluster.scheduler.http_server._sockets.values()
        hosts = sorted({f"{s.getsockname()[0]}:{s.getsockname()[1]}" for s in sockets})
    except Exception:
        return client.dashboard_link, "listening where --dashboard says"
    loopback = all(_loopback(h.rsplit(":", 1)[0].strip("[]")) for h in hosts)
    return client.dashboard_link, f"listening on {', '.join(hosts)}" + (" only" if loopback
                                                                         else ": open to the network")


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
