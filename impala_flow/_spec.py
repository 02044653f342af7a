"""The graph spec model and its problems: the bottom layer of graph handling.

Every stage of the pipeline (:mod:`impala_flow._load` -> :mod:`impala_flow._resolve` ->
:mod:`impala_flow._validate` -> :mod:`impala_flow._build`) reads or fills a
:class:`GraphSpec` and reports :class:`Problem` s; this module also holds the did-you-mean
helpers every error message uses. It imports no stage.
"""

from __future__ import annotations

import difflib
import math
import re
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from ._clock import parse_speed
from ._yamlloc import Loc

__all__ = [
    "GraphSpec", "ComponentSpec", "ConnectionSpec", "GraphError", "Problem", "closest", "did_you_mean",
    "CONNECTION", "component_id_problem", "checked_speed", "MIN_SPEED", "capped", "MAX_PROBLEMS_PER_FILE",
]

#: slowest replay speed accepted (1 s of mission in 1 000 s)
MIN_SPEED = 1e-3

#: ``a.out -> b.in`` with an optional ``[delay]`` suffix
CONNECTION = re.compile(r"^\s*([^.\s]+)\.(\S+)\s*->\s*([^.\s]+)\.(\S+?)\s*(\[delay\])?\s*$")
_BAD_ID_CHARS = re.compile(r"[\s./\[\]]|->")


def closest(word: str, choices: Iterable[str], n: int = 1) -> str | None:
    """The ``n`` choices closest to ``word`` (a misspelt name), joined by ', '; None if none is close."""
    m = difflib.get_close_matches(word, list(choices), n=n, cutoff=0.5)
    return ", ".join(m) if m else None


def did_you_mean(hint: str | None, otherwise: str = "") -> str:
    """`` (did you mean 'HINT'?)`` to end a one-line error, or ``otherwise`` without a hint."""
    return f" (did you mean '{hint}'?)" if hint else otherwise


def component_id_problem(cid: Any) -> str | None:
    """Why ``cid`` cannot be a component id (None when it can): an id must be a string that
    can be written in a connection ``id.port -> id.port``, so no space, '.', '/', '[', ']'
    nor '->'."""
    if not isinstance(cid, str):
        return f"component id {cid!r} must be a string (YAML read it as {type(cid).__name__}: quote it)"
    if not cid:
        return "component id must not be empty"
    bad = _BAD_ID_CHARS.search(cid)
    if bad:
        return (f"component id {cid!r} cannot be written in a connection 'id.port -> id.port': "
                f"it contains {bad.group(0)!r} (no spaces, '.', '/', '[', ']' or '->')")
    return None


def checked_speed(value: object) -> float | None:
    """A replay speed: ``'max'``/None -> None, else a finite factor >= :data:`MIN_SPEED`;
    anything else raises ``ValueError`` (one line)."""
    try:
        v = parse_speed(value)
    except ValueError:
        v = math.nan
    if v is not None and not (math.isfinite(v) and v >= MIN_SPEED):
        raise ValueError(f"speed must be 'max' or a finite factor >= {MIN_SPEED:g}, got {value!r}")
    return v


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


#: problems listed per file; the others are counted in one line
MAX_PROBLEMS_PER_FILE = 20


def capped(problems: list[Problem], limit: int = MAX_PROBLEMS_PER_FILE) -> list[Problem]:
    """``problems`` with at most ``limit`` per file, then one line counting the rest of that
    file's (a file full of errors is not reprinted line by line)."""
    seen: dict[str, int] = {}
    out: list[Problem] = []
    for p in problems:
        file = p.loc.file if p.loc is not None else ""
        seen[file] = seen.get(file, 0) + 1
        if seen[file] <= limit:
            out.append(p)
    for file, n in seen.items():
        if n > limit:
            out.append(Problem(Loc(file, 0, 0) if file else None, f"and {n - limit} more problems"))
    return out


@dataclass
class ComponentSpec:
    """One component of a graph. ``loc`` is where its type is written, ``def_loc`` where its
    id is; ``param_locs`` locate each parameter. ``param_bases`` is the folder a relative
    path in each parameter is resolved against (the graph file's folder, or the working
    directory for a value given on the command line)."""

    id: str
    type: str
    params: dict[str, Any]
    on_error: str = "stop"
    loc: Loc | None = None
    param_locs: dict[str, Loc] = field(default_factory=dict)
    def_loc: Loc | None = None
    param_bases: dict[str, str] = field(default_factory=dict)
    #: the graph's bounds of some inputs: {input: {"maxsize": n, "overflow": policy, "maxbytes": n}}
    inputs: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: where each input of ``inputs`` is written
    input_locs: dict[str, Loc] = field(default_factory=dict)


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
    #: folder a relative ``record.path`` is resolved against
    record_base: str = "."
    variables: dict[str, Any] = field(default_factory=dict)
    source_text: str = ""

    def resolved(self) -> dict[str, Any]:
        """The graph as plain data with every include, variable and override applied."""
        return {
            "name": self.name,
            "clock": {"mode": self.clock_mode, "speed": self.speed},
            "components": {
                c.id: {"type": c.type, "params": dict(c.params), "on_error": c.on_error,
                       **({"inputs": {k: dict(v) for k, v in c.inputs.items()}} if c.inputs else {})}
                for c in self.components.values()
            },
            "connections": [str(c) for c in self.connections],
            **({"record": dict(self.record)} if self.record else {}),
        }
