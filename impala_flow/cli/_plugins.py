"""``impala-flow plugins``: installed plugins, their components, ports and parameters."""

from __future__ import annotations

import argparse
import json
from typing import Any

from .._component import Component, Input, Output, Param, Source
from .._registry import Registry
from ..msgs import is_message, schema_name
from .helpers import open_session

__all__ = ["add_parser", "run", "describe_plugins", "describe_component"]

EPILOG = """\
examples:
  impala-flow plugins                 every plugin, component, port and parameter
  impala-flow plugins --json | jq '.plugins[].components[].type'
  IMPALA_FLOW_DISABLE_PLUGINS=radar impala-flow plugins   without the 'radar' plugin

A plugin that fails to import or to register is listed as BROKEN with its error; every other
plugin still loads, and only graphs using the broken plugin's types fail. A plugin lacking a
library is listed with the line that brings it: NEEDS gtsam: pip install 'impala-flow[slam]'.

A component type is written '<plugin>.<Class>' in a graph (components: {p: {type: radar.FuzzyPairer}}).
Input policies: reactive (each sample triggers process), sampling (last value, never triggers),
sync=GROUP (fire together within a tolerance); history=S keeps S seconds for input.at(t).
Overflow of a full input FIFO: block, drop_oldest, drop_newest (drops are counted).
"""


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "plugins", help="list installed plugins, components, ports and parameters",
        description="List every installed plugin (entry point group 'impala_flow') with its version and "
        "its components: each component's ports (direction, message type, input policy, sync group, "
        "history, FIFO size and overflow policy) and parameters (type, default, bounds, choices, doc).",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--json", action="store_true", help="print JSON instead of text")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    registry = _load_registry()
    data = describe_plugins(registry)
    if args.json:
        print(json.dumps(data, indent=2))
    else:
        print(format_plugins(data))
    return 0


# --- loading: a broken plugin is listed, never fatal ------------------------------------------
def _load_registry() -> Registry:
    """The session's registry; plugins that failed to import or register are in ``.broken``."""
    return open_session().registry


# --- description as plain data --------------------------------------------------------------
def _type_name(t: Any) -> str:
    if t is object:
        return "any"
    if is_message(t):
        return schema_name(t)
    return getattr(t, "__name__", str(t))


def _first_line(doc: str | None) -> str:
    for line in (doc or "").strip().splitlines():
        if line.strip():
            return line.strip()
    return ""


def _jsonable(v: Any) -> Any:
    try:
        json.dumps(v, allow_nan=False)
        return v
    except (TypeError, ValueError):
        return repr(v)


def _input(name: str, d: Input) -> dict[str, Any]:
    return {
        "name": name, "direction": "in", "type": _type_name(d.type), "policy": d.policy, "sync": d.sync,
        "tolerance_s": d.tolerance if d.sync else None, "history_s": d.history, "maxsize": d.maxsize,
        "overflow": d.overflow, "required": d.required, "angular": d.angular, "doc": d.doc,
    }


def _output(name: str, d: Output) -> dict[str, Any]:
    return {"name": name, "direction": "out", "type": _type_name(d.type), "doc": d.doc}


def _param(name: str, p: Param) -> dict[str, Any]:
    return {
        "name": name, "type": getattr(p.type, "__name__", str(p.type)), "required": p.required,
        "default": None if p.required else _jsonable(p.default),
        **{k: getattr(p, k) for k in ("ge", "gt", "le", "lt")},
        "choices": None if p.choices is None else [_jsonable(c) for c in p.choices], "doc": p.doc,
    }


def describe_component(type_name: str, cls: type[Component]) -> dict[str, Any]:
    """A component type as plain data: docstring, ports, parameters, periodic timers."""
    ins, outs = dict(cls.__inputs__), dict(cls.__outputs__)
    dynamic = getattr(cls.declare_ports, "__func__", None) is not Component.declare_ports.__func__
    note = ""
    if dynamic:
        note = "ports depend on the parameters"
        values, problems = cls.validate_params({})
        if not problems:
            try:
                ins, outs = cls.declare_ports(values)
                note += "; shown for the defaults"
            except Exception:  # noqa: S110 - a listing must not fail on one component
                pass
    return {
        "type": type_name,
        "class": f"{cls.__module__}.{cls.__qualname__}",
        "kind": "source" if issubclass(cls, Source) else "component",
        "live": bool(cls.live),
        "summary": _first_line(cls.__doc__),
        "ports_note": note,
        "inputs": [_input(k, d) for k, d in ins.items()],
        "outputs": [_output(k, d) for k, d in outs.items()],
        "params": [_param(k, p) for k, p in cls.__params__.items()],
        "timers": [{"name": k, "period": t.period, "doc": t.doc} for k, t in cls.__timers__.items()],
    }


