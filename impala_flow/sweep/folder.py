"""A sweep's folder: what it is made from, what the sweep wrote there, and what it may delete.

``DIR/sweep-record.json`` is written before any task runs. It records the sweep's identity
(the sweep file's and the graph's content, with their includes and scenario files, by
SHA-256; each mission file's path, size and modification time) and everything the sweep
creates there (its output files, ``tasks/<id>/`` per task, its simulated missions). Then:

- a folder that exists and is not empty is used only with ``resume`` (a sweep folder, the same
  sweep: anything different is refused, naming it) or ``overwrite`` (a sweep folder: what the
  previous sweep created is removed, nothing else; another folder: refused if any name the
  sweep writes is already there, so no file of the user's is ever overwritten);
- an output folder equal to, inside or over a mission, the sweep file or the graph is refused
  (:func:`impala_flow._paths.output_clash`);
- deletions go through :func:`remove_own`: one child of the sweep's ``tasks/`` or
  ``missions/`` folder, named as the sweep names them, links not followed.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from pathlib import Path
from typing import Any

from .._paths import output_clash
from .spec import SweepError, SweepSpec, is_safe_id

__all__ = ["RECORD", "OWN_FILES", "prepare_folder", "sweep_identity", "remove_own", "compare"]

RECORD = "sweep-record.json"
#: files a sweep writes at the top of its folder (beside tasks/ and missions/)
OWN_FILES = ("results.csv", "summary.md", "variants.png", "dask.log")
_FORMAT = 1


def _sha256(path: str | Path) -> str | None:
    h = hashlib.sha256()
    try:
        with open(path, "rb") as f:
            for block in iter(lambda: f.read(1 << 20), b""):
                h.update(block)
    except OSError:
        return None
    return h.hexdigest()


def _graph_files(graph: Path) -> list[str]:
    """The graph file and the files it includes (each once)."""
    from .._load import _read

    try:
        _, chain = _read(graph.resolve(), [], (graph.resolve(),), {graph.resolve()}, [1 << 30])
    except Exception:  # an unreadable graph: the check before says why
        return [str(graph)]
    return [str(graph)] + sorted(str(p) for _, p in chain)


def _mission_id(path: str) -> dict[str, Any]:
    try:
        st = os.stat(path)
    except OSError:
        return {"path": path, "size": None, "mtime_ns": None}
    return {"path": path, "size": st.st_size, "mtime_ns": st.st_mtime_ns}


def sweep_identity(spec: SweepSpec) -> dict[str, Any]:
    """What makes two sweeps the same one (see the module doc)."""
    return {
        "sweep_file": {"path": str(spec.path.resolve()), "sha256": _sha256(spec.path)},
        "graph": [{"path": p, "sha256": _sha256(p)} for p in _graph_files(spec.graph)],
        "scenarios": [{"path": p, "sha256": _sha256(p)} for p in spec.scenario_files],
        "missions": [_mission_id(p) for p in spec.files],
    }


def compare(old: dict[str, Any], new: dict[str, Any]) -> list[str]:
    """What differs between two identities, one phrase each (empty: the same sweep)."""
    diffs: list[str] = []
    if old.get("sweep_file", {}).get("sha256") != new["sweep_file"]["sha256"]:
        diffs.append(f"the sweep file {new['sweep_file']['path']} is not the one the folder was made from "
                     f"({old.get('sweep_file', {}).get('path')}, content differs)")
    for what in ("graph", "scenarios"):
        before = {g["path"]: g["sha256"] for g in old.get(what, [])}
        now = {g["path"]: g["sha256"] for g in new[what]}
        for p in now.keys() - before.keys():
            diffs.append(f"{what} file {p} is new")
        for p in before.keys() - now.keys():
            diffs.append(f"{what} file {p} is no longer used")
        diffs += [f"{what} file {p} changed (content differs)" for p in now if p in before and now[p] != before[p]]
    before_m = {m["path"]: m for m in old.get("missions", [])}
    now_m = {m["path"]: m for m in new["missions"]}
    for p in now_m.keys() - before_m.keys():
        diffs.append(f"mission {p} is not one of the folder's")
    for p in before_m.keys() - now_m.keys():
        diffs.append(f"mission {p} of the folder is no longer in the sweep")
    for p, m in now_m.items():
        b = before_m.get(p)
        if b is None:
            continue
        if b.get("size") != m["size"]:
            diffs.append(f"mission {p} changed: {b.get('size')} bytes then, {m['size']} now")
        elif b.get("mtime_ns") != m["mtime_ns"]:
            diffs.append(f"mission {p} changed: modified since the folder was made")
    return diffs


def _read_record(out: Path) -> dict[str, Any] | None:
    path = out / RECORD
    if not path.is_file() or path.is_symlink():
        return None
    try:
        rec = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeError, ValueError):
        return None
    return rec if isinstance(rec, dict) and rec.get("format") == _FORMAT else None


def _write_record(out: Path, spec: SweepSpec, identity: dict[str, Any]) -> None:
    from .runner import mission_file

    sims = sorted({mission_file(out, t).name for t in spec.tasks if t.simulated})
    rec = {"format": _FORMAT, "identity": identity, "tasks": [t.id for t in spec.tasks], "missions": sims}
    tmp = out / f".{RECORD}.{os.getpid()}.part"
    tmp.write_text(json.dumps(rec, indent=1) + "\n", encoding="utf-8")
    os.replace(tmp, out / RECORD)


def remove_own(root: Path, name: str, kind: str) -> None:
    """Delete ``root/kind/name`` (kind: ``tasks`` or ``missions``), a thing the sweep made:
    refused (:class:`SweepError`) unless ``name`` is one safe name (no separator, not ``.``
    nor ``..``, no leading dot) and the path resolves to a direct child of ``root/kind``; a
    link is unlinked, never followed."""
    if kind not in ("tasks", "missions") or not is_safe_id(name):
        raise SweepError(f"refusing to delete {root / kind / name!s}: not a name the sweep gives")
    parent = root / kind
    path = parent / name
    inside = os.path.realpath(os.path.dirname(path)) == os.path.realpath(parent) and os.path.basename(path) == name
    if parent.is_symlink() or not inside:
        raise SweepError(f"refusing to delete {path}: not inside the sweep's {kind} folder")
    if path.is_symlink() or path.is_file():
        path.unlink()
    elif path.is_dir():
        shutil.rmtree(path)


def prepare_folder(spec: SweepSpec, out: str | Path, *, resume: bool = False, overwrite: bool = False) -> Path:
    """Make ``out`` the folder of this sweep (module doc) or raise :class:`SweepError` without
    touching anything; return it resolved."""
    if resume and overwrite:
        raise SweepError("--resume and --overwrite: give one (resume keeps what is done, overwrite starts again)")
    out = Path(out)
    inputs = [(spec.path, "the sweep file"), *((g, "the graph file") for g in _graph_files(spec.graph)),
              *((s, "the scenario file") for s in spec.scenario_files), *((m, "the mission") for m in spec.files)]
    clash = output_clash(str(out), [(str(p), what) for p, what in inputs])
    if clash:
        raise SweepError(f"{out}: the sweep's folder: {clash}")
    if out.exists() and not out.is_dir():
        raise SweepError(f"{out}: not a folder")
    identity = sweep_identity(spec)
    rec = _read_record(out) if out.is_dir() else None
    empty = not out.exists() or not any(out.iterdir())
    if resume:
        if rec is None:
            raise SweepError(f"--resume {out}: not a sweep folder (no {RECORD} there): nothing to resume")
        diffs = compare(rec.get("identity") or {}, identity)
        if diffs:
            more = f" (and {len(diffs) - 3} more)" if len(diffs) > 3 else ""
            raise SweepError(f"--resume {out}: not the same sweep: {'; '.join(diffs[:3])}{more}; -o another "
                             "folder, or --overwrite to start this folder again")
    elif not empty:
        if rec is not None:
            if not overwrite:
                raise SweepError(f"-o {out}: a sweep's folder already (made from "
                                 f"{(rec.get('identity') or {}).get('sweep_file', {}).get('path')}): --resume {out} "
                                 "to finish it, --overwrite to start it again, or -o another folder")
            _remove_previous(out.resolve(), rec)
        else:
            if not overwrite:
                raise SweepError(f"-o {out}: the folder exists, is not empty and is not a sweep's: -o a new or empty "
                                 "folder, or --overwrite to write the sweep beside what is there")
            taken = [n for n in (*OWN_FILES, "tasks", "missions", RECORD) if os.path.lexists(out / n)]
            if taken:
                raise SweepError(f"-o {out} --overwrite: {out / taken[0]} is not a sweep's and would be overwritten"
                                 + (f" (and {len(taken) - 1} more: {', '.join(taken[1:])})" if len(taken) > 1 else "")
                                 + ": move it, or -o another folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise SweepError(f"{out}: cannot create the folder: {e.strerror or e}") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise SweepError(f"{out}: cannot write in this folder")
    out = out.resolve()
    if not resume:
        _write_record(out, spec, identity)
    return out


def _remove_previous(out: Path, rec: dict[str, Any]) -> None:
    """Remove what the sweep recorded in ``rec`` created in ``out``, and nothing else."""
    for name in OWN_FILES:
        p = out / name
        if p.is_symlink() or p.is_file():
            p.unlink()
    for kind, names in (("tasks", rec.get("tasks") or []), ("missions", rec.get("missions") or [])):
        for name in names:
            if isinstance(name, str) and is_safe_id(name):
                remove_own(out, name, kind)
                if kind == "missions":
                    remove_own(out, os.path.splitext(name)[0] + ".log", kind)
        folder = out / kind
        if folder.is_dir() and not folder.is_symlink() and not any(folder.iterdir()):
            folder.rmdir()
    (out / RECORD).unlink(missing_ok=True)
