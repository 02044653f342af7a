"""Checks made on the client before anything is submitted, so a typo fails fast and located:
the graph is valid, every ``component.param`` of the grid names a component of the graph
and a parameter of its type, every metric names a component of the graph, and the
``simulate`` command exists when missions are simulated."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..build import validate
from ..graph import resolve_graph
from ..paths import resolve_paths
from ..registry import Registry
from ..spec import GraphError, GraphSpec, closest, did_you_mean
from .spec import SweepError, SweepSpec

__all__ = ["check_sweep"]


def check_sweep(spec: SweepSpec, registry: Registry, out_dir: str | Path, pm: object | None = None) -> GraphSpec:
    """Raise :class:`GraphError` (the graph itself) or :class:`SweepError` (the sweep file);
    return the graph as the first task would get it, without overrides."""
    files = [t.mission for t in spec.tasks if not t.simulated]
    # a simulated mission does not exist yet: a stand-in path, whose "cannot open" is not a problem
    stand_in = str(Path(out_dir).resolve() / "missions" / ".not-yet-simulated.mcap")
    mission = files[0] if files else stand_in
    first = spec.tasks[0]
    variables = {**spec.variables, "mission": mission, "out": str(Path(out_dir).resolve() / "tasks" / first.id)}
    graph, problems = resolve_graph(spec.graph, (), variables)
    problems += resolve_paths(graph, registry)
    problems += validate(graph, registry)
    problems = [p for p in problems if stand_in not in p.message]
    if problems:
        raise GraphError(problems)
    for name in spec.param_names:
        comp, param = name.split(".")
        where = spec.where(f"param:{name}")
        c = graph.components.get(comp)
        if c is None:
            raise SweepError(f"{where}: {name}: no component '{comp}' in graph {spec.graph.name}"
                             + did_you_mean(closest(comp, graph.components)))
        cls = registry.components.get(c.type)
        if cls is not None and param not in cls.__params__:
            raise SweepError(f"{where}: {name}: {c.type} has no parameter '{param}'"
                             + did_you_mean(closest(param, cls.__params__),
                                            f" (parameters: {', '.join(cls.__params__)})"))
    for m in spec.metrics:
        comp = m.split(".")[0]
        if comp not in graph.components:
            raise SweepError(f"{spec.where(f'metric:{m}')}: metric {m}: no component '{comp}' in graph "
                             f"{spec.graph.name}" + did_you_mean(closest(comp, graph.components)))
    if pm is not None and any(t.simulated for t in spec.tasks):
        sub = argparse.ArgumentParser(add_help=False).add_subparsers()
        pm.hook.impala_flow_add_commands(subparsers=sub)  # type: ignore[attr-defined]
        if "simulate" not in sub.choices:
            t = next(t for t in spec.tasks if t.simulated)
            raise SweepError(f"{spec.where(f'scenario:{t.scenario}')}: simulated missions need the 'simulate' "
                             "command, which no installed plugin provides (the radar plugin does)")
    return graph
