"""Sweep files: which graph, over which missions, seeds and parameter variants, which metrics.

```yaml
graph: graphs/rslam.yaml                 # relative paths: against the sweep file's folder
missions:
  simulate: {scenario: beynes, duration_s: 20, seeds: [1, 2]}   # simulated on the workers
  files: [missions/*.mcap]                                        # and/or recordings (globs)
grid: {slam.search_m: [1.0, 2.0]}        # product of the values; or `variants: [{...}, {...}]`
metrics: [eval.ate_rmse_m, eval.drift_pct]   # component.key of the run summary
repeats: 1                               # each (mission, variant) run this many times
variables: {}                            # more --var values for the graph (not mission, out)
```

``simulate`` may also be a list of such mappings (several scenarios). Read with impala-flow's
safe YAML loader; every problem is one ``file:line:col:`` line (:class:`SweepError`).
Every task gets a stable id built from its mission, seed, variant and repeat, so a sweep can
be resumed and its task folders found again.
"""

from __future__ import annotations

import glob
import hashlib
import itertools
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..yamlloc import YamlError, load_yaml, location

__all__ = ["SweepSpec", "SweepError", "Task", "load_sweep", "format_value", "RESERVED_VARIABLES"]

_TOP = ("graph", "missions", "grid", "variants", "metrics", "repeats", "variables")
_SIM = ("scenario", "duration_s", "seeds")
#: variables the sweep sets for every task: the mission file and the task's output folder
RESERVED_VARIABLES = ("mission", "out")
_MAX_ID = 120


class SweepError(ValueError):
    """A sweep file that cannot be used (one line, file:line:col)."""


@dataclass(frozen=True)
class Task:
    """One run: a mission (simulated or a file), one variant of the parameters, one repeat."""

    id: str
    mission: str  # a file path, or "sim:<scenario>" for a simulated one
    seed: int | None
    duration_s: float | None
    params: tuple[tuple[str, Any], ...]
    repeat: int = 0

    @property
    def variant(self) -> str:
        return ", ".join(f"{k}={format_value(v)}" for k, v in self.params) or "default"

    @property
    def simulated(self) -> bool:
        return self.mission.startswith("sim:")

    @property
    def scenario(self) -> str | None:
        return self.mission[4:] if self.simulated else None

    def overrides(self) -> list[str]:
        """The variant as ``--set`` items (values written as YAML flow, typed as in the sweep file)."""
        return [f"{k}={format_value(v)}" for k, v in self.params]


@dataclass
class SweepSpec:
    path: Path
    graph: Path
    metrics: list[str]
    tasks: list[Task] = field(default_factory=list)
    variables: dict[str, Any] = field(default_factory=dict)
    #: where things are written in the sweep file: "graph", "metric:<m>", "param:<c.p>" -> "file:line:col"
    locs: dict[str, str] = field(default_factory=dict)

    @property
    def param_names(self) -> list[str]:
        """Every parameter a variant sets, in first-seen order."""
        return list(dict.fromkeys(k for t in self.tasks for k, _ in t.params))

    @property
    def variants(self) -> list[str]:
        return list(dict.fromkeys(t.variant for t in self.tasks))

    def where(self, what: str) -> str:
        return self.locs.get(what, str(self.path))


def format_value(v: Any) -> str:
    """A parameter value as YAML flow text that reads back as the same value (JSON is YAML)."""
    if isinstance(v, str):
        return v if re.fullmatch(r"[A-Za-z_][\w./-]*", v) and v.lower() not in ("true", "false", "null") \
            else json.dumps(v)
    if isinstance(v, float) and not math.isfinite(v):
        return ".nan" if math.isnan(v) else (".inf" if v > 0 else "-.inf")
    return json.dumps(v)


