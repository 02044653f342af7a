"""Stage 3 of graph loading, *validate*: a resolved spec checked against the installed plugins.

Every problem is collected, none stops the scan: unknown types (with the closest installed),
parameters, ports and port types, required inputs, cycles without a delay, record streams,
a live source in an offline graph, and the files the graph reads and writes
(:func:`impala_flow._paths.check_paths`). Runs after *resolve* (:mod:`impala_flow._resolve`)
and before *build* (:mod:`impala_flow._build`).
"""

from __future__ import annotations

import fnmatch
from typing import Any

from ._component import Component, Input, Output
from ._network import topological_order
from ._paths import check_paths
from ._registry import Registry
from ._spec import GraphSpec, Problem, closest, did_you_mean
from ._yamlloc import Loc, brief

__all__ = ["validate", "resolve_record", "RECORDER_TYPE", "RECORDER_ID"]

RECORDER_TYPE = "io.Recorder"
RECORDER_ID = "record"


def _compatible(out_t: type, in_t: type) -> bool:
    return in_t is object or out_t is object or (isinstance(out_t, type) and issubclass(out_t, in_t))


def _tname(t: type) -> str:
    return getattr(t, "__name__", str(t))


PortTable = dict[str, tuple[type[Component], dict, dict[str, Input], dict[str, Output]]]


def _ports(spec: GraphSpec, registry: Registry, problems: list[Problem]) -> PortTable:
    out: dict[str, Any] = {}
    for c in spec.components.values():
        cls = registry.components.get(c.type)
        if cls is None:
            why = registry.why_unknown(c.type)
            if why is not None:  # its plugin is installed but broken: say so, not "did you mean"
                problems.append(Problem(c.loc, f"component '{c.id}': {why}"))
                continue
            hint = closest(c.type, registry.components, n=3)
            # the same class in another plugin (io.FoxgloveBridge moved to view.FoxgloveBridge): say so
            moved = [t for t in registry.components if t.split(".", 1)[-1] == c.type.split(".", 1)[-1]]
            also = f"; did you mean '{moved[0]}'? plugin '{moved[0].split('.')[0]}' has it" if len(moved) == 1 else ""
            problems.append(Problem(c.loc, f"component '{c.id}': unknown type '{c.type}'"
                                    + (f" (closest installed: {hint}{also})" if hint else
                                       f" (installed: {', '.join(sorted(registry.components)) or 'none'})")))
            continue
        values, bad = cls.validate_params(c.params)
        for k, msg in bad.items():
            problems.append(Problem(c.param_locs.get(k, c.loc),
                                    f"component '{c.id}' ({c.type}): parameter '{k}': {msg}"))
        if bad:  # still check its connections against the class's own declarations
            out[c.id] = (cls, values, dict(cls.__inputs__), dict(cls.__outputs__))
            continue
        try:
            ins, outs = cls.declare_ports(values)
        except Exception as e:
            problems.append(Problem(c.loc, f"component '{c.id}' ({c.type}): {e}"))
            continue
        out[c.id] = (cls, values, ins, outs)
    return out


def resolve_record(spec: GraphSpec, outputs: dict[str, dict[str, Output]], problems: list[Problem]) -> dict[str, str]:
    """``record.streams`` patterns -> {topic: "component.port"} (topic is ``component/port``
    unless a stream is given as ``{from: component.port, topic: name}``)."""
    rec = spec.record or {}
    streams = rec.get("streams", ["*"])
    topics: dict[str, str] = {}
    every = [f"{cid}.{p}" for cid, ports in outputs.items() for p in ports]
    if not isinstance(streams, list):
        problems.append(Problem(spec.record_loc,
                                "record streams must be a list of patterns like 'slam.pose' or 'radar/*'"))
        return topics
    for item in streams:
        if isinstance(item, dict) and set(item) <= {"from", "topic"} and "from" in item:
            if item["from"] not in every:
                problems.append(Problem(spec.record_loc, f"record: no output '{item['from']}'"))
                continue
            topics[str(item.get("topic") or item["from"].replace(".", "/", 1))] = item["from"]
            continue
        if not isinstance(item, str):
            problems.append(Problem(spec.record_loc,
                                    f"record: a stream is a pattern or {{from:, topic:}}, got {brief(item)}"))
            continue
        hits = [o for o in every if fnmatch.fnmatchcase(o, item) or fnmatch.fnmatchcase(o.replace(".", "/", 1), item)]
        if not hits:
            problems.append(Problem(spec.record_loc, f"record: pattern '{item}' matches no output"))
        for o in hits:
            topics.setdefault(o.replace(".", "/", 1), o)
    return topics


