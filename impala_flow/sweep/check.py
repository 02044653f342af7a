"""Checks made on the client before anything is submitted, so a typo fails fast and located:
the graph is valid, every ``component.param`` of the grid names a component of the graph
and a parameter of its type, every metric names a component of the graph, and the
``simulate`` command exists when missions are simulated."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from .._component import Param
from .._load import read_graph as resolve_graph
from .._registry import Registry
from .._resolve import resolve_paths
from .._spec import GraphError, GraphSpec, closest, did_you_mean
from .._validate import validate
from .spec import SweepError, SweepSpec, format_value

__all__ = ["check_sweep"]


def check_sweep(spec: SweepSpec, registry: Registry, out_dir: str | Path, pm: object | None = None) -> GraphSpec:
    """Raise :class:`GraphError` (the graph itself) or :class:`SweepError` (the sweep file);
    return the graph as the first task would get it, without overrides."""
    # nothing here expands the sweep: the checks read its axes (a typo in a huge grid answers at once)
    files = spec.files
    # a simulated mission does not exist yet: a stand-in path, whose "cannot open" is not a problem
    stand_in = str(Path(out_dir).resolve() / "missions" / ".not-yet-simulated.mcap")
    mission = files[0] if files else stand_in
    variables = {**spec.variables, "mission": mission, "out": str(Path(out_dir).resolve() / "tasks" / "check")}
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
    _check_types(spec, graph, registry)
    for m in spec.metrics:
        comp = m.split(".")[0]
        if comp not in graph.components:
            raise SweepError(f"{spec.where(f'metric:{m}')}: metric {m}: no component '{comp}' in graph "
                             f"{spec.graph.name}" + did_you_mean(closest(comp, graph.components)))
    sims = [m[4:] for m, _, _ in spec.missions if m.startswith("sim:")]
    if pm is not None and sims:
        sub = argparse.ArgumentParser(add_help=False).add_subparsers()
        pm.hook.impala_flow_add_commands(subparsers=sub)  # type: ignore[attr-defined]
        if "simulate" not in sub.choices:
            raise SweepError(f"{spec.where(f'scenario:{sims[0]}')}: simulated missions need the 'simulate' "
                             "command, which no installed plugin provides (the radar plugin does)")
    return graph


def _type_problem(p: Param, value: Any) -> str | None:
    """Why ``value`` cannot be ``p``'s type (as ``--set`` would read it), or None; NaN is
    refused too (as :class:`Param` does). Bounds and choices are the task's to check: a
    variant out of range is a failed row, the others run."""
    t = p.type
    if isinstance(value, float) and math.isnan(value) and t in (float, int):
        return "NaN is not allowed (as for any parameter)"
    if t is float and isinstance(value, (int, float)) and not isinstance(value, bool):
        return None
    if t is list and isinstance(value, tuple):
        return None
    if isinstance(value, t) and not (t is int and isinstance(value, bool)):
        return None
    return f"expected {t.__name__}, got {type(value).__name__} {format_value(value)}"


def _check_types(spec: SweepSpec, graph: GraphSpec, registry: Registry) -> None:
    """Every value a variant sets (each written once in the sweep file, so this is linear in
    the file, not in the product) against its parameter's type, on the client: the first
    wrong one located in the sweep file, with how many more there are."""
    bad: list[str] = []
    for name, value, loc in spec.values:
        comp, param = name.split(".")
        c = graph.components.get(comp)
        cls = registry.components.get(c.type) if c is not None else None
        p = cls.__params__.get(param) if cls is not None else None
        why = _type_problem(p, value) if p is not None else None
        if why:
            bad.append(f"{loc}: {name}: {why} ({c.type} parameter '{param}' is a {p.type.__name__})")
    if bad:
        raise SweepError(bad[0] + (f" (and {len(bad) - 1} more wrong-typed value(s))" if len(bad) > 1 else ""))
