"""Stage 1 of graph loading, *load*: YAML files -> :class:`~impala_flow._spec.GraphSpec`.

The pipeline, run in order by :class:`impala_flow.Session`: **load** (this module: include,
``${variables}``, ``--set`` overrides, every value located) -> **resolve**
(:mod:`impala_flow._resolve`: relative paths) -> **validate** (:mod:`impala_flow._validate`:
against the installed plugins) -> **build** (:mod:`impala_flow._build`: the network).
Each stage returns the problems it found; the session raises them all at once.

.. code-block:: yaml

    name: rslam-replay
    variables: {mission: missions/beynes.mcap, out: out/rslam, log: "${out}/log"}
    clock: {mode: replay, speed: max}      # mode: replay | realtime; speed: max | factor
    components:
      mission: {type: io.Replayer, params: {path: "${mission}"}}
      slam: {type: slam.RSlam, on_error: stop}   # on_error: stop | skip
      # an input's bounds, over the component's own: a slow stage keeps the newest turn
      # rslam: {type: slam.RSlam, inputs: {image: {maxsize: 1, overflow: drop_oldest}}}
    connections:
      - mission.radar/beams -> slam.beams        # "a.out -> b.in"; "[delay]" breaks a cycle
    record: {path: "${out}/run.mcap", streams: ["slam.*"]}

- ``include:`` merges other files first (relative to the including file; a file included
  twice is merged once). A component id defined again with a ``type`` is an error naming
  both places unless written with ``override: true`` (it then replaces the included one);
  without ``type`` it refines the included component's parameters. A connection written
  twice (in one file or across includes) is an error.
- ``${name}`` is replaced by the variable's value, also inside other variables' values
  (a cycle is an error). Caller variables (``--var``) win over the files' and must name
  a variable the graph declares or uses.
- Each parameter and ``record.path`` notes the folder it is relative to (the folder of the
  file it is written in, or the working directory for a value that starts with a variable
  given on the command line or comes from ``--set``); the next stage,
  :mod:`impala_flow._resolve`, resolves the paths against it.

Loading checks what the files alone say (keys, variable cycles, connection syntax, ids);
validation (:func:`impala_flow._validate.validate`) reports every other problem, each with
file:line:col. The YAML is read with the safe loader only (see :mod:`impala_flow._yamlloc`).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import yaml

from ._ports import OVERFLOWS
from ._spec import (
    CONNECTION,
    ComponentSpec,
    ConnectionSpec,
    GraphError,
    GraphSpec,
    Problem,
    checked_speed,
    closest,
    component_id_problem,
    did_you_mean,
)
from ._yamlloc import (
    MAX_BYTES,
    Loc,
    LocDict,
    LocList,
    YamlError,
    brief,
    decode_text,
    load_value,
    load_yaml,
    read_bounded,
    shown,
)

__all__ = ["read_graph", "parse_set", "TOP_KEYS", "COMPONENT_KEYS", "INPUT_KEYS", "CLOCK_KEYS", "RECORD_KEYS",
           "MAX_GRAPH_BYTES", "graph_files"]

TOP_KEYS = ("name", "description", "include", "variables", "clock", "components", "connections", "record")
COMPONENT_KEYS = ("type", "params", "on_error", "description", "override", "inputs")
#: what a graph may set of a component's input (``inputs: {name: {...}}``)
INPUT_KEYS = ("maxsize", "overflow", "maxbytes")
CLOCK_KEYS = ("mode", "speed")
RECORD_KEYS = ("path", "streams", "compression", "foxglove", "ros2", "chunk_size", "maxsize", "flush_period_s",
               "threads")
#: most bytes of a graph with all its includes (validation stays well under a second)
MAX_GRAPH_BYTES = 2 * MAX_BYTES
_VAR = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)\}")
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")

Lookup = Callable[[str, "Loc | None"], tuple[bool, Any]]


# ----------------------------------------------------------------------------------
# variables

def _subst(value: Any, lookup: Lookup, loc: Loc | None, problems: list[Problem]) -> Any:
    """``value`` with every ``${name}`` replaced (a whole ``${name}`` keeps the value's type)."""
    if isinstance(value, str):
        if "${" not in value:
            return value
        m = _VAR.fullmatch(value)
        if m:
            found, v = lookup(m.group(1), loc)
            return v if found else value

        def rep(mm: re.Match) -> str:
            found, v = lookup(mm.group(1), loc)
            return str(v) if found else mm.group(0)

        return _VAR.sub(rep, value)
    if isinstance(value, LocDict):
        out = LocDict({k: _subst(v, lookup, value.value_where(k), problems) for k, v in value.items()})
        out.loc, out.key_locs, out.value_locs = value.loc, value.key_locs, value.value_locs
        return out
    if isinstance(value, LocList):
        out2 = LocList(_subst(v, lookup, value.where(i), problems) for i, v in enumerate(value))
        out2.loc, out2.item_locs = value.loc, value.item_locs
        return out2
    if isinstance(value, dict):
        return {k: _subst(v, lookup, loc, problems) for k, v in value.items()}
    if isinstance(value, list):
        return [_subst(v, lookup, loc, problems) for v in value]
    return value


def _names_used(value: Any, out: set[str]) -> None:
    stack = [value]
    while stack:
        v = stack.pop()
        if isinstance(v, str):
            out.update(_VAR.findall(v))
        elif isinstance(v, dict):
            stack += [*v.keys(), *v.values()]
        elif isinstance(v, list):
            stack += v


class _Variables:
    """The graph's variables: raw values by name (files in order, then the caller's),
    substituted on first use, cycles reported."""

    def __init__(self, problems: list[Problem]) -> None:
        self.raw: dict[str, Any] = {}
        self.locs: dict[str, Loc | None] = {}
        self.from_caller: set[str] = set()
        self.values: dict[str, Any] = {}
        self.problems = problems
        self._active: list[str] = []

    def lookup(self, name: str, loc: Loc | None) -> tuple[bool, Any]:
        if name in self.values:
            return True, self.values[name]
        if name not in self.raw:
            self.problems.append(Problem(loc, f"undefined variable '${{{name}}}'"))
            return False, None
        if name in self._active:
            cycle = " -> ".join([*self._active[self._active.index(name):], name])
            self.problems.append(Problem(self.locs.get(name), f"variable cycle: {cycle}"))
            return False, None
        self._active.append(name)
        try:
            value = _subst(self.raw[name], self.lookup, self.locs.get(name), self.problems)
        finally:
            self._active.pop()
        self.values[name] = value
        return True, value

    def resolve_all(self) -> dict[str, Any]:
        for name in list(self.raw):
            self.lookup(name, self.locs.get(name))
        return dict(self.values)

    def from_command_line(self, value: Any) -> bool:
        """Whether a raw string value starts with a caller variable (itself, or through
        the variables it starts with): its relative path is the working directory's."""
        seen: set[str] = set()
        while isinstance(value, str):
            m = _VAR.match(value)
            if not m or m.group(1) in seen:
                return False
            name = m.group(1)
            if name in self.from_caller:
                return True
            seen.add(name)
            value = self.raw.get(name)
        return False


# ----------------------------------------------------------------------------------
# loading

def _check_keys(d: LocDict, allowed: Iterable[str], what: str, problems: list[Problem]) -> None:
    """One problem for the unknown keys of ``d``: the first, shown short and escaped, and how
    many more (a file that is not a graph is never echoed back key by key)."""
    allowed = tuple(allowed)
    unknown = [k for k in d if k not in allowed]
    if not unknown:
        return
    k = unknown[0]
    hint = closest(str(k), allowed)
    more = f" (and {len(unknown) - 1} more unknown key{'s' * (len(unknown) > 2)})" if len(unknown) > 1 else ""
    problems.append(Problem(d.where(k), f"unknown key '{shown(k)}' in {what}{more}"
                            + did_you_mean(hint, f"; expected one of {', '.join(allowed)}")))


def parse_set(item: str) -> tuple[str, str, Any]:
    """``comp.param=value`` -> (comp, param, value parsed as YAML scalar/list)."""
    if "=" not in item or "." not in item.split("=", 1)[0]:
        raise GraphError([Problem(None, f"--set '{shown(item)}': expected COMPONENT.PARAM=VALUE")])
    key, raw = item.split("=", 1)
    comp, param = key.split(".", 1)
    try:
        value = load_value(raw)
    except YamlError as e:
        raise GraphError([Problem(None, f"--set {item}: {e}")]) from None
    except yaml.YAMLError:
        value = raw  # not YAML: the text itself
    return comp.strip(), param.strip(), value


def _read(path: Path, problems: list[Problem], seen: tuple[Path, ...], done: set[Path],
          budget: list[int]) -> tuple[LocDict, list[tuple[LocDict, Path]]]:
    """Read ``path`` and, depth first, its includes (each file once). Returns (doc, [(included
    doc, path)]). ``budget`` holds the bytes the graph may still read."""
    try:
        budget[0] -= path.stat().st_size
    except OSError:
        pass  # load_yaml says why it cannot read it
    if budget[0] < 0:
        raise GraphError([Problem(Loc(str(path), 1, 1), f"the graph and its includes exceed "
                                  f"{MAX_GRAPH_BYTES // 1024} kB: not a graph")])
    doc = load_yaml(path)
    if not isinstance(doc, LocDict):
        raise GraphError([Problem(Loc(str(path), 1, 1), "a graph file must be a mapping (name:, components:, ...)")])
    if doc and not any(k in TOP_KEYS or closest(str(k)[:40], TOP_KEYS) for k in doc):
        # another YAML file (or a text file that parses as one): one line, none of its contents
        # (a misspelt key of a graph, close to one, is reported as such by _merge)
        raise GraphError([Problem(Loc(str(path), 1, 1), f"not a graph file: none of its {len(doc)} keys is a "
                                  f"graph key ({', '.join(TOP_KEYS)})")])
    chain: list[tuple[LocDict, Path]] = []
    inc = doc.get("include")
    if inc is not None:
        items = inc if isinstance(inc, list) else [inc]
        for i, item in enumerate(items):
            loc = inc.where(i) if isinstance(inc, LocList) else doc.value_where("include")
            if not isinstance(item, str):
                problems.append(Problem(loc, f"include expects a file name, got '{shown(item)}'"))
                continue
            p = (path.parent / item).resolve()
            if p in seen:
                problems.append(Problem(loc, f"include cycle: {item} is already being included"))
                continue
            if p in done:
                continue  # included already through another file: merged once
            if not p.exists():
                problems.append(Problem(loc, f"included file not found: {shown(item)}"))
                continue
            done.add(p)
            sub, subchain = _read(p, problems, (*seen, p), done, budget)
            chain += subchain + [(sub, p)]
    return doc, chain


def read_graph(path: str | Path, overrides: Iterable[str] = (), variables: dict[str, Any] | None = None,
                  text: str | None = None) -> tuple[GraphSpec, list[Problem]]:
    """Read a graph with its includes, variables and overrides applied, not yet checked
    against the plugins (so path parameters are not resolved yet): (spec, problems found so
    far). A file that cannot be read at all raises :class:`GraphError`."""
    problems: list[Problem] = []
    path = Path(path)
    try:
        if text is not None:
            doc = load_yaml(path, text)
            chain: list[tuple[LocDict, Path]] = []
            if not isinstance(doc, LocDict):
                raise GraphError([Problem(Loc(str(path), 1, 1), "a graph file must be a mapping")])
        else:
            top = path.resolve()
            doc, chain = _read(top, problems, (top,), {top}, [MAX_GRAPH_BYTES])
    except YamlError as e:
        raise GraphError([Problem(None, str(e))]) from None
    spec = GraphSpec(name=path.stem, file=str(path))
    if text is not None:
        spec.source_text = text
    else:
        try:  # read again, bounded: the file could have been swapped since
            spec.source_text = decode_text(str(path), read_bounded(path, MAX_BYTES))
        except YamlError:
            spec.source_text = ""
    docs = chain + [(doc, path)]
    folders = [str(p.parent) for _, p in docs]  # the main file's as given, the includes' absolute
    # variables: included files first, then this file, then the caller's
    var = _Variables(problems)
    used: set[str] = set()
    for d, _ in docs:
        v = d.get("variables")
        if isinstance(v, LocDict):
            for k, val in v.items():
                if not isinstance(k, str) or not _NAME.match(k):
                    problems.append(Problem(v.where(k), f"variable name '{shown(k)}' must be a name like out_dir "
                                                        "(letters, digits, '_')"))
                    continue
                var.raw[k], var.locs[k] = val, v.value_where(k)
        elif v is not None:
            problems.append(Problem(d.value_where("variables"), "variables must be a mapping NAME: value"))
        _names_used(d, used)
    known = set(var.raw) | used
    for k, val in (variables or {}).items():
        if k not in known:
            hint = closest(k, known, n=3)
            problems.append(Problem(None, f"--var {k}: the graph has no variable '{k}'"
                                    + (f" (closest: {hint})" if hint else
                                       f" (variables: {', '.join(sorted(known)) or 'none'})")))
            continue
        var.raw[k], var.locs[k] = val, None
        var.from_caller.add(k)
    spec.variables = var.resolve_all()
    for (d, _), folder in zip(docs, folders, strict=True):
        body = LocDict({k: v for k, v in d.items() if k != "variables"})  # variables: substituted above
        body.loc, body.key_locs, body.value_locs = d.loc, d.key_locs, d.value_locs
        _merge(spec, _subst(body, var.lookup, d.loc, problems), problems)
        _note_bases(spec, d, folder, var)
    _check_duplicate_connections(spec, problems)
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
        spec.components[comp].param_bases[param] = ""  # the working directory
        spec.components[comp].param_locs[param] = Loc(f"--set {shown(item, 80)}", 0, 0)  # its problems name it
    return spec, problems


def _note_bases(spec: GraphSpec, d: LocDict, folder: str, var: _Variables) -> None:
    """Record the folder each (raw) parameter and record path of ``d`` is relative to."""
    def base(raw: Any) -> str:
        return "" if var.from_command_line(raw) else folder

    comps = d.get("components")
    if isinstance(comps, LocDict):
        for cid, c in comps.items():
            params = c.get("params") if isinstance(c, LocDict) else None
            if isinstance(params, LocDict) and cid in spec.components:
                for k, raw in params.items():
                    spec.components[cid].param_bases[k] = base(raw)
    rec = d.get("record")
    if isinstance(rec, LocDict) and "path" in rec:
        spec.record_base = base(rec["path"])


def _check_duplicate_connections(spec: GraphSpec, problems: list[Problem]) -> None:
    first: dict[tuple[str, str, str, str], ConnectionSpec] = {}
    for c in spec.connections:
        key = (c.src, c.out, c.dst, c.inp)
        if key in first:
            problems.append(Problem(c.loc, f"duplicate connection '{c}': already written at {first[key].loc} "
                                           "(every sample would be delivered twice)"))
        else:
            first[key] = c


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
                                        f"clock mode must be 'replay' or 'realtime', got {brief(mode)}"))
            spec.clock_mode = mode
            if "speed" in clock:
                try:
                    checked_speed(clock["speed"])
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
                _merge_component(spec, cid, c, comps.where(cid), problems)
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


