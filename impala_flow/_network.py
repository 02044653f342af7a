"""Network: component instances wired together, in graph order, ready for an executor.

Graph order (:meth:`Network.order`) is a topological order of the components over their
non-delayed connections (ties broken by the order the components were added), computed
with networkx; it is the order of listings (``impala-flow graph``). Both executors run
in :func:`impala_flow._lifecycle.event_order` (start, stop, and the second key of the
deterministic event order): the same topological order with ties broken by component
id, so the order of a YAML file never changes a run's results.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import networkx as nx

from ._component import Component, Source
from ._ports import InputPort, OutputPort

__all__ = ["Network", "Connection", "CycleError"]


class CycleError(ValueError):
    """Connections form a cycle with no delayed connection in it."""


@dataclass(frozen=True)
class Connection:
    src: OutputPort
    dst: InputPort
    delayed: bool = False

    def __str__(self) -> str:
        arrow = "-[delay]->" if self.delayed else "->"
        return f"{self.src.origin} {arrow} {self.dst.owner.name}.{self.dst.name}"


@dataclass
class Network:
    """Components and connections; ``order()`` gives the graph order."""

    name: str = "graph"
    components: dict[str, Component] = field(default_factory=dict)
    connections: list[Connection] = field(default_factory=list)
    on_error: dict[str, str] = field(default_factory=dict)  # component -> "stop" | "skip"
    metadata: dict[str, Any] = field(default_factory=dict)

    def add(self, comp: Component, on_error: str = "stop") -> Component:
        if comp.name in self.components:
            raise ValueError(f"two components are named '{comp.name}'")
        self.components[comp.name] = comp
        self.on_error[comp.name] = on_error
        return comp

    def connect(self, src: OutputPort, dst: InputPort, delayed: bool = False) -> Connection:
        c = Connection(src, dst, delayed)
        src._targets.append((dst, delayed))
        dst.sources.append(src)
        dst.connected = True
        dst.fed_back = dst.fed_back or delayed
        self.connections.append(c)
        return c

    def digraph(self, include_delayed: bool = True) -> nx.DiGraph:
        g = nx.DiGraph()
        g.add_nodes_from(self.components)
        for c in self.connections:
            if include_delayed or not c.delayed:
                g.add_edge(c.src.owner.name, c.dst.owner.name)
        return g

    def order(self) -> list[Component]:
        g = self.digraph(include_delayed=False)
        index = {n: i for i, n in enumerate(self.components)}
        try:
            names = list(nx.lexicographical_topological_sort(g, key=index.__getitem__))
        except nx.NetworkXUnfeasible:
            cycle = nx.find_cycle(g)
            path = " -> ".join([a for a, _ in cycle] + [cycle[0][0]])
            raise CycleError(f"cycle without a delayed connection: {path}") from None
        return [self.components[n] for n in names]

    def sources(self) -> list[Source]:
        return [c for c in self.order() if isinstance(c, Source)]
