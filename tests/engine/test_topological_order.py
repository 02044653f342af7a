"""The run order without networkx (impala_flow._network.topological_order) is networkx's."""

from __future__ import annotations

import random

import networkx as nx
import pytest

from impala_flow._network import topological_order


def _random_graph(rng: random.Random) -> tuple[list[str], list[tuple[str, str]]]:
    nodes = list(dict.fromkeys(f"c{rng.randint(0, 40)}" for _ in range(rng.randint(1, 12))))
    edges = []
    for _ in range(rng.randint(0, 20)):
        a, b = rng.choice(nodes), rng.choice(nodes)
        if rng.random() < 0.85 and nodes.index(a) >= nodes.index(b):  # mostly forward: DAGs and cycles both
            a, b = b, a
        if a != b or rng.random() < 0.1:  # a few self-loops
            edges.append((a, b))
    if rng.random() < 0.3:
        edges.append((rng.choice(nodes) + "x", rng.choice(nodes)))  # a node known from an edge only
    return nodes, edges


@pytest.mark.parametrize("seed", range(4))
def test_order_and_cycles_are_networkx_lexicographical_topological_sort(seed):
    rng = random.Random(seed)
    orders = cycles = 0
    for _ in range(400):
        nodes, edges = _random_graph(rng)
        g = nx.DiGraph()
        g.add_nodes_from(nodes)
        g.add_edges_from(edges)
        index = {n: i for i, n in enumerate(g)}
        for key in (str, index.__getitem__, lambda n: 0):  # the two keys the executors use, and all ties
            try:
                want = list(nx.lexicographical_topological_sort(g, key=key))
            except nx.NetworkXUnfeasible:
                want = None
            assert topological_order(nodes, edges, key) == want, (nodes, edges)
            orders += want is not None
            cycles += want is None
    assert orders > 300 and cycles > 100  # both cases exercised


GRAPH = """
name: t
components:
  src: {type: test.ScriptedSource, params: {ports: [out]}}
  a: {type: test.CollectingSink}
  b: {type: test.CollectingSink}
connections:
  - src.out -> a.x
  - src.out -> b.x
"""

RUN = f"""
import sys
from impala_flow.testing import CollectingSink, ScriptedSource, run_graph_text
summary, net = run_graph_text({GRAPH!r}, ScriptedSource, CollectingSink)
assert summary.error is None and [c.name for c in net.order()] == ["src", "a", "b"]
print("networkx" in sys.modules)
"""


def test_a_run_imports_no_networkx():
    """networkx costs 0.17 s to import: loading, validating, building and running a graph
    does without it (the graph command and a cycle's error message import it)."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", RUN], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "False"
