"""Shared pieces of the subcommands: session, graph loading, progress bar, summary."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
import time
from collections.abc import Callable, Iterator
from typing import Any

import yaml

from .._component import Source
from .._network import Network
from .._offline import timer_problems
from .._paths import not_writable
from .._session import Session
from .._spec import GraphError, checked_speed
from .._summary import ComponentError, RunSummary
from .._validate import RECORDER_TYPE
from .._yamlloc import YamlError, load_value
from ..io import MissionReader
from . import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE, CommandError

__all__ = ["add_graph_args", "parse_vars", "open_session", "load_spec", "Progress", "run_network", "check_speed",
           "check_writable_file", "check_output_over_inputs", "record_source", "window", "loss_line"]


def add_graph_args(p: argparse.ArgumentParser) -> None:
    """Add the GRAPH argument and the repeatable ``--set COMP.PARAM=VALUE`` and ``--var NAME=VALUE``
    options to a command's parser (read back by :func:`load_spec`)."""
    p.add_argument("graph", metavar="GRAPH", help="graph YAML file")
    p.add_argument("--set", dest="overrides", action="append", default=[], metavar="COMP.PARAM=VALUE",
                   help="override a component parameter (repeatable), e.g. --set slam.cell_m=0.4")
    p.add_argument("--var", dest="variables", action="append", default=[], metavar="NAME=VALUE",
                   help="set a ${NAME} variable of the graph (repeatable)")


def parse_vars(items: list[str]) -> dict[str, Any]:
    """``--var NAME=VALUE`` items -> {name: value read as a YAML scalar or flow list}."""
    out: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            raise CommandError(f"--var {item!r}: expected NAME=VALUE", EXIT_USAGE)
        k, v = item.split("=", 1)
        try:
            out[k.strip()] = load_value(v)
        except YamlError as e:
            raise CommandError(f"--var {item}: {e}", EXIT_USAGE) from None
        except yaml.YAMLError:  # not YAML: the text itself
            out[k.strip()] = v
    return out


def add_blas_threads_arg(p: argparse.ArgumentParser) -> None:
    """``--blas-threads N`` (default 1; 0: the BLAS libraries' own count, one per core)."""
    p.add_argument("--blas-threads", type=_blas_threads, default=1, metavar="N",
                   help="threads of the BLAS library (NumPy's and SciPy's matrix products) while the graph "
                   "runs (default 1: the components and their own thread pools already share the cores, and "
                   "BLAS threads waiting for a core spin; 0: the library's own, one per core)")


def _blas_threads(text: str) -> int | None:
    try:
        n = int(text)
    except ValueError:
        n = -1
    if n < 0:
        raise argparse.ArgumentTypeError(f"expected an integer >= 0 (0: the library's own), got {text!r}")
    return n or None


def check_speed(value: Any) -> None:
    """Refuse a ``--speed`` that is not 'max' nor a finite factor >= 0.001 (exit 2)."""
    if value is None:
        return
    try:
        checked_speed(value)
    except ValueError as e:
        raise CommandError(f"--speed: {e}", EXIT_USAGE) from None


def check_writable_file(path: str, option: str) -> None:
    """Refuse, before a run, an output file that cannot be written (exit 2): a folder, a file
    without write permission, a missing or unwritable folder, a name too long, a named pipe."""
    why = not_writable(path)
    if why and ("long" in why or "pipe" in why):
        raise CommandError(f"{option} {path}: {why}", EXIT_USAGE)
    if os.path.isdir(path):
        raise CommandError(f"{option} {path}: is a folder", EXIT_USAGE)
    if os.path.exists(path):
        if not os.access(path, os.W_OK):
            raise CommandError(f"{option} {path}: not writable", EXIT_USAGE)
        return
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise CommandError(f"{option} {path}: folder {folder} does not exist", EXIT_USAGE)
    if not os.access(folder, os.W_OK | os.X_OK):
        raise CommandError(f"{option} {path}: cannot write in folder {folder}", EXIT_USAGE)