def load_sweep(path: str | Path) -> SweepSpec:
    """Load and validate a sweep file (module doc); raises :class:`SweepError`."""
    path = Path(path)
    where = str(path)
    try:
        doc = load_yaml(path)
    except YamlError as e:
        raise SweepError(str(e)) from None
    if not isinstance(doc, dict) or not doc:
        raise SweepError(f"{where}:1:1: a sweep file is a mapping with graph, missions and metrics")
    top = location(doc, None, f"{where}:1:1")
    for k in doc:
        if k not in _TOP:
            raise SweepError(f"{location(doc, k, where)}: unknown key {k!r} (valid: {', '.join(_TOP)})")
    for k in ("graph", "missions", "metrics"):
        if k not in doc:
            raise SweepError(f"{top}: missing key {k!r}")
    base = path.parent
    locs: dict[str, str] = {"graph": location(doc, "graph", where, value=True)}
    if not isinstance(doc["graph"], str) or not doc["graph"]:
        raise SweepError(f"{locs['graph']}: graph must be the path of a graph file")
    graph = Path(doc["graph"])
    graph = graph if graph.is_absolute() else base / graph
    if not graph.is_file():
        raise SweepError(f"{locs['graph']}: graph {doc['graph']!r}: no such file ({graph}; relative paths are "
                         "read from the sweep file's folder)")
    graph = graph.resolve()
    metrics = _metrics(doc, where, locs)
    repeats = doc.get("repeats", 1)
    if isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1:
        raise SweepError(f"{location(doc, 'repeats', where, value=True)}: repeats must be an integer >= 1, "
                         f"got {repeats!r}")
    variables = doc.get("variables") or {}
    if not isinstance(variables, dict):
        raise SweepError(f"{location(doc, 'variables', where, value=True)}: variables must be a mapping of name: value")
    for k in variables:
        if k in RESERVED_VARIABLES:
            raise SweepError(f"{location(variables, k, where)}: variable {k!r} is set by the sweep for every task "
                             "(mission: the mission file, out: the task's folder)")
    variants = _variants(doc, where, locs)
    missions = _missions(doc["missions"], base, location(doc, "missions", where, value=True), locs)
    tags = _mission_tags(missions, base)
    tasks = []
    for (mission, seed, duration), params, rep in itertools.product(missions, variants, range(repeats)):
        parts = [tags[mission]] + ([f"s{seed}"] if seed is not None else []) \
            + ([f"{duration:g}s"] if duration is not None and _durations(missions, mission) > 1 else []) \
            + [f"{k}={format_value(v)}" for k, v in params] + ([f"r{rep}"] if repeats > 1 else [])
        tasks.append(Task("_".join(parts), mission, seed, duration, params, rep))
    return SweepSpec(path, graph, metrics, _unique_ids(tasks), dict(variables), locs)


def _metrics(doc: Any, where: str, locs: dict[str, str]) -> list[str]:
    metrics = doc["metrics"]
    at = location(doc, "metrics", where, value=True)
    if not isinstance(metrics, list) or not metrics:
        raise SweepError(f"{at}: metrics must be a non-empty list of 'component.key' (e.g. eval.ate_rmse_m)")
    for i, m in enumerate(metrics):
        mat = location(metrics, i, at, value=True)
        if not isinstance(m, str) or m.count(".") != 1 or not all(m.split(".")):
            raise SweepError(f"{mat}: metric {m!r} is not 'component.key' (e.g. eval.ate_rmse_m)")
        if f"metric:{m}" in locs:
            raise SweepError(f"{mat}: metric {m!r} listed twice")
        locs[f"metric:{m}"] = mat
    return list(metrics)


