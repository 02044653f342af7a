"""Graphs in YAML: loading (include, ${variables}, --set overrides), validation, building.

.. code-block:: yaml

    name: rslam-replay
    variables: {mission: missions/beynes.mcap}
    clock: {mode: replay, speed: max}      # mode: replay | realtime; speed: max | factor
    components:
      mission: {type: io.Replayer, params: {path: "${mission}"}}
      slam: {type: slam.RSlam, on_error: stop}   # on_error: stop | skip
    connections:
      - mission.radar/beams -> slam.beams        # "a.out -> b.in"; "[delay]" breaks a cycle
    record: {path: out/run.mcap, streams: ["slam.*"]}

Validation reports every problem at once, each with file:line:col. The YAML is read
with the safe loader only.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import yaml

from .registry import Registry
from .yamlloc import Loc, LocDict, LocList, YamlError, load_value, load_yaml

__all__ = [
    "GraphSpec", "ComponentSpec", "ConnectionSpec", "GraphError", "Problem", "load_graph",
    "load_graph_text", "resolve_graph", "closest", "did_you_mean", "parse_set", "TOP_KEYS",
]

TOP_KEYS = ("name", "description", "include", "variables", "clock", "components", "connections", "record")
COMPONENT_KEYS = ("type", "params", "on_error", "description")
CLOCK_KEYS = ("mode", "speed")
RECORD_KEYS = ("path", "streams", "compression", "foxglove", "chunk_size", "maxsize", "flush_period_s")
_VAR = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)\}")
_CONN = re.compile(r"^\s*([^.\s]+)\.(\S+)\s*->\s*([^.\s]+)\.(\S+?)\s*(\[delay\])?\s*$")


def closest(word: str, choices: Iterable[str], n: int = 1) -> str | None:
    m = difflib.get_close_matches(word, list(choices), n=n, cutoff=0.5)
    return ", ".join(m) if m else None


def did_you_mean(hint: str | None, otherwise: str = "") -> str:
    return f" (did you mean '{hint}'?)" if hint else otherwise


@dataclass(frozen=True)
class Problem:
    loc: Loc | None
    message: str

    def __str__(self) -> str:
        return f"{self.loc}: {self.message}" if self.loc else self.message


class GraphError(ValueError):
    """A graph that cannot run; ``problems`` lists every problem found, with locations."""

    def __init__(self, problems: list[Problem]) -> None:
        self.problems = problems
        n = len(problems)
        head = str(problems[0]) if n == 1 else f"{n} problems in graph:\n" + "\n".join(f"  {p}" for p in problems)
        super().__init__(head)


@dataclass
class ComponentSpec:
    id: str
    type: str
    params: dict[str, Any]
    on_error: str = "stop"
    loc: Loc | None = None
    param_locs: dict[str, Loc] = field(default_factory=dict)


@dataclass
class ConnectionSpec:
    src: str
    out: str
    dst: str
    inp: str
    delayed: bool = False
    loc: Loc | None = None

    def __str__(self) -> str:
        return f"{self.src}.{self.out} -> {self.dst}.{self.inp}" + (" [delay]" if self.delayed else "")


@dataclass
class GraphSpec:
    name: str = "graph"
    file: str = "<memory>"
    description: str = ""
    clock_mode: str = "replay"
    speed: Any = "max"
    components: dict[str, ComponentSpec] = field(default_factory=dict)
    connections: list[ConnectionSpec] = field(default_factory=list)
    record: dict[str, Any] | None = None
    record_loc: Loc | None = None
    variables: dict[str, Any] = field(default_factory=dict)
    source_text: str = ""

    def resolved(self) -> dict[str, Any]:
        """The graph as plain data with every include, variable and override applied."""
        return {
            "name": self.name,
            "clock": {"mode": self.clock_mode, "speed": self.speed},
            "components": {
                c.id: {"type": c.type, "params": dict(c.params), "on_error": c.on_error}
                for c in self.components.values()
            },
            "connections": [str(c) for c in self.connections],
            **({"record": dict(self.record)} if self.record else {}),
        }


# ----------------------------------------------------------------------------------
# loading

def _subst(value: Any, variables: dict[str, Any], loc: Loc | None, problems: list[Problem]) -> Any:
    if isinstance(value, str):
        m = _VAR.fullmatch(value)
        if m:
            if m.group(1) not in variables:
                problems.append(Problem(loc, f"undefined variable '${{{m.group(1)}}}'"))
                return value
            return variables[m.group(1)]

        def rep(mm: re.Match) -> str:
            if mm.group(1) not in variables:
                problems.append(Problem(loc, f"undefined variable '${{{mm.group(1)}}}'"))
                return mm.group(0)
            return str(variables[mm.group(1)])

        return _VAR.sub(rep, value)
    if isinstance(value, LocDict):
        out = LocDict({k: _subst(v, variables, value.value_where(k), problems) for k, v in value.items()})
        out.loc, out.key_locs, out.value_locs = value.loc, value.key_locs, value.value_locs
        return out
    if isinstance(value, LocList):
        out2 = LocList(_subst(v, variables, value.where(i), problems) for i, v in enumerate(value))
        out2.loc, out2.item_locs = value.loc, value.item_locs
        return out2
    if isinstance(value, dict):
        return {k: _subst(v, variables, loc, problems) for k, v in value.items()}
    if isinstance(value, list):
        return [_subst(v, variables, loc, problems) for v in value]
    return value


def _check_keys(d: LocDict, allowed: Iterable[str], what: str, problems: list[Problem]) -> None:
    allowed = tuple(allowed)
    for k in d:
        if k not in allowed:
            hint = closest(str(k), allowed)
            problems.append(Problem(d.where(k), f"unknown key '{k}' in {what}"
                                    + did_you_mean(hint, f"; expected one of {', '.join(allowed)}")))


def parse_set(item: str) -> tuple[str, str, Any]:
    """``comp.param=value`` -> (comp, param, value parsed as YAML scalar/list)."""
    if "=" not in item or "." not in item.split("=", 1)[0]:
        raise GraphError([Problem(None, f"--set {item!r}: expected COMPONENT.PARAM=VALUE")])
    key, raw = item.split("=", 1)
    comp, param = key.split(".", 1)
    try:
        value = load_value(raw)
    except yaml.YAMLError:
        value = raw
    return comp.strip(), param.strip(), value


def _read(path: Path, problems: list[Problem], seen: tuple[Path, ...]) -> tuple[LocDict, list[tuple[LocDict, Path]]]:
    """Read ``path`` and, depth first, its includes. Returns (doc, [(included doc, path)])."""
    doc = load_yaml(path)
    if not isinstance(doc, LocDict):
        raise GraphError([Problem(Loc(str(path), 1, 1), "a graph file must be a mapping (name:, components:, ...)")])
    chain: list[tuple[LocDict, Path]] = []
    inc = doc.get("include")
    if inc is not None:
        items = inc if isinstance(inc, list) else [inc]
        for i, item in enumerate(items):
            loc = inc.where(i) if isinstance(inc, LocList) else doc.value_where("include")
            if not isinstance(item, str):
                problems.append(Problem(loc, f"include expects a file name, got {item!r}"))
                continue
            p = (path.parent / item).resolve()
            if p in seen:
                problems.append(Problem(loc, f"include cycle: {item} is already being included"))
                continue
            if not p.exists():
                problems.append(Problem(loc, f"included file not found: {item}"))
                continue
            sub, subchain = _read(p, problems, (*seen, p))
            chain += subchain + [(sub, p)]
    return doc, chain


def load_graph(path: str | Path, registry: Registry, overrides: Iterable[str] = (),
               variables: dict[str, Any] | None = None, text: str | None = None) -> GraphSpec:
    """Load and validate a graph file; raise :class:`GraphError` with every problem."""
    from .build import validate

    spec, problems = resolve_graph(path, overrides, variables, text)
    problems += validate(spec, registry)
    if problems:
        raise GraphError(problems)
    return spec


def resolve_graph(path: str | Path, overrides: Iterable[str] = (), variables: dict[str, Any] | None = None,
                  text: str | None = None) -> tuple[GraphSpec, list[Problem]]:
    """Read a graph with its includes, variables and overrides applied, not yet checked
    against the plugins: (spec, problems found so far). A file that cannot be read at all
    raises :class:`GraphError`."""
    problems: list[Problem] = []
    path = Path(path)
    try:
        if text is not None:
            doc = load_yaml(path, text)
            chain: list[tuple[LocDict, Path]] = []
            if not isinstance(doc, LocDict):
                raise GraphError([Problem(Loc(str(path), 1, 1), "a graph file must be a mapping")])
        else:
            doc, chain = _read(path.resolve(), problems, (path.resolve(),))
    except YamlError as e:
        raise GraphError([Problem(None, str(e))]) from None
    spec = GraphSpec(name=path.stem, file=str(path))
    spec.source_text = text if text is not None else (path.read_text(encoding="utf-8") if path.exists() else "")
    # variables: included files first, then this file, then the caller's
    for d, _ in chain + [(doc, path)]:
        v = d.get("variables")
        if isinstance(v, dict):
            spec.variables.update(v)
        elif v is not None:
            problems.append(Problem(d.value_where("variables"), "variables must be a mapping NAME: value"))
    spec.variables.update(variables or {})
    for d, _ in chain + [(doc, path)]:
        _merge(spec, _subst(d, spec.variables, d.loc, problems), problems)
    for item in overrides:
        try:
            comp, param, value = parse_set(item)
        except GraphError as e:
            problems += e.problems
            continue
        if comp not in spec.components:
            hint = closest(comp, spec.components)
            problems.append(Problem(None, f"--set {item}: no component '{comp}'" + did_you_mean(hint)))
            continue
        spec.components[comp].params[param] = value
    return spec, problems


def load_graph_text(text: str, registry: Registry, name: str = "<graph>", **kw: Any) -> GraphSpec:
    return load_graph(name, registry, text=text, **kw)


def _merge(spec: GraphSpec, d: LocDict, problems: list[Problem]) -> None:
    _check_keys(d, TOP_KEYS, "graph", problems)
    if "name" in d:
        spec.name = str(d["name"])
    if "description" in d:
        spec.description = str(d["description"])
    clock = d.get("clock")
    if clock is not None:
        if not isinstance(clock, LocDict):
            problems.append(Problem(d.value_where("clock"),
                                    "clock must be a mapping {mode: replay|realtime, speed: max|N}"))
        else:
            _check_keys(clock, CLOCK_KEYS, "clock", problems)
            mode = clock.get("mode", spec.clock_mode)
            if mode not in ("replay", "realtime"):
                problems.append(Problem(clock.value_where("mode"),
                                        f"clock mode must be 'replay' or 'realtime', got {mode!r}"))
            spec.clock_mode = mode
            if "speed" in clock:
                from .clock import parse_speed
                try:
                    parse_speed(clock["speed"])
                    spec.speed = clock["speed"]
                except ValueError as e:
                    problems.append(Problem(clock.value_where("speed"), str(e)))
    comps = d.get("components")
    if comps is not None:
        if not isinstance(comps, LocDict):
            problems.append(Problem(d.value_where("components"),
                                    "components must be a mapping ID: {type: ..., params: ...}"))
        else:
            for cid, c in comps.items():
                _merge_component(spec, str(cid), c, comps.where(cid), problems)
    conns = d.get("connections")
    if conns is not None:
        if not isinstance(conns, LocList):
            problems.append(Problem(d.value_where("connections"), "connections must be a list of 'a.out -> b.in'"))
        else:
            for i, item in enumerate(conns):
                c = _parse_connection(item, conns.where(i), problems)
                if c:
                    spec.connections.append(c)
    rec = d.get("record")
    if rec is not None:
        if not isinstance(rec, LocDict):
            problems.append(Problem(d.value_where("record"), "record must be a mapping {path: ..., streams: [...]}"))
        else:
            _check_keys(rec, RECORD_KEYS, "record", problems)
            if "path" not in rec:
                problems.append(Problem(rec.loc, "record needs a 'path'"))
            spec.record, spec.record_loc = dict(rec), rec.loc


def _merge_component(spec: GraphSpec, cid: str, c: Any, loc: Loc, problems: list[Problem]) -> None:
    if "." in cid or "/" in cid or not cid:
        problems.append(Problem(loc, f"component id '{cid}' must not be empty nor contain '.' or '/'"))
        return
    if isinstance(c, str):  # shorthand  id: type.Name
        c = LocDict(type=c)
        c.loc, c.key_locs, c.value_locs = loc, {}, {}
    if not isinstance(c, LocDict):
        problems.append(Problem(loc, f"component '{cid}' must be a mapping {{type: ..., params: ...}}"))
        return
    _check_keys(c, COMPONENT_KEYS, f"component '{cid}'", problems)
    params = c.get("params") or LocDict()
    if not isinstance(params, dict):
        problems.append(Problem(c.value_where("params"), f"component '{cid}': params must be a mapping"))
        params = LocDict()
    old = spec.components.get(cid)
    if old is not None and "type" not in c:  # an includer refining an included component
        old.params.update(params)
        if isinstance(params, LocDict):
            old.param_locs.update(params.key_locs)
        if "on_error" in c:
            old.on_error = c["on_error"]
        return
    if "type" not in c:
        problems.append(Problem(loc, f"component '{cid}' has no 'type'"))
        return
    on_error = c.get("on_error", "stop")
    if on_error not in ("stop", "skip"):
        problems.append(Problem(c.value_where("on_error"),
                                f"component '{cid}': on_error must be 'stop' or 'skip', got {on_error!r}"))
    spec.components[cid] = ComponentSpec(
        cid, str(c["type"]), dict(params), on_error, c.where("type"),
        dict(params.key_locs) if isinstance(params, LocDict) else {},
    )


def _parse_connection(item: Any, loc: Loc, problems: list[Problem]) -> ConnectionSpec | None:
    if isinstance(item, dict):
        extra = set(item) - {"from", "to", "delay"}
        if extra or "from" not in item or "to" not in item:
            problems.append(Problem(loc, "a connection mapping takes 'from', 'to' and optionally 'delay'"))
            return None
        item = f"{item['from']} -> {item['to']}" + (" [delay]" if item.get("delay") else "")
    if not isinstance(item, str):
        problems.append(Problem(loc, f"a connection is 'component.output -> component.input', got {item!r}"))
        return None
    m = _CONN.match(item)
    if not m:
        problems.append(Problem(loc, f"cannot read connection {item!r}: "
                                     "expected 'component.output -> component.input'"))
        return None
    return ConnectionSpec(m.group(1), m.group(2), m.group(3), m.group(4), bool(m.group(5)), loc)
