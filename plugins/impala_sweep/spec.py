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
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from impala_flow import YamlError, load_yaml, location

__all__ = ["SweepSpec", "SweepError", "Task", "load_sweep", "format_value", "RESERVED_VARIABLES", "MAX_TASKS",
           "MAX_TASKS_CEILING", "is_safe_id", "clean_name", "MISSION_SOURCE"]

_TOP = ("graph", "missions", "grid", "variants", "metrics", "repeats", "variables")
_SIM = ("scenario", "duration_s", "seeds")
#: the mission source (``registry.mission_sources``) that makes ``missions: simulate:`` missions
MISSION_SOURCE = "simulate"
#: variables the sweep sets for every task: the mission file and the task's output folder
RESERVED_VARIABLES = ("mission", "out")
_MAX_ID = 120
#: most tasks a sweep expands to unless told (``--max-tasks``); counted from the axes'
#: sizes before anything is built
MAX_TASKS = 10_000
#: the highest ``--max-tasks`` accepted (each task is a few hundred bytes on the client)
MAX_TASKS_CEILING = 1_000_000
#: a task id: a folder name and a Dask key (no separators, no leading dot, never "." or "..")
SAFE_ID = re.compile(r"[A-Za-z0-9_=+][A-Za-z0-9_=+.~-]*")


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
        return variant_name(self.params)

    @property
    def simulated(self) -> bool:
        return self.mission.startswith("sim:")

    @property
    def scenario(self) -> str | None:
        return self.mission[4:] if self.simulated else None

    def overrides(self) -> list[str]:
        """The variant as ``--set`` items (values written as YAML flow, typed as in the sweep file)."""
        return [f"{k}={format_value(v)}" for k, v in self.params]


Mission = tuple[str, int | None, float | None]  # (path or "sim:<scenario>", seed, duration_s)
Variant = tuple[tuple[str, Any], ...]


@dataclass
class SweepSpec:
    """A sweep file, read and checked but not expanded: :attr:`n_tasks` is the product of the
    axes' sizes; :attr:`tasks` builds the tasks on first use (after the checks)."""

    path: Path
    graph: Path
    metrics: list[str]
    missions: list[Mission] = field(default_factory=list)
    #: the grid (name -> values, expanded as a product) or the explicit variants
    grid: dict[str, list[Any]] | None = None
    variant_list: list[Variant] = field(default_factory=lambda: [()])
    repeats: int = 1
    variables: dict[str, Any] = field(default_factory=dict)
    #: where things are written in the sweep file: "graph", "metric:<m>", "param:<c.p>" -> "file:line:col"
    locs: dict[str, str] = field(default_factory=dict)
    #: every value a variant sets, once per place it is written: (component.param, value, "file:line:col")
    values: list[tuple[str, Any, str]] = field(default_factory=list)
    _tasks: list[Task] | None = field(default=None, repr=False)

    @property
    def n_variants(self) -> int:
        return math.prod(len(v) for v in self.grid.values()) if self.grid is not None else len(self.variant_list)

    @property
    def n_tasks(self) -> int:
        """How many tasks the sweep expands to, from the axes' sizes (nothing built)."""
        return len(self.missions) * self.n_variants * self.repeats

    def iter_variants(self) -> Iterator[Variant]:
        if self.grid is None:
            yield from self.variant_list
            return
        names = list(self.grid)
        for combo in itertools.product(*(self.grid[k] for k in names)):
            yield tuple(zip(names, combo, strict=True))

    @property
    def tasks(self) -> list[Task]:
        if self._tasks is None:
            self._tasks = _build_tasks(self)
        return self._tasks

    @property
    def param_names(self) -> list[str]:
        """Every parameter a variant sets, in first-seen order."""
        if self.grid is not None:
            return list(self.grid)
        return list(dict.fromkeys(k for v in self.variant_list for k, _ in v))

    @property
    def variants(self) -> list[str]:
        return [variant_name(v) for v in self.iter_variants()]

    @property
    def files(self) -> list[str]:
        """The recorded missions' files (not the simulated ones)."""
        return [m for m, _, _ in self.missions if not m.startswith("sim:")]

    @property
    def scenario_files(self) -> list[str]:
        sims = (m[4:] for m, _, _ in self.missions if m.startswith("sim:"))
        return list(dict.fromkeys(s for s in sims if Path(s).is_absolute()))

    def where(self, what: str) -> str:
        return self.locs.get(what, str(self.path))


def variant_name(params: Variant) -> str:
    return ", ".join(f"{k}={format_value(v)}" for k, v in params) or "default"