def check_output_over_inputs(path: str, option: str, spec: Any, session: Session,
                             extra: tuple[tuple[str, str], ...] = ()) -> None:
    """Refuse (exit 2) an output file of the command that is, or lies inside, a file or
    folder the graph reads, the graph file itself, or one of ``extra`` (path, what)."""
    from .._paths import graph_files, output_clash

    inputs = [(f.path, f"the input of {f.who}") for f in graph_files(spec, session.registry) if f.kind == "read"]
    clash = output_clash(path, [*inputs, (spec.file, "the graph file"), *extra])
    if clash:
        raise CommandError(f"{option}: {clash}", EXIT_USAGE)


def open_session() -> Session:
    """A :class:`~impala_flow.Session` with the installed plugins; a failure is a one-line CommandError."""
    try:
        return Session()
    except Exception as e:
        raise CommandError(f"plugins: {e}", EXIT_FAILED) from e


def load_spec(session: Session, args: argparse.Namespace) -> Any:
    """The graph named by ``args`` (from :func:`add_graph_args`), loaded with its ``--set`` and ``--var``;
    a bad graph is a one-line CommandError (exit 2) naming the file, line and column."""
    try:
        return session.load(args.graph, args.overrides, parse_vars(args.variables))
    except (GraphError, YamlError) as e:
        raise CommandError(str(e), EXIT_USAGE) from None


class Progress:
    """A tqdm bar in mission seconds, with wall time and speed ratio; silent when not a TTY."""

    def __init__(self, net: Network, enabled: bool | None = None, desc: str = "mission") -> None:
        hints = [s.duration_hint_ns() for s in net.components.values() if isinstance(s, Source)]
        known = [h for h in hints if h]
        self.total_s = max(known) / 1e9 if known else None
        self.enabled = sys.stderr.isatty() if enabled is None else enabled
        self.bar: Any = None
        self.desc = desc
        self.wall0 = time.perf_counter()

    def __call__(self, t_ns: int, start_ns: int | None) -> None:
        if not self.enabled or start_ns is None:
            return
        if self.bar is None:
            from tqdm import tqdm

            self.bar = tqdm(total=self.total_s, unit="s", desc=self.desc, file=sys.stderr, leave=True,
                            bar_format="{desc}: {percentage:3.0f}%|{bar}| {n:.1f}/{total:.1f} s mission "
                            "[{elapsed} wall{postfix}]" if self.total_s else
                            "{desc}: {n:.1f} s mission [{elapsed} wall{postfix}]")
        mission_s = (t_ns - start_ns) / 1e9
        wall = time.perf_counter() - self.wall0
        n = round(mission_s, 3)
        self.bar.n = min(n, self.total_s) if self.total_s else n  # a hint can fall short by a bit
        self.bar.set_postfix_str(f"x{mission_s / wall:.1f} real time" if wall > 0 else "", refresh=False)
        self.bar.refresh()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def run_network(session: Session, spec: Any, speed: Any = None, quiet: bool = False,
                progress: bool | None = None, on_summary: Callable[[RunSummary], None] | None = None,
                duration_s: float | None = None, blas_threads: int | None = 1) -> int:
    """Build and run ``spec`` (for ``duration_s`` seconds of mission time when given), show
    progress, print the summary, return the exit code (0 when it stopped at ``duration_s``).
    ``blas_threads``: :meth:`Session.run`'s."""
    check_speed(speed)
    net = session.build(spec)
    bad = timer_problems(net)  # a timer that would spin over the mission's span: refused before it starts
    if bad:
        raise CommandError("; ".join(bad), EXIT_USAGE)
    bar = Progress(net, enabled=progress)
    try:
        summary = session.run(net, speed=speed if speed is not None else spec.speed,
                              mode=spec.clock_mode, progress=bar, duration_s=duration_s,
                              blas_threads=blas_threads)
    except ComponentError as e:
        bar.close()
        partial = getattr(e, "summary", None)
        if partial is not None:
            if not quiet:
                print(partial.format(), file=sys.stderr)
            if on_summary:  # a failed run's summary too (its error, the events it processed)
                on_summary(partial)
        raise CommandError(str(e), EXIT_FAILED) from e
    bar.close()
    if not quiet:
        print(summary.format(), file=sys.stderr)
    if on_summary:
        on_summary(summary)
    return EXIT_INTERRUPTED if summary.interrupted else EXIT_OK