def _merge_component(spec: GraphSpec, cid: Any, c: Any, loc: Loc | None, problems: list[Problem]) -> None:
    bad = component_id_problem(cid)
    if bad:
        problems.append(Problem(loc, bad))
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
    override = c.get("override", False)
    if not isinstance(override, bool):
        problems.append(Problem(c.value_where("override"), f"component '{cid}': override must be true or false, "
                                                           f"got {brief(override)}"))
        override = False
    inputs, input_locs = _parse_inputs(cid, c, problems)
    old = spec.components.get(cid)
    if old is not None and "type" not in c and not override:  # an includer refining an included component
        old.params.update(params)
        if isinstance(params, LocDict):
            old.param_locs.update(params.key_locs)
        if "on_error" in c:
            old.on_error = c["on_error"]
        for name, bounds in inputs.items():
            old.inputs.setdefault(name, {}).update(bounds)
        old.input_locs.update(input_locs)
        return
    if old is not None and not override:
        problems.append(Problem(loc, f"component '{cid}' is already defined at {old.def_loc}: write "
                                     "'override: true' to replace it, or leave out 'type' to refine its params"))
        return
    if old is None and override:
        problems.append(Problem(c.value_where("override"), f"component '{cid}': override: true, but no "
                                                           f"included file defines a component '{cid}'"))
    if "type" not in c:
        problems.append(Problem(loc, f"component '{cid}' has no 'type'"))
        return
    on_error = c.get("on_error", "stop")
    if on_error not in ("stop", "skip"):
        problems.append(Problem(c.value_where("on_error"),
                                f"component '{cid}': on_error must be 'stop' or 'skip', got {brief(on_error)}"))
    spec.components[cid] = ComponentSpec(
        cid, str(c["type"]), dict(params), on_error, c.where("type"),
        dict(params.key_locs) if isinstance(params, LocDict) else {}, loc,
        inputs=inputs, input_locs=input_locs,
    )


