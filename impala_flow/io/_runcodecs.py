"""The codec registry of a run: standard types plus the message types and mirrors plugins register."""

from __future__ import annotations

import logging

from ._registry import CodecRegistry

log = logging.getLogger(__name__)


def run_codecs(registry: object | None = None) -> CodecRegistry:
    """Standard types, then every message type, codec and mirror the run's plugins registered.

    ``registry`` is the run's (``Component.registry``, set when a graph is built); without
    one (validation, hand-wired components) the installed plugins are loaded again here,
    and a plugin that fails to load leaves the standard types usable.
    """
    if registry is not None:
        return CodecRegistry.from_plugins(registry)
    try:
        from ..plugins import load_registry

        return CodecRegistry.from_plugins(load_registry())
    except Exception as e:  # noqa: BLE001 - never fail a recording for an unrelated plugin
        log.warning("plugin types unavailable for recording/replay: %s", e)
        return CodecRegistry.with_standard_types()
