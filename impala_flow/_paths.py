"""Files a graph reads and writes (:func:`graph_files`), clobbering refused at validation.

A component declares its path parameters with ``Param(str, path=KIND)``
(:data:`~impala_flow._component.PATH_KINDS`); ``record.path`` is a file written. A relative
path is resolved against the folder of the graph file it is written in (like
``include:``), unless it starts with a variable given on the command line or comes from
``--set``: it then stays relative to the working directory where the user typed it (that is
the *resolve* stage, :mod:`impala_flow._resolve`; this module knows the files of a resolved spec).

Validation refuses, each located: an output that is the same file (links resolved) as an
input a component reads (recording over the mission being replayed destroys it), lies
inside an input folder, or is a folder containing an input (:func:`output_clash`); two
outputs on one path; an output that cannot be created: a parent is a file or not writable,
a name longer than the file system takes (``ENAMETOOLONG``, found here rather than in
``stop()`` after the whole run), a named pipe or socket where a file is written. Nothing is
created at validation time.
"""

from __future__ import annotations

import os
import stat
from dataclasses import dataclass
from pathlib import PurePath

from ._registry import Registry
from ._spec import GraphSpec, Problem
from ._yamlloc import Loc

__all__ = ["check_paths", "GraphFile", "graph_files", "looks_like_file", "output_clash",
           "not_writable"]


def looks_like_file(value: str) -> bool:
    """A ``read_or_name`` value names a file when it has a folder part or a suffix."""
    return "/" in value or os.sep in value or PurePath(value).suffix != ""


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


def _limit(folder: str, name: str, default: int) -> int:
    try:
        return int(os.pathconf(folder, name))
    except (OSError, ValueError):
        return default


def _too_long(path: str, existing: str) -> str | None:
    """Why the absolute ``path`` cannot exist on the file system of ``existing`` (its
    deepest existing folder): a name or the whole path too long (``ENAMETOOLONG``)."""
    name_max = _limit(existing, "PC_NAME_MAX", 255)
    for part in path.split(os.sep):
        size = len(os.fsencode(part))
        if size > name_max:
            return f"the name '{part[:24]}...' is {size} bytes long, more than the {name_max} the file system takes"
    size, path_max = len(os.fsencode(path)), _limit(existing, "PC_PATH_MAX", 4096)
    if size >= path_max:
        return f"the path is {size} bytes long, more than the {path_max - 1} the file system takes"
    return None


def not_writable(path: str, kind: str = "write") -> str | None:
    """Why ``path`` cannot be written as a file (``kind`` "write") or a folder ("write_dir"),
    or None: a folder where a file goes (or the reverse), a named pipe or socket (writing
    would wait or fail), no write permission, a name too long, a parent that is a file or
    in which nothing can be created. Nothing is created."""
    path = os.path.abspath(os.path.expanduser(path))
    existing = path if os.path.exists(path) else os.path.dirname(path)
    while not os.path.exists(existing):
        up = os.path.dirname(existing)
        if up == existing:
            break
        existing = up
    too_long = _too_long(path, existing if os.path.isdir(existing) else os.path.dirname(existing))
    if too_long:
        return too_long
    if os.path.exists(path):
        st = os.stat(path)
        if kind == "write" and stat.S_ISDIR(st.st_mode):
            return "it is a folder, not a file"
        if kind == "write_dir" and not stat.S_ISDIR(st.st_mode):
            return "it is a file, not a folder"
        if stat.S_ISFIFO(st.st_mode) or stat.S_ISSOCK(st.st_mode):
            return "it is a named pipe or a socket, not a file"
        if not os.access(path, os.W_OK):
            return "it is not writable"
        return None
    if not os.path.isdir(existing):
        return f"its folder cannot be created: '{existing}' is a file"
    if not os.access(existing, os.W_OK | os.X_OK):
        return f"its folder cannot be created: no permission to write in '{existing}'"
    return None


def _not_creatable(f: GraphFile) -> str | None:
    """Why ``f`` (an output) cannot be written, or None."""
    return not_writable(f.path, f.kind)


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
                continue
            clash = output_clash(w.path, [(r.path, f"the input of {r.who} (at {r.loc})")])
            if clash:  # a file inside a folder read, or a folder written that holds a file read
                problems.append(Problem(w.loc, f"{w.who}: {clash}"))
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
