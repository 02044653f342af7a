"""Testing helpers for plugin authors, also a pytest plugin (entry point ``pytest11``).

    from impala_flow.testing import ScriptedSource, CollectingSink, run_components

    def test_scale():
        src = ScriptedSource("src", samples=[(0, "out", 1.0), (10, "out", 2.0)])
        sink = CollectingSink("sink")
        run_components(src, Scale("scale", gain=3.0), sink,
                       connections=["src.out -> scale.x", "scale.y -> sink.x"])
        assert sink.values() == [3.0, 6.0]

Fixtures: ``impala_session`` (a fresh :class:`Session` of the installed plugins),
``run_graph_text`` (run a YAML string with extra in-test components), ``fake_clock``.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import Any

from ._clock import FakeClock, ReplayClock
from ._component import Component, Input, Output, Param, Source
from ._network import Network
from ._offline import OfflineExecutor
from ._sample import Sample
from ._session import Session
from ._spec import CONNECTION
from ._summary import RunSummary
from .hookspecs import hookimpl

__all__ = [
    "ScriptedSource", "CollectingSink", "run_components", "connect", "plugin_of", "FakeClock",
    "run_graph_text",
]


class ScriptedSource(Source):
    """Emits a scripted list of ``(t_ns, port, data)`` (ports named in ``ports``)."""

    ports = Param(list, default=["out"], doc="output port names")

    def __init__(self, name: str = "src", samples: Iterable[tuple[int, str, Any]] = (), **params: Any) -> None:
        self.script = list(samples)
        if "ports" not in params:
            params["ports"] = sorted({p for _, p, _ in self.script}) or ["out"]
        super().__init__(name, **params)

    @classmethod
    def declare_ports(cls, params: dict[str, Any]) -> tuple[dict[str, Input], dict[str, Output]]:
        return {}, {p: Output(object) for p in params["ports"]}

    def generate(self) -> Iterator[tuple[int, str, Any]]:
        yield from self.script

    def duration_hint_ns(self) -> int | None:
        return (self.script[-1][0] - self.script[0][0]) if self.script else None


class CollectingSink(Component):
    """Keeps every sample it receives on input ``x`` (or on the inputs named in ``ports``)."""

    ports = Param(list, default=["x"], doc="input port names")
    policy = Param(str, default="reactive", choices=("reactive", "sampling"))

    @classmethod
    def declare_ports(cls, params: dict[str, Any]) -> tuple[dict[str, Input], dict[str, Output]]:
        return {p: Input(object, policy=params["policy"]) for p in params["ports"]}, {}

    def start(self) -> None:
        self.samples: list[Sample] = []
        self.by_port: dict[str, list[Sample]] = {p: [] for p in self.inputs}

    def process(self, t: int) -> None:
        port = self.inputs[self.trigger]
        s = port.take_sample()
        self.samples.append(s)
        self.by_port[self.trigger].append(s)

    def values(self, port: str | None = None) -> list[Any]:
        return [s.data for s in (self.samples if port is None else self.by_port[port])]

    def times(self, port: str | None = None) -> list[int]:
        return [s.timestamp for s in (self.samples if port is None else self.by_port[port])]


def connect(net: Network, spec: str) -> None:
    """Wire ``"a.out -> b.in"`` (``[delay]`` suffix allowed) inside ``net``."""
    m = CONNECTION.match(spec)
    if not m:
        raise ValueError(f"cannot read connection {spec!r}")
    a, out, b, inp, delay = m.groups()
    net.connect(net.components[a].outputs[out], net.components[b].inputs[inp], bool(delay))


def run_components(*components: Component, connections: Iterable[str] = (), speed: float | None = None,
                   clock: ReplayClock | None = None, name: str = "test") -> RunSummary:
    """Run components wired by ``connections`` on the deterministic executor."""
    net = Network(name=name)
    for c in components:
        net.add(c)
    for spec in connections:
        connect(net, spec)
    return OfflineExecutor(net, clock or ReplayClock(speed)).run()


def plugin_of(*classes: type[Component]) -> object:
    """A plugin object registering ``classes`` (pass it to ``Session(extra_plugins=...)``)."""

    class _Plugin:
        @staticmethod
        @hookimpl
        def impala_flow_register(registry: Any) -> None:
            for c in classes:
                registry.add_component(c)

    return _Plugin()


def run_graph_text(text: str, *classes: type[Component], plugin: str = "test", speed: Any = "max",
                   overrides: Iterable[str] = ()) -> tuple[RunSummary, Network]:
    """Load, validate and run a YAML graph; ``classes`` are registered as ``<plugin>.<Class>``."""
    session = Session(extra_plugins={plugin: plugin_of(*classes)} if classes else None)
    spec = session.load_text(text, overrides=list(overrides))
    net = session.build(spec)
    return session.run(net, speed=speed), net


# --- pytest plugin ---------------------------------------------------------------------
try:
    import pytest
except ImportError:  # pragma: no cover - pytest is only needed for the fixtures
    pytest = None  # type: ignore[assignment]

if pytest is not None:

    @pytest.fixture
    def impala_session() -> Session:
        """A fresh session with the installed plugins."""
        return Session()

    @pytest.fixture
    def fake_clock() -> FakeClock:
        return FakeClock(1.0)