def validate(spec: GraphSpec, registry: Registry) -> list[Problem]:
    """Every problem of ``spec``: an empty graph, types, parameters, ports, port types,
    required inputs, cycles without a delay, record streams, a live source in an offline
    (``mode: replay``) graph, files written over files read or in folders that cannot be
    created (:func:`impala_flow._paths.check_paths`)."""
    problems: list[Problem] = []
    if not spec.components:
        problems.append(Problem(Loc(spec.file, 1, 1), "the graph has no components: nothing to run"))
    ports = _ports(spec, registry, problems)
    if spec.clock_mode == "replay":
        for cid, (cls, _, _, _) in ports.items():
            if cls.live:
                problems.append(Problem(spec.components[cid].loc, f"component '{cid}' ({spec.components[cid].type}) "
                                        "is a live source: an offline graph (clock mode 'replay') cannot run it; "
                                        "set clock: {mode: realtime}"))
    connected: set[tuple[str, str]] = set()
    edges: list[tuple[str, str, Any]] = []
    for c in spec.connections:
        ok = True
        for cid in (c.src, c.dst):
            if cid not in spec.components:
                hint = closest(cid, spec.components)
                problems.append(Problem(c.loc, f"connection '{c}': no component '{cid}'" + did_you_mean(hint)))
                ok = False
        if not ok:
            continue
        outs = ports[c.src][3] if c.src in ports else None
        ins = ports[c.dst][2] if c.dst in ports else None
        if outs is not None and c.out not in outs:
            hint = closest(c.out, outs)
            problems.append(Problem(c.loc, f"connection '{c}': '{c.src}' ({spec.components[c.src].type}) "
                                    f"has no output '{c.out}'"
                                    + did_you_mean(hint, f"; outputs: {', '.join(outs) or 'none'}")))
            ok = False
        if ins is not None and c.inp not in ins:
            hint = closest(c.inp, ins)
            problems.append(Problem(c.loc, f"connection '{c}': '{c.dst}' ({spec.components[c.dst].type}) "
                                    f"has no input '{c.inp}'"
                                    + did_you_mean(hint, f"; inputs: {', '.join(ins) or 'none'}")))
            ok = False
        if ok and ins is not None:
            connected.add((c.dst, c.inp))
        if not ok or outs is None or ins is None:
            continue
        if not _compatible(outs[c.out].type, ins[c.inp].type):
            problems.append(Problem(c.loc, f"connection '{c}': output type {_tname(outs[c.out].type)} "
                                    f"does not fit input type {_tname(ins[c.inp].type)}"))
        if not c.delayed:
            edges.append((c.src, c.dst, c))
    for cid, (_, _, ins, _) in ports.items():
        comp = spec.components[cid]
        for name in comp.inputs:  # the graph's bounds of an input: the input must exist
            if name not in ins:
                problems.append(Problem(comp.input_locs.get(name, comp.loc),
                                        f"component '{cid}' ({comp.type}): inputs: no input '{name}'"
                                        + did_you_mean(closest(name, ins), f"; inputs: {', '.join(ins) or 'none'}")))
        for name, decl in ins.items():
            if decl.required and (cid, name) not in connected and cid != RECORDER_ID:
                problems.append(Problem(spec.components[cid].loc,
                                        f"component '{cid}': required input '{name}' is not connected"))
    if topological_order((), ((a, b) for a, b, _ in edges), str) is None:  # a cycle: networkx names it
        import networkx as nx  # only then: it is slow to import

        g = nx.DiGraph()
        for a, b, c in edges:
            g.add_edge(a, b, conn=c)
        cyc = nx.find_cycle(g)
        conn = g.edges[cyc[0][0], cyc[0][1]]["conn"]
        path = " -> ".join([a for a, _ in cyc] + [cyc[0][0]])
        problems.append(Problem(conn.loc, f"cycle without a delay: {path} (mark one connection '[delay]')"))
    if spec.record is not None:
        if RECORDER_TYPE not in registry.components:
            problems.append(Problem(spec.record_loc, f"record: needs the '{RECORDER_TYPE}' component "
                                    "(the engine's own: every registry of impala_flow.plugins has it)"))
        else:
            resolve_record(spec, {cid: p[3] for cid, p in ports.items()}, problems)
            # its parameters (chunk_size, flush_period_s, ...) are checked now, not when it is built
            given = {k: v for k, v in spec.record.items() if k != "streams"}
            _, bad = registry.components[RECORDER_TYPE].validate_params(given)
            for k, msg in bad.items():
                problems.append(Problem(spec.record_loc, f"record: '{k}': {msg}"))
            if spec.record.get("ros2") and "ros2" not in registry.foreign_writers and "ros2" not in bad:
                broken = registry.broken.get("ros2")
                why = broken.needs or broken.describe() if broken else "no plugin registers it (the 'ros2' plugin: " \
                    "pip install 'impala-flow[ros2]')"
                problems.append(Problem(spec.record_loc, f"record: 'ros2': ros2 output unavailable: {why}"))
    problems += check_paths(spec, registry)
    return problems
