"""Stage 2 of graph loading, *resolve*: the relative paths of a loaded spec made usable.

A component declares its path parameters with ``Param(str, path=KIND)``; ``record.path`` is
a file written. A relative path is resolved against the folder noted for it by the *load*
stage (:mod:`impala_flow._load`): the folder of the graph file it is written in (like
``include:``), or the working directory for a value that starts with a variable given on the
command line or comes from ``--set``. A ``read_or_name`` value that is a bare name (no folder
part, no suffix) is left alone. Runs before *validate* (:mod:`impala_flow._validate`), which
checks the resolved files (:mod:`impala_flow._paths`).
"""

from __future__ import annotations

import os
from pathlib import PurePath

from ._paths import looks_like_file
from ._registry import Registry
from ._spec import GraphSpec, Problem

__all__ = ["resolve_paths"]


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