def _variants(doc: Any, where: str, locs: dict[str, str]) -> list[tuple[tuple[str, Any], ...]]:
    if "grid" in doc and "variants" in doc:
        raise SweepError(f"{location(doc, 'variants', where)}: give either grid (a product) or variants (a list), "
                         "not both")
    if "variants" in doc:
        vs = doc["variants"]
        at = location(doc, "variants", where, value=True)
        if not isinstance(vs, list) or not vs:
            raise SweepError(f"{at}: variants must be a non-empty list of {{component.param: value}} mappings")
        out = []
        for i, v in enumerate(vs):
            if not isinstance(v, dict):
                raise SweepError(f"{location(vs, i, at, value=True)}: variant {i + 1} must be a mapping "
                                 "{component.param: value} ({} for the graph as it is)")
            _check_names(v, where, locs)
            variant = tuple(sorted((str(k), val) for k, val in v.items()))
            if variant in out:
                raise SweepError(f"{location(vs, i, at, value=True)}: variant {i + 1} repeats an earlier one")
            out.append(variant)
        return out
    grid = doc.get("grid")
    if grid is None or grid == {}:
        return [()]
    if not isinstance(grid, dict):
        raise SweepError(f"{location(doc, 'grid', where, value=True)}: grid must map component.param to a list "
                         "of values")
    _check_names(grid, where, locs)
    names = list(grid)
    for k in names:
        vals = grid[k]
        if not isinstance(vals, list) or not vals:
            raise SweepError(f"{location(grid, k, where, value=True)}: grid {k}: must be a non-empty list of values, "
                             f"e.g. [{format_value(vals) if not isinstance(vals, (list, dict)) else '1.0, 2.0'}]")
        seen: list[Any] = []
        for i, v in enumerate(vals):
            if v in seen:
                raise SweepError(f"{location(vals, i, where, value=True)}: grid {k}: value {format_value(v)} "
                                 "listed twice")
            seen.append(v)
    return [tuple(zip(names, combo, strict=True)) for combo in itertools.product(*(grid[k] for k in names))]


def _check_names(d: Any, where: str, locs: dict[str, str]) -> None:
    for k in d:
        if not isinstance(k, str) or k.count(".") != 1 or not all(k.split(".")):
            raise SweepError(f"{location(d, k, where)}: {k!r} is not 'component.param' (e.g. slam.search_m)")
        locs.setdefault(f"param:{k}", location(d, k, where))


def _looks_like_file(scenario: str) -> bool:
    return scenario.endswith((".yaml", ".yml")) or "/" in scenario or "\\" in scenario


def _missions(m: Any, base: Path, where: str, locs: dict[str, str]) -> list[tuple[str, int | None, float | None]]:
    if not isinstance(m, dict) or not m:
        raise SweepError(f"{where}: missions must be a mapping with simulate and/or files")
    for k in m:
        if k not in ("simulate", "files"):
            raise SweepError(f"{location(m, k, where)}: unknown key missions.{k} (valid: simulate, files)")
    out: list[tuple[str, int | None, float | None]] = []
    sims = m.get("simulate")
    if sims is not None:
        sat = location(m, "simulate", where, value=True)
        items = sims if isinstance(sims, list) else [sims]
        if not items:
            raise SweepError(f"{sat}: missions.simulate must be a mapping (scenario, duration_s, seeds) or a "
                             "list of them")
        for i, sim in enumerate(items):
            out += _simulated(sim, base, location(sims, i, sat, value=True) if isinstance(sims, list) else sat, locs)
    files = m.get("files")
    if files is not None:
        fat = location(m, "files", where, value=True)
        if isinstance(files, str):
            files = [files]
        if not isinstance(files, list) or not files:
            raise SweepError(f"{fat}: missions.files must be a list of mission files or globs")
        for i, pattern in enumerate(files):
            pat = location(files, i, fat, value=True)
            if not isinstance(pattern, str) or not pattern:
                raise SweepError(f"{pat}: missions.files: {pattern!r} is not a path or a glob")
            full = pattern if Path(pattern).is_absolute() else str(base / pattern)
            hits = sorted(h for h in glob.glob(full) if Path(h).is_file())
            if not hits:
                raise SweepError(f"{pat}: missions.files: {pattern!r} matches no file ({full}; relative paths are "
                                 "read from the sweep file's folder)")
            out += [(str(Path(h).resolve()), None, None) for h in hits]
    seen: set[tuple[str, int | None, float | None]] = set()
    unique = []
    for item in out:  # a file two globs match runs once
        if item not in seen:
            seen.add(item)
            unique.append(item)
    return unique


