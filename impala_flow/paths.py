"""Files a graph reads and writes: relative paths resolved, clobbering refused at validation.

A component declares its path parameters with ``Param(str, path=KIND)``
(:data:`~impala_flow.component.PATH_KINDS`); ``record.path`` is a file written. A relative
path is resolved against the folder of the graph file it is written in (like
``include:``), unless it starts with a variable given on the command line or comes from
``--set``: it then stays relative to the working directory where the user typed it.

Validation refuses, each located: an output that is the same file (links resolved) as an
input a component reads (recording over the mission being replayed destroys it); two
outputs on one path; an output whose folder cannot be created (a parent is a file, or not
writable). Nothing is created at validation time.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import PurePath

from .registry import Registry
from .spec import GraphSpec, Problem
from .yamlloc import Loc

__all__ = ["resolve_paths", "check_paths", "GraphFile", "graph_files", "looks_like_file", "output_clash"]


def looks_like_file(value: str) -> bool:
    """A ``read_or_name`` value names a file when it has a folder part or a suffix."""
    return "/" in value or os.sep in value or PurePath(value).suffix != ""


def _resolve(value: str, base: str) -> str:
    value = os.path.expanduser(value)
    if os.path.isabs(value) or not base:
        return value
    return os.path.normpath(os.path.join(base, value))


def resolve_paths(spec: GraphSpec, registry: Registry) -> list[Problem]:
    """Resolve, in place, the relative path parameters of ``spec`` and ``record.path``."""
    default_base = str(PurePath(spec.file).parent)
    for c in spec.components.values():
        cls = registry.components.get(c.type)
        if cls is None:
            continue  # validate() reports the unknown type
        for k, p in cls.__params__.items():
            value = c.params.get(k)
            if getattr(p, "path", None) is None or not isinstance(value, str) or not value:
                continue
            if p.path == "read_or_name" and not looks_like_file(value):
                continue
            c.params[k] = _resolve(value, c.param_bases.get(k, default_base))
    if spec.record is not None and isinstance(spec.record.get("path"), str) and spec.record["path"]:
        spec.record["path"] = _resolve(spec.record["path"], spec.record_base)
    return []


@dataclass(frozen=True)
class GraphFile:
    """A file a graph reads or writes: ``kind`` is a path kind, ``who`` names the owner."""

    path: str
    kind: str
    who: str
    loc: Loc | None


def graph_files(spec: GraphSpec, registry: Registry) -> list[GraphFile]:
    """Every file (resolved) the components of ``spec`` and its ``record:`` read or write."""
    files: list[GraphFile] = []
    for c in spec.components.values():
        cls = registry.components.get(c.type)
        if cls is None:
            continue
        for k, p in cls.__params__.items():
            value = c.params.get(k, p.default)
            kind = getattr(p, "path", None)
            if kind is None or not isinstance(value, str) or not value:
                continue
            if kind == "read_or_name":
                if not looks_like_file(value):
                    continue
                kind = "read"
            files.append(GraphFile(value, kind, f"component '{c.id}' ({c.type}) parameter '{k}'",
                                   c.param_locs.get(k, c.loc)))
    if spec.record is not None and isinstance(spec.record.get("path"), str) and spec.record["path"]:
        files.append(GraphFile(spec.record["path"], "write", "record", spec.record_loc))
    return files


def _same(a: str, b: str) -> bool:
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    try:
        return os.path.samefile(a, b)  # hard links
    except OSError:
        return False


def _not_creatable(f: GraphFile) -> str | None:
    """Why ``f`` (an output) cannot be written, or None."""
    path = os.path.abspath(f.path)
    if os.path.exists(path):
        if f.kind == "write" and os.path.isdir(path):
            return f"'{f.path}' is a folder, not a file"
        if f.kind == "write_dir" and not os.path.isdir(path):
            return f"'{f.path}' is a file, not a folder"
        if not os.access(path, os.W_OK):
            return f"'{f.path}' is not writable"
        return None
    parent = os.path.dirname(path)
    while not os.path.exists(parent):
        up = os.path.dirname(parent)
        if up == parent:
            break
        parent = up
    if not os.path.isdir(parent):
        return f"its folder cannot be created: '{parent}' is a file"
    if not os.access(parent, os.W_OK | os.X_OK):
        return f"its folder cannot be created: no permission to write in '{parent}'"
    return None


def check_paths(spec: GraphSpec, registry: Registry) -> list[Problem]:
    """Outputs overwriting inputs, two outputs on one path, outputs that cannot be created."""
    problems: list[Problem] = []
    files = graph_files(spec, registry)
    reads = [f for f in files if f.kind == "read"]
    writes = [f for f in files if f.kind != "read"]
    for i, w in enumerate(writes):
        for r in reads:
            if _same(w.path, r.path):
                problems.append(Problem(w.loc, f"{w.who} writes '{w.path}', the file {r.who} reads (at {r.loc}): "
                                               "it would be overwritten; write somewhere else"))
        for w0 in writes[:i]:
            if _same(w.path, w0.path):
                problems.append(Problem(w.loc, f"{w.who} writes '{w.path}', as {w0.who} does (at {w0.loc}): "
                                               "one would overwrite the other"))
        why = _not_creatable(w)
        if why:
            problems.append(Problem(w.loc, f"{w.who}: cannot write '{w.path}': {why}"))
    return problems


def _inside(child: str, parent: str) -> bool:
    try:
        return os.path.commonpath([child, parent]) == parent
    except ValueError:  # different drives
        return False


def output_clash(output: str, inputs: list[tuple[str, str]]) -> str | None:
    """Why writing ``output`` (a file or a folder) could destroy one of ``inputs``, or None.

    ``inputs`` are ``(path, what)`` pairs (``what`` names it in the message, e.g. "the dataset
    folder"). Refused, links resolved: the output *is* an input (same file, hard links too),
    lies *inside* an input folder, or is a folder *over* (containing) an input. Commands call
    it before any work, so nothing the user owns is touched when it says no.
    """
    out = os.path.realpath(os.path.expanduser(output))
    for path, what in inputs:
        inp = os.path.realpath(os.path.expanduser(path))
        if out == inp or _same(output, path):
            return f"'{output}' is {what} '{path}' itself: it would be overwritten"
        if os.path.isdir(inp) and _inside(out, inp):
            return f"'{output}' is inside {what} '{path}': write outside it"
        if _inside(inp, out):
            return f"'{output}' contains {what} '{path}': write elsewhere"
    return None