def _parse_inputs(cid: str, c: LocDict, problems: list[Problem]) -> tuple[dict[str, dict[str, Any]], dict[str, Loc]]:
    """A component's ``inputs: {name: {maxsize: n, overflow: policy, maxbytes: n}}`` (the bounds
    a graph sets over the component's own declaration); whether each input exists is checked by
    validation, against the component's ports."""
    raw = c.get("inputs")
    if raw is None:
        return {}, {}
    if not isinstance(raw, LocDict):
        problems.append(Problem(c.value_where("inputs"), f"component '{cid}': inputs must be a mapping "
                                "{input: {maxsize: n, overflow: drop_oldest, maxbytes: n}}"))
        return {}, {}
    out: dict[str, dict[str, Any]] = {}
    locs: dict[str, Loc] = {}
    for name, bounds in raw.items():
        where = raw.where(name)
        if not isinstance(bounds, LocDict) or not bounds:
            problems.append(Problem(raw.value_where(name), f"component '{cid}': input '{shown(name)}' takes a "
                                    f"mapping of {', '.join(INPUT_KEYS)}, got {brief(bounds)}"))
            continue
        _check_keys(bounds, INPUT_KEYS, f"component '{cid}', input '{shown(name)}'", problems)
        ok: dict[str, Any] = {}
        for key in INPUT_KEYS:
            if key not in bounds:
                continue
            v = bounds[key]
            if key == "overflow":
                good = v in OVERFLOWS
                want = f"one of {', '.join(OVERFLOWS)}"
            else:
                good = isinstance(v, int) and not isinstance(v, bool) and 1 <= v < 1 << 62
                want = "an integer >= 1" + (" (samples)" if key == "maxsize" else " (bytes)")
            if good:
                ok[key] = v
            else:
                problems.append(Problem(bounds.value_where(key), f"component '{cid}', input '{shown(name)}': "
                                        f"{key} must be {want}, got {brief(v)}"))
        out[str(name)] = ok
        if where is not None:
            locs[str(name)] = where
    return out, locs


