"""Message packages installed beside the engine: the ``impala_flow.messages`` entry point group.

A message package declares one entry point whose value is a module with ``TYPES`` (its
``@message`` classes) and, optionally, ``LEGACY`` (``(old type, upgrade function)`` pairs
for older versions found in recordings)::

    [project.entry-points."impala_flow.messages"]
    impala_msgs = "impala_msgs"

The engine's registries and recording readers know every type of every installed package,
with no plugin loaded (``impala-flow info`` on a recording of radar beams decodes them). A
package that fails to import is left out with one warning naming it and why.
"""

from __future__ import annotations

import functools
import importlib
import logging
from dataclasses import dataclass
from importlib.metadata import entry_points
from typing import Any

from ._base import is_message

__all__ = ["GROUP", "MessagePackage", "installed_packages", "installed_types"]

GROUP = "impala_flow.messages"
_log = logging.getLogger("impala_flow")


@dataclass(frozen=True)
class MessagePackage:
    """One installed message package: its entry point name, types and legacy readers."""

    name: str
    types: tuple[type, ...]
    legacy: tuple[tuple[type, Any], ...]


def _load(ep: Any) -> MessagePackage:
    module = importlib.import_module(ep.value.split(":", 1)[0])
    types = tuple(getattr(module, "TYPES", ()))
    legacy = tuple(getattr(module, "LEGACY", ()))
    bad = [t for t in types if not is_message(t)] + [old for old, _ in legacy if not is_message(old)]
    if bad:
        raise TypeError(f"{bad[0]!r} is not a @message type")
    return MessagePackage(ep.name, types, legacy)


@functools.cache
def installed_packages() -> tuple[MessagePackage, ...]:
    """The installed message packages, by entry point name (read once per process)."""
    out = []
    for ep in sorted(entry_points(group=GROUP), key=lambda e: e.name):
        try:
            out.append(_load(ep))
        except Exception as e:  # a broken package must not break the engine
            _log.warning("message package '%s' (%s) left out: %s: %s", ep.name, ep.value, type(e).__name__, e)
    return tuple(out)


def installed_types() -> tuple[type, ...]:
    """Every message type of every installed message package."""
    return tuple(t for p in installed_packages() for t in p.types)
