"""The codec registry of a run: standard types plus the message types and mirrors plugins register."""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from ._registry import CodecRegistry

__all__ = ["run_codecs", "set_plugin_loader"]

log = logging.getLogger(__name__)

#: loads the installed plugins' registry for a run that has none: set by impala_flow.plugins, which
#: sits above io in the engine's layers (io never imports it, so there is no import circle)
_loader: list[Callable[[], Any]] = []


def set_plugin_loader(load: Callable[[], Any]) -> None:
    """Make :func:`run_codecs` without a registry use ``load()`` (the installed plugins' registry)."""
    _loader[:] = [load]


def run_codecs(registry: object | None = None) -> CodecRegistry:
    """Standard types, then every message type, codec and mirror the run's plugins registered.

    ``registry`` is the run's (``Component.registry``, set when a graph is built); without
    one (validation, hand-wired components) the installed plugins are loaded again here,
    and a plugin that fails to load leaves the standard types usable.
    """
    if registry is not None:
        return CodecRegistry.from_plugins(registry)
    if not _loader:  # impala_flow.plugins not imported: the standard types (message packages included)
        return CodecRegistry.with_standard_types()
    try:
        return CodecRegistry.from_plugins(_loader[0]())
    except Exception as e:  # noqa: BLE001 - never fail a recording for an unrelated plugin
        log.warning("plugin types unavailable for recording/replay: %s", e)
        return CodecRegistry.with_standard_types()