def _parse_connection(item: Any, loc: Loc | None, problems: list[Problem]) -> ConnectionSpec | None:
    if isinstance(item, dict):
        extra = set(item) - {"from", "to", "delay"}
        if extra or "from" not in item or "to" not in item:
            problems.append(Problem(loc, "a connection mapping takes 'from', 'to' and optionally 'delay'"))
            return None
        item = f"{item['from']} -> {item['to']}" + (" [delay]" if item.get("delay") else "")
    if not isinstance(item, str):
        problems.append(Problem(loc, f"a connection is 'component.output -> component.input', got '{shown(item)}'"))
        return None
    m = CONNECTION.match(item)
    if not m:
        problems.append(Problem(loc, f"cannot read connection '{shown(item)}': "
                                     "expected 'component.output -> component.input'"))
        return None
    return ConnectionSpec(m.group(1), m.group(2), m.group(3), m.group(4), bool(m.group(5)), loc)


def graph_files(path: str | Path) -> list[str]:
    """The graph file ``path`` and the files it includes (each once, the includes sorted);
    an unreadable graph gives ``[path]`` alone (loading it says why)."""
    top = Path(path).resolve()
    try:
        _, chain = _read(top, [], (top,), {top}, [MAX_GRAPH_BYTES])
    except Exception:  # an unreadable graph: load_graph reports it
        return [str(path)]
    return [str(path)] + sorted(str(p) for _, p in chain)
