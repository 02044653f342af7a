"""Session: one run's plugins, graph, network and executor, built fresh every time.

    session = Session()                               # discovers installed plugins now
    spec = session.load("graphs/frontend.yaml", overrides=["pairer.pfa=1e-4"],
                        variables={"mission": "out/beynes.mcap"})
    summary = session.run(spec, speed="max")          # offline; SIGINT/SIGTERM stop cleanly

:meth:`Session.load` runs the graph pipeline in order, each stage its own module:
:meth:`~Session.read` (:mod:`impala_flow._load`: YAML -> spec) -> :meth:`~Session.resolve`
(:mod:`impala_flow._resolve`: relative paths) -> :meth:`~Session.validate`
(:mod:`impala_flow._validate`: against the installed plugins), then raises every problem at
once; :meth:`~Session.build` (:mod:`impala_flow._build`) makes the network
:meth:`~Session.run` hands to an executor. A caller that wants the problems rather than an
error (a sweep checking its graph) calls the stages itself.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from ._build import build
from ._clock import ReplayClock, parse_speed
from ._load import graph_files, read_graph
from ._network import Network
from ._offline import OfflineExecutor
from ._registry import Registry
from ._resolve import resolve_paths
from ._spec import GraphError, GraphSpec, Problem, capped
from ._summary import RunSummary
from ._validate import validate
from .plugins import load_registry, make_plugin_manager, warn_broken

__all__ = ["Session", "stop_on_signals"]


@contextlib.contextmanager
def stop_on_signals(stop: threading.Event) -> Iterator[None]:
    """Turn SIGINT/SIGTERM into ``stop.set()`` while inside (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    def handler(signum: int, frame: Any) -> None:
        stop.set()

    old = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)


class Session:
    """A run's plugin manager and registry (never built at import time).

    A plugin that fails to import or to register is left out with a warning (see
    :mod:`impala_flow.plugins`); it is listed in ``session.registry.broken``.
    """

    def __init__(self, extra_plugins: dict[str, Any] | None = None, entrypoints: bool = True) -> None:
        self.pm = make_plugin_manager(extra_plugins, entrypoints=entrypoints)
        self.registry: Registry = load_registry(self.pm)
        warn_broken(self.registry)
        self.stop_event = threading.Event()

    def load(self, path: str | Path, overrides: list[str] | tuple[str, ...] = (),
             variables: dict[str, Any] | None = None, text: str | None = None) -> GraphSpec:
        """Read, resolve and validate a graph file (or ``text`` named ``path``); raise
        :class:`GraphError` with every problem (at most 20 per file).

        ``variables`` are the caller's (``--var``): they win over the files' and a relative
        path starting with one of them stays relative to the working directory."""
        spec, problems = self.problems(path, overrides, variables, text)
        if problems:
            raise GraphError(capped(problems))
        self.pm.hook.impala_flow_graph_loaded(graph=spec)
        return spec

    def problems(self, path: str | Path, overrides: list[str] | tuple[str, ...] = (),
                 variables: dict[str, Any] | None = None, text: str | None = None) -> tuple[GraphSpec, list[Problem]]:
        """Read, resolve and validate a graph as :meth:`load` does, but return every problem
        found (each with ``.message`` and ``.loc``) instead of raising, so a caller can drop
        the ones it expects (e.g. a mission file that does not exist yet) before raising
        ``GraphError(problems)``. A file that cannot be read at all still raises
        :class:`~impala_flow.GraphError`."""
        spec, problems = self.read(path, overrides, variables, text)
        problems += self.resolve(spec)
        problems += self.validate(spec)
        return spec, problems

    @staticmethod
    def graph_files(path: str | Path) -> list[str]:
        """The graph file ``path`` and the files it includes (each once, the includes sorted):
        what a graph is made from, e.g. to fingerprint it. An unreadable graph gives ``[path]``
        alone (loading it says why)."""
        return graph_files(path)

    def load_text(self, text: str, name: str = "<graph>", **kw: Any) -> GraphSpec:
        """:meth:`load` of a graph given as text (``name`` locates its problems)."""
        return self.load(name, text=text, **kw)

    @staticmethod
    def read(path: str | Path, overrides: list[str] | tuple[str, ...] = (),
             variables: dict[str, Any] | None = None, text: str | None = None) -> tuple[GraphSpec, list[Problem]]:
        """Stage 1, *load*: the graph with its includes, variables and overrides applied, and
        the problems found so far; a file that cannot be read at all raises :class:`GraphError`."""
        return read_graph(path, overrides, variables, text)

    def resolve(self, spec: GraphSpec) -> list[Problem]:
        """Stage 2, *resolve*: the relative path parameters and ``record.path`` of ``spec``, in place."""
        return resolve_paths(spec, self.registry)

    def validate(self, spec: GraphSpec) -> list[Problem]:
        """Stage 3, *validate*: every problem of a resolved ``spec`` against the installed plugins."""
        return validate(spec, self.registry)

    def build(self, spec: GraphSpec) -> Network:
        """Stage 4, *build*: the network of a validated ``spec``."""
        return build(spec, self.registry)

    def run(self, spec: GraphSpec | Network, speed: Any = None, mode: str | None = None,
            progress: Callable[[int, int | None], None] | None = None,
            duration_s: float | None = None, blas_threads: int | None = 1) -> RunSummary:
        """Run a graph (or an already built network) offline or live.

        ``mode`` (``replay`` or ``realtime``) and ``speed`` (``'max'`` or a factor) default
        to the graph's ``clock:`` section; a bare network runs offline at max speed.
        ``duration_s`` stops the run after that many seconds of mission time (live: of wall
        time) as if the inputs ended there: what was read is processed and flushed
        (``summary.stopped_at_duration``). ``blas_threads``: the BLAS libraries' own threads while
        the components run (default 1: the run's components and their own pools already share the
        cores; None: the libraries' own; :mod:`impala_flow._native`).
        """
        duration_ns = None if duration_s is None else int(round(duration_s * 1e9))
        if isinstance(spec, Network):
            net, mode = spec, mode or "replay"
            speed = "max" if speed is None else speed
            for c in net.components.values():  # a component a command built itself: named as a graph names it
                if not type(c).__dict__.get("type_name"):
                    self.registry.name_of(type(c))
        else:
            net, mode = self.build(spec), mode or spec.clock_mode
            speed = spec.speed if speed is None else speed
        with stop_on_signals(self.stop_event):
            if mode == "realtime":
                from ._realtime import RealTimeExecutor

                return RealTimeExecutor(net, stop_event=self.stop_event, progress=progress,
                                        duration_ns=duration_ns, blas_threads=blas_threads).run()
            clock = ReplayClock(parse_speed(speed))
            return OfflineExecutor(net, clock, progress=progress, stop_event=self.stop_event,
                                   duration_ns=duration_ns, blas_threads=blas_threads).run()