def _simulated(sim: Any, base: Path, at: str, locs: dict[str, str]) -> list[tuple[str, int | None, float | None]]:
    if not isinstance(sim, dict):
        raise SweepError(f"{at}: missions.simulate must be a mapping (scenario, duration_s, seeds)")
    for k in sim:
        if k not in _SIM:
            raise SweepError(f"{location(sim, k, at)}: unknown key missions.simulate.{k} (valid: {', '.join(_SIM)})")
    if "scenario" not in sim:
        raise SweepError(f"{location(sim, None, at)}: missions.simulate needs a scenario (a name such as beynes, or "
                         "a scenario file)")
    scenario = sim["scenario"]
    if not isinstance(scenario, str) or not scenario:
        raise SweepError(f"{location(sim, 'scenario', at, value=True)}: scenario must be a name or a scenario file")
    if _looks_like_file(scenario):
        file = Path(scenario) if Path(scenario).is_absolute() else base / scenario
        if not file.is_file():
            raise SweepError(f"{location(sim, 'scenario', at, value=True)}: scenario file {scenario!r}: "
                             f"no such file ({file})")
        scenario = str(file.resolve())
    locs.setdefault(f"scenario:{scenario}", location(sim, "scenario", at, value=True))
    seeds = sim.get("seeds", [1])
    sat = location(sim, "seeds", at, value=True)
    if isinstance(seeds, int) and not isinstance(seeds, bool):
        seeds = [seeds]
    if not isinstance(seeds, list) or not seeds:
        raise SweepError(f"{sat}: seeds must be a non-empty list of integers")
    for i, s in enumerate(seeds):
        if isinstance(s, bool) or not isinstance(s, int):
            raise SweepError(f"{location(seeds, i, sat, value=True)}: seed {s!r} is not an integer")
    if len(set(seeds)) != len(seeds):
        raise SweepError(f"{sat}: a seed is listed twice")
    dur = sim.get("duration_s")
    if dur is not None and (isinstance(dur, bool) or not isinstance(dur, (int, float)) or not 0 < dur < float("inf")):
        raise SweepError(f"{location(sim, 'duration_s', at, value=True)}: duration_s must be a positive number "
                         f"of seconds, got {dur!r}")
    return [(f"sim:{scenario}", int(s), None if dur is None else float(dur)) for s in seeds]


def _durations(missions: list[tuple[str, int | None, float | None]], mission: str) -> int:
    return len({d for m, _, d in missions if m == mission})


def _mission_tags(missions: list[tuple[str, int | None, float | None]], base: Path) -> dict[str, str]:
    """A short name per mission for the task ids: the scenario or the file's stem, the path
    when two files share a stem."""
    stems: dict[str, set[str]] = {}
    for m, _, _ in missions:
        name = Path(m[4:]).stem if m.startswith("sim:") else Path(m).stem
        stems.setdefault(name, set()).add(m)
    tags = {}
    for name, ms in stems.items():
        for m in ms:
            if len(ms) == 1:
                tags[m] = name
            else:
                p = Path(m[4:] if m.startswith("sim:") else m)
                try:
                    rel = p.relative_to(base.resolve())
                except ValueError:
                    rel = p
                tags[m] = str(rel.with_suffix("")).strip("/")
    return tags


def _clean(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9._=+-]+", "-", name).strip("-") or "task"


def _unique_ids(tasks: list[Task]) -> list[Task]:
    """Task ids usable as folder names and Dask keys: safe characters, not too long, unique
    (a short hash of the task's content is added where needed)."""
    def digest(t: Task) -> str:
        return hashlib.sha1(repr((t.mission, t.seed, t.duration_s, t.params, t.repeat)).encode()).hexdigest()[:8]

    ids = []
    for t in tasks:
        name = _clean(t.id)
        if len(name) > _MAX_ID:
            name = f"{name[:_MAX_ID - 9]}~{digest(t)}"
        ids.append(name)
    counts: dict[str, int] = {}
    for name in ids:
        counts[name] = counts.get(name, 0) + 1
    out = []
    for t, name in zip(tasks, ids, strict=True):
        if counts[name] > 1:
            name = f"{name}~{digest(t)}"
        out.append(Task(name, t.mission, t.seed, t.duration_s, t.params, t.repeat))
    return out
