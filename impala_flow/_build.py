"""Stage 4 of graph loading, *build*: the :class:`~impala_flow._network.Network` a validated
spec describes (components instantiated with their parameters, connections wired, the
``record:`` section turned into an ``io.Recorder`` component), and its Graphviz text.
Runs after *validate* (:mod:`impala_flow._validate`); an executor runs what it returns.
"""

from __future__ import annotations

from ._network import CycleError, Network
from ._registry import Registry
from ._spec import GraphError, GraphSpec, Problem
from ._validate import RECORDER_ID, RECORDER_TYPE, resolve_record

__all__ = ["build", "to_dot"]


def build(spec: GraphSpec, registry: Registry) -> Network:
    """Instantiate and wire the components of a validated ``spec``."""
    net = Network(name=spec.name)
    net.metadata["graph"] = spec.resolved()
    for c in spec.components.values():
        cls = registry.components[c.type]
        comp = cls(name=c.id, **c.params)
        comp.registry = registry
        for name, bounds in c.inputs.items():  # the graph's bounds of an input, over the component's own
            port = comp.inputs[name]
            port.maxsize = bounds.get("maxsize", port.maxsize)
            port.overflow = bounds.get("overflow", port.overflow)
            port.maxbytes = bounds.get("maxbytes", port.maxbytes)
        net.add(comp, on_error=c.on_error)
    for c in spec.connections:
        net.connect(net.components[c.src].outputs[c.out], net.components[c.dst].inputs[c.inp], c.delayed)
    if spec.record is not None:
        problems: list = []
        topics = resolve_record(spec, {k: v.outputs for k, v in net.components.items()}, problems)
        if problems:
            raise GraphError(problems)
        params = {k: v for k, v in spec.record.items() if k != "streams"}
        if spec.clock_mode == "replay":
            # offline: chunks by size only, never by wall time, so the same inputs give the
            # same bytes at any replay speed (a live run keeps its crash-safety flushes)
            params.setdefault("flush_period_s", 0.0)
        params.update(topics=topics, graph=spec.resolved(),
                      plugins={n: p.version for n, p in registry.plugins.items()})
        rec = registry.components[RECORDER_TYPE](name=RECORDER_ID, **params)
        rec.registry = registry
        net.add(rec)
        for topic, origin in topics.items():
            cid, port = origin.split(".", 1)
            net.connect(net.components[cid].outputs[port], rec.inputs[topic])
    try:
        net.order()
    except CycleError as e:
        raise GraphError([Problem(None, str(e))]) from None
    return net


def _dot_id(text: str) -> str:
    """A quoted DOT string (its backslashes are kept: label escapes like ``\\n`` work)."""
    return '"' + text.replace('"', '\\"') + '"'


def _record_text(text: str) -> str:
    """Text of a record field, its special characters escaped."""
    out = text.replace("\\", "\\\\")
    for ch in "{}|<>":
        out = out.replace(ch, "\\" + ch)
    return out


def to_dot(net: Network) -> str:
    """Graphviz DOT text of a built network.

    One record-shaped node per component, in graph order: its inputs on the left, its
    id and type in the middle, its outputs on the right. One edge per connection, from
    the output field to the input field; delayed connections are dashed and do not
    constrain the ranks. Render with ``dot -Tsvg``.
    """
    lines = [
        f"digraph {_dot_id(net.name)} {{",
        "  rankdir=LR;",
        f"  label={_dot_id(net.name)}; labelloc=t; fontname=Helvetica;",
        '  node [shape=record, style="rounded,filled", fillcolor="#eef3fb", fontname=Helvetica, fontsize=11];',
        "  edge [fontname=Helvetica, fontsize=9, color=\"#4a5a70\"];",
    ]
    for c in net.order():
        kind = type(c).type_name or type(c).__name__
        ins = "|".join(f"<i{k}> {_record_text(n)}" for k, n in enumerate(c.inputs))
        outs = "|".join(f"<o{k}> {_record_text(n)}" for k, n in enumerate(c.outputs))
        middle = f"{_record_text(c.name)}\\n{_record_text(kind)}"
        fields = ([f"{{{ins}}}"] if ins else []) + [middle] + ([f"{{{outs}}}"] if outs else [])
        lines.append(f"  {_dot_id(c.name)} [label={_dot_id('{' + ' | '.join(fields) + '}')}];")
    for conn in net.connections:
        src, dst = conn.src.owner, conn.dst.owner
        o = list(src.outputs).index(conn.src.name)
        i = list(dst.inputs).index(conn.dst.name)
        attrs = f"tooltip={_dot_id(str(conn))}"
        if conn.delayed:
            attrs += ', style=dashed, constraint=false, label="delay"'
        lines.append(f"  {_dot_id(src.name)}:o{o}:e -> {_dot_id(dst.name)}:i{i}:w [{attrs}];")
    lines.append("}")
    return "\n".join(lines) + "\n"