def describe_plugins(registry: Registry) -> dict[str, Any]:
    """Every plugin of ``registry`` with its version, components, message types and mission
    sources (name, help), and the broken ones (``broken``: name, entry point, version, error, hint,
    and the missing library with the line that installs it)."""
    registry.load_all()  # a component module failing to import joins ``broken`` here, before the listing
    plugins = []
    for info in sorted(registry.plugins.values(), key=lambda p: p.name):
        plugins.append({
            "name": info.name, "version": info.version, "module": info.module,
            "components": [describe_component(t, registry.components[t]) for t in info.components],
            "types": sorted(info.types),
            "mission_sources": [{"name": m.name, "help": m.help} for m in sorted(
                registry.mission_sources.values(), key=lambda m: m.name) if m.plugin == info.name],
        })
    broken = [{"name": b.name, "entry_point": b.target, "version": b.version, "error": b.error, "hint": b.hint,
               "missing": b.missing, "install": b.install}
              for b in sorted(registry.broken.values(), key=lambda b: b.name)]
    return {"plugins": plugins, "broken": broken}


# --- text -----------------------------------------------------------------------------------
def _table(rows: list[list[str]], indent: str) -> list[str]:
    """Rows of cells, columns aligned (the last cell is free text)."""
    if not rows:
        return []
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]) - 1)]
    out = []
    for r in rows:
        cells = [c.ljust(w) for c, w in zip(r[:-1], widths, strict=True)] + [r[-1]]
        out.append((indent + "  ".join(cells)).rstrip())
    return out


def _input_policy(p: dict[str, Any]) -> str:
    bits = [p["policy"]]
    if p["sync"]:
        bits = [f"sync={p['sync']} ±{p['tolerance_s']:g}s"]
    if p["history_s"] is not None:
        bits.append(f"history={p['history_s']:g}s")
    if p["policy"] != "sampling" or p["sync"]:
        bits.append(f"fifo={p['maxsize']} {p['overflow']}")
    if p["angular"]:
        bits.append("angular")
    if not p["required"]:
        bits.append("optional")
    return ", ".join(bits)


def _num(v: float) -> str:
    return str(int(v)) if isinstance(v, int) or (isinstance(v, float) and v.is_integer() and abs(v) < 1e15) else repr(v)


def _param_spec(p: dict[str, Any]) -> str:
    bits = ["required" if p["required"] else f"= {p['default']!r}"]
    ops = {"ge": ">=", "gt": ">", "le": "<=", "lt": "<"}
    bits += [f"{ops[k]} {_num(p[k])}" for k in ops if p[k] is not None]
    if p["choices"] is not None:
        bits.append("one of " + "|".join(str(c) for c in p["choices"]))
    return ", ".join(bits)


def format_component(c: dict[str, Any], indent: str = "  ") -> list[str]:
    kind = "source" if c["kind"] == "source" else ""
    if c["live"]:
        kind = "live source"
    head = f"{indent}{c['type']}" + (f" [{kind}]" if kind else "") + (f": {c['summary']}" if c["summary"] else "")
    lines = [head]
    sub = indent + "    "
    if c["ports_note"]:
        lines.append(f"{sub}({c['ports_note']})")
    rows = [["in", p["name"], p["type"], _input_policy(p), p["doc"]] for p in c["inputs"]]
    rows += [["out", p["name"], p["type"], "", p["doc"]] for p in c["outputs"]]
    rows += [["param", p["name"], p["type"], _param_spec(p), p["doc"]] for p in c["params"]]
    lines += _table(rows, sub)
    for t in c["timers"]:
        period = f"every {t['period']:g} s" if isinstance(t["period"], (int, float)) else f"every '{t['period']}' s"
        lines.append(f"{sub}timer {t['name']} {period}" + (f"  {t['doc']}" if t["doc"] else ""))
    return lines


def format_plugins(data: dict[str, Any]) -> str:
    """The text listing: one block per plugin, one per component, aligned columns."""
    plugins = data["plugins"]
    broken = data.get("broken", [])
    if not plugins and not broken:
        return "no plugin installed (entry point group 'impala_flow')"
    out: list[str] = []
    for b in broken:
        head = f"{b['name']} {b['version'] or '(no version)'}  [{b['entry_point']}]  "
        if b.get("missing"):  # a library its installation lacks: the line that brings it
            out.append(head + f"NEEDS {b['missing']}: " + (b.get("install") or "not installed"))
        else:
            out.append(head + f"BROKEN: {b['error']}")
        out.append(f"  left out: every other plugin works; graphs using '{b['name']}.*' types fail "
                   f"({b['hint']})")
        out.append("")
    for p in plugins:
        n = len(p["components"])
        out.append(f"{p['name']} {p['version'] or '(no version)'}  [{p['module']}]  "
                   f"{n} component{'s' if n != 1 else ''}")
        if p["types"]:
            out.append("  message types: " + ", ".join(p["types"]))
        for m in p.get("mission_sources", []):
            out.append(f"  mission source: {m['name']}" + (f" ({m['help']})" if m["help"] else ""))
        for c in p["components"]:
            out += format_component(c)
            out.append("")
        if not p["components"]:
            out.append("")
    total = sum(len(p["components"]) for p in plugins)
    out.append(f"{len(plugins)} plugin{'s' if len(plugins) != 1 else ''}, {total} component types"
               + (f", {len(broken)} broken plugin{'s' if len(broken) != 1 else ''} left out" if broken else ""))
    return "\n".join(out)