#: the GIL's switch interval while :func:`record_source` runs (Python's default is 5 ms). The main thread runs
#: Python without pause (each sample through the executor and the writer); the source's reading thread and
#: the writer's compressing thread come back from I/O, inflate or zstd (GIL released) many times per scan
#: and per chunk, and each time wait up to the interval to take the GIL back, so they fall behind and the
#: main thread waits for them. Measured on the RADIATE head import (400 scans, 2 cores, alternating runs):
#: 5 ms 7.44-7.67 s wall, 1 ms 6.79-6.86 s, 0.5 ms 6.46-6.90 s, 0.2 ms 6.33-6.64 s, for 0.1-0.2 s more CPU
#: (9.1-9.2 -> 9.3 s: more switches). Only the scheduling changes: the file is the same bytes.
RECORD_SWITCH_INTERVAL_S = 0.0002


@contextlib.contextmanager
def _switch_interval(seconds: float) -> Iterator[None]:
    """``sys.setswitchinterval(seconds)`` inside, the previous interval restored after."""
    old = sys.getswitchinterval()
    sys.setswitchinterval(seconds)
    try:
        yield
    finally:
        sys.setswitchinterval(old)


def record_source(session: Session, source: Source, path: str, topics: dict[str, str],
                  compression: str = "zstd", progress: bool | None = None, quiet: bool = False) -> int:
    """Record ``source``'s ports to ``path`` (``topics``: port -> topic) through the
    engine's ``io.Recorder``: the one recording path every mission file goes through.

    Offline sources give the same samples every time, so chunks are cut by size only:
    the same source gives the same bytes."""
    rec_cls = session.registry.components.get(RECORDER_TYPE)
    if rec_cls is None:
        raise CommandError(f"recording needs the '{RECORDER_TYPE}' component (the engine's own: every registry "
                           "of impala_flow.plugins has it)")
    net = Network(name=f"record-{source.name}")
    net.add(source)
    origin = {topic: f"{source.name}.{port}" for port, topic in topics.items()}
    graph = {"name": net.name, "components": {source.name: {"type": session.registry.name_of(type(source)),
                                                            "params": source.params}}}
    rec = net.add(rec_cls(name="record", path=str(path), topics=origin, compression=compression, graph=graph,
                          flush_period_s=0.0,
                          plugins={n: p.version for n, p in session.registry.plugins.items()}))
    rec.registry = source.registry = session.registry
    for port, topic in topics.items():
        net.connect(source.outputs[port], rec.inputs[topic])
    bar = Progress(net, enabled=progress, desc=source.name)
    try:
        with _switch_interval(RECORD_SWITCH_INTERVAL_S):
            summary = session.run(net, speed="max", progress=bar)
    except ComponentError as e:
        bar.close()
        raise CommandError(str(e), EXIT_FAILED) from e
    bar.close()
    if not quiet:
        print(summary.format(), file=sys.stderr)
    return EXIT_INTERRUPTED if summary.interrupted else EXIT_OK


def window(r: MissionReader, args: argparse.Namespace) -> tuple[int | None, int | None]:
    """--start-s / --end-s as int ns on the recording's clock (None: open)."""
    t0 = r.info().start_ns or 0
    lo = None if args.start_s is None else t0 + int(round(args.start_s * 1e9))
    hi = None if args.end_s is None else t0 + int(round(args.end_s * 1e9))
    return lo, hi


def loss_line(r: MissionReader, topic: str) -> str | None:
    """One line saying what damaged chunks of ``r`` lost of ``topic`` (None: nothing), for ``export``."""
    losses = [loss for loss in r.losses if loss.topic in (topic, None)]
    if not losses:
        return None
    n = sum(loss.count or 0 for loss in losses)
    unknown = any(loss.count is None for loss in losses)
    ranges = ", ".join(f"{loss.start_ns * 1e-9:.3f}..{loss.end_ns * 1e-9:.3f} s" for loss in losses)
    what = f"{n}{'+' if unknown else ''} messages" if n else "an unknown number of messages"
    return (f"{r.path}: {what} of {topic!r} lost in damaged chunks (t={ranges}); nothing exported "
            "(--allow-loss exports the rest)")
