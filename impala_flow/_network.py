"""Network: component instances wired together, in graph order, ready for an executor.

Graph order (:meth:`Network.order`) is a topological order of the components over their
non-delayed connections (ties broken by the order the components were added), networkx's
``lexicographical_topological_sort`` (:func:`topological_order`, the same order without
importing networkx: 0.17 s of every start); it is the order of listings (``impala-flow graph``). Both executors run
in :func:`impala_flow._lifecycle.event_order` (start, stop, and the second key of the
deterministic event order): the same topological order with ties broken by component
id, so the order of a YAML file never changes a run's results.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Hashable, Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from ._component import Component, Source
from ._ports import InputPort, OutputPort

if TYPE_CHECKING:
    import networkx as nx

__all__ = ["Network", "Connection", "CycleError", "topological_order"]


def topological_order(nodes: Iterable[Hashable], edges: Iterable[tuple[Hashable, Hashable]],
                      key: Callable[[Any], Any]) -> list[Any] | None:
    """The order of ``networkx.lexicographical_topological_sort`` on the DiGraph of ``nodes``
    then ``edges`` (added in this order; repeated edges count once), ties broken by ``key``
    then by the order nodes were added; None when the edges form a cycle. networkx is slow to
    import (0.17 s) and only its error messages (:func:`networkx.find_cycle`) are needed."""
    succ: dict[Any, dict[Any, None]] = {n: {} for n in nodes}
    for a, b in edges:
        succ.setdefault(a, {})[b] = None
        succ.setdefault(b, {})
    indegree = dict.fromkeys(succ, 0)
    for children in succ.values():
        for c in children:
            indegree[c] += 1
    nodeid = {n: i for i, n in enumerate(succ)}
    ready = [(key(n), nodeid[n], n) for n, d in indegree.items() if d == 0]
    heapq.heapify(ready)
    out = []
    while ready:
        node = heapq.heappop(ready)[2]
        for c in succ[node]:
            indegree[c] -= 1
            if indegree[c] == 0:
                heapq.heappush(ready, (key(c), nodeid[c], c))
        out.append(node)
    return out if len(out) == len(succ) else None


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
        import networkx as nx  # here, not at import: 0.17 s, for the graph command and the error messages

        g = nx.DiGraph()
        g.add_nodes_from(self.components)
        g.add_edges_from(self.edges(include_delayed))
        return g

    def edges(self, include_delayed: bool = True) -> list[tuple[str, str]]:
        """(source component, destination component) per connection, in the order they were made."""
        return [(c.src.owner.name, c.dst.owner.name) for c in self.connections if include_delayed or not c.delayed]

    def order(self) -> list[Component]:
        index = {n: i for i, n in enumerate(self.components)}
        names = topological_order(self.components, self.edges(include_delayed=False), index.__getitem__)
        if names is None:
            import networkx as nx  # the cycle, named

            cycle = nx.find_cycle(self.digraph(include_delayed=False))
            path = " -> ".join([a for a, _ in cycle] + [cycle[0][0]])
            raise CycleError(f"cycle without a delayed connection: {path}")
        return [self.components[n] for n in names]

    def sources(self) -> list[Source]:
        return [c for c in self.order() if isinstance(c, Source)]