def format_value(v: Any) -> str:
    """A parameter value as YAML flow text that reads back as the same value (JSON is YAML)."""
    if isinstance(v, str):
        return v if re.fullmatch(r"[A-Za-z_][\w./-]*", v) and v.lower() not in ("true", "false", "null") \
            else json.dumps(v)
    if isinstance(v, float) and not math.isfinite(v):
        return ".nan" if math.isnan(v) else (".inf" if v > 0 else "-.inf")
    return json.dumps(v)


def load_sweep(path: str | Path, max_tasks: int = MAX_TASKS) -> SweepSpec:
    """Load and validate a sweep file (module doc); raises :class:`SweepError`.

    Nothing is expanded: the number of tasks is the product of the axes' sizes (missions x
    variants x repeats), refused over ``max_tasks`` before any task is built."""
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
    values: list[tuple[str, Any, str]] = []
    grid, variant_list = _variants(doc, where, locs, values)
    missions = _missions(doc["missions"], base, location(doc, "missions", where, value=True), locs)
    spec = SweepSpec(path, graph, metrics, missions, grid, variant_list, repeats, dict(variables), locs, values)
    n = spec.n_tasks
    if n > max_tasks:
        axis = "grid" if grid is not None else "variants" if "variants" in doc else "missions"
        at = location(doc, "repeats" if repeats > 1 else axis, where, value=True)
        raise SweepError(f"{at}: the sweep expands to {n} tasks ({len(missions)} mission(s) x {spec.n_variants} "
                         f"variant(s) x {repeats} repeat(s)), over the limit of {max_tasks}: shrink it, or raise "
                         f"the limit with --max-tasks N (at most {MAX_TASKS_CEILING})")
    return spec


def _build_tasks(spec: SweepSpec) -> list[Task]:
    """Every task, in the sweep's order (missions, variants, repeats), with unique safe ids."""
    tags = _mission_tags(spec.missions, spec.path.parent)
    durations: dict[str, set[float | None]] = {}
    for m, _, d in spec.missions:
        durations.setdefault(m, set()).add(d)
    tasks = []
    for (mission, seed, duration), params, rep in itertools.product(spec.missions, spec.iter_variants(),
                                                                    range(spec.repeats)):
        parts = [tags[mission]] + ([f"s{seed}"] if seed is not None else []) \
            + ([f"{duration:g}s"] if duration is not None and len(durations[mission]) > 1 else []) \
            + [f"{k}={format_value(v)}" for k, v in params] + ([f"r{rep}"] if spec.repeats > 1 else [])
        tasks.append(Task("_".join(clean_name(p) for p in parts), mission, seed, duration, params, rep))
    return _unique_ids(tasks)


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


def _value_key(v: Any) -> str:
    """Two values the same for a duplicate check (1 and 1.0 alike, as ``==`` has them)."""
    if isinstance(v, (int, float)) and not isinstance(v, bool):
        return repr(float(v))
    try:
        return json.dumps(v, sort_keys=True, default=str)
    except (TypeError, ValueError):
        return repr(v)


def _variants(doc: Any, where: str, locs: dict[str, str], values: list[tuple[str, Any, str]]
              ) -> tuple[dict[str, list[Any]] | None, list[Variant]]:
    """(grid, None) or (None, explicit variants); duplicates found in one pass (hashed)."""
    if "grid" in doc and "variants" in doc:
        raise SweepError(f"{location(doc, 'variants', where)}: give either grid (a product) or variants (a list), "
                         "not both")
    if "variants" in doc:
        vs = doc["variants"]
        at = location(doc, "variants", where, value=True)
        if not isinstance(vs, list) or not vs:
            raise SweepError(f"{at}: variants must be a non-empty list of {{component.param: value}} mappings")
        out = []
        seen: set[str] = set()
        for i, v in enumerate(vs):
            vat = location(vs, i, at, value=True)
            if not isinstance(v, dict):
                raise SweepError(f"{vat}: variant {i + 1} must be a mapping "
                                 "{component.param: value} ({} for the graph as it is)")
            _check_names(v, where, locs)
            variant = tuple(sorted((str(k), val) for k, val in v.items()))
            key = _value_key([[k, _value_key(val)] for k, val in variant])
            if key in seen:
                raise SweepError(f"{vat}: variant {i + 1} repeats an earlier one")
            seen.add(key)
            values += [(str(k), val, location(v, k, vat, value=True)) for k, val in v.items()]
            out.append(variant)
        return None, out
    grid = doc.get("grid")
    if grid is None or grid == {}:
        return None, [()]
    if not isinstance(grid, dict):
        raise SweepError(f"{location(doc, 'grid', where, value=True)}: grid must map component.param to a list "
                         "of values")
    _check_names(grid, where, locs)
    for k in grid:
        vals = grid[k]
        if not isinstance(vals, list) or not vals:
            raise SweepError(f"{location(grid, k, where, value=True)}: grid {k}: must be a non-empty list of values, "
                             f"e.g. [{format_value(vals) if not isinstance(vals, (list, dict)) else '1.0, 2.0'}]")
        seen_values: set[str] = set()
        for i, v in enumerate(vals):
            key = _value_key(v)
            if key in seen_values:
                raise SweepError(f"{location(vals, i, where, value=True)}: grid {k}: value {format_value(v)} "
                                 "listed twice")
            seen_values.add(key)
            values.append((str(k), v, location(vals, i, location(grid, k, where, value=True), value=True)))
    return {str(k): list(v) for k, v in grid.items()}, [()]


def _check_names(d: Any, where: str, locs: dict[str, str]) -> None:
    for k in d:
        if not isinstance(k, str) or k.count(".") != 1 or not all(k.split(".")):
            raise SweepError(f"{location(d, k, where)}: {k!r} is not 'component.param' (e.g. slam.search_m)")
        locs.setdefault(f"param:{k}", location(d, k, where))


def _looks_like_file(scenario: str) -> bool:
    return scenario.endswith((".yaml", ".yml")) or "/" in scenario or "\\" in scenario


def _missions(m: Any, base: Path, where: str, locs: dict[str, str]) -> list[Mission]:
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


def _mission_tags(missions: list[Mission], base: Path) -> dict[str, str]:
    """A short name per mission for the task ids: the scenario or the file's stem, the path
    when two files share a stem (made safe by :func:`clean_name`, told apart by
    :func:`_unique_ids`)."""
    stems: dict[str, set[str]] = {}
    for m, _, _ in missions:
        name = Path(m[4:]).stem if m.startswith("sim:") else Path(m).stem
        stems.setdefault(clean_name(name).lower(), set()).add(m)
    tags = {}
    for ms in stems.values():
        for m in ms:
            p = Path(m[4:] if m.startswith("sim:") else m)
            if len(ms) == 1:
                tags[m] = p.stem
            else:
                try:
                    rel = p.relative_to(base.resolve())
                except ValueError:
                    rel = p
                tags[m] = str(rel.with_suffix("")).strip("/")
    return tags


def clean_name(name: str) -> str:
    """``name`` as safe characters only: letters, digits and ``_=+.~-``, every other run
    (separators, spaces, control characters) one ``-``; no leading dot or dash (so never
    ``.``, ``..`` nor a hidden name); ``x`` when nothing is left."""
    name = re.sub(r"[^A-Za-z0-9_=+.~-]+", "-", name)
    return name.lstrip(".-").rstrip(".-") or "x"


def is_safe_id(task_id: str) -> bool:
    """A task id that can only name one folder inside ``tasks/`` (see :data:`SAFE_ID`)."""
    return (isinstance(task_id, str) and 0 < len(task_id) <= _MAX_ID + 20 and SAFE_ID.fullmatch(task_id) is not None
            and task_id not in (".", ".."))


def _unique_ids(tasks: list[Task]) -> list[Task]:
    """Task ids usable as folder names and Dask keys: safe characters, not too long, unique
    even on a case-insensitive file system (a short hash of the task's content is added to
    every id of a clash, so the outcome does not depend on the order)."""
    def digest(t: Task) -> str:
        return hashlib.sha1(repr((t.mission, t.seed, t.duration_s, t.params, t.repeat)).encode()).hexdigest()[:8]

    ids = []
    for t in tasks:
        name = clean_name(t.id)
        if len(name) > _MAX_ID:
            name = f"{name[:_MAX_ID - 9].rstrip('.-')}~{digest(t)}"
        ids.append(name)
    counts: dict[str, int] = {}
    for name in ids:
        counts[name.lower()] = counts.get(name.lower(), 0) + 1
    out = []
    taken: set[str] = set()
    for t, name in zip(tasks, ids, strict=True):
        if counts[name.lower()] > 1:
            name = f"{name}~{digest(t)}"
        base, k = name, 1
        while name.lower() in taken:  # a hash clash, or an id that already looked like a disambiguated one
            name, k = f"{base}~{k}", k + 1
        taken.add(name.lower())
        assert is_safe_id(name), name
        out.append(Task(name, t.mission, t.seed, t.duration_s, t.params, t.repeat))
    return out
