"""Mirrors: a second, tool-readable copy of a recorded stream, written beside it.

A plugin registers, for a Python type ``T``, a factory ``make(T) -> Mirror | None``
(``registry.add_mirror(T, make)`` in ``impala_flow_register``); the run's
:class:`~impala_flow.io.CodecRegistry` carries it to the :class:`~impala_flow.io.MissionWriter`,
which writes every value of type ``T`` twice: on its own channel, exactly (``impala-flow-bin``),
and converted by the mirror on the channel ``mirror.topic_of(topic)`` (metadata
``impala_flow.mirror_of = <topic>``). Readers of recorded streams skip mirror channels.

Two keys are special: ``object`` registers the fallback mirror of every type without its own
(the writer uses it only when asked, ``json_views``), and :data:`TRANSFORMS` the mirror of the
frame tree (a list of planar transforms ``(parent, child, x_m, y_m, z_m, yaw_rad)``) that
:meth:`~impala_flow.io.MissionWriter.write_transforms` writes on ``mirror.topic``. The engine
registers no mirror itself: without a plugin that does, recordings have no mirror channels.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

__all__ = ["Mirror", "MirrorFactory", "MIRROR_KEY", "TRANSFORMS", "FRAMES_MIRROR_OF"]

#: channel metadata key of a mirror channel: the topic it mirrors
MIRROR_KEY = "impala_flow.mirror_of"
#: registration key of the frame-tree mirror (``registry.add_mirror(TRANSFORMS, make)``)
TRANSFORMS = "transforms"
#: ``MIRROR_KEY`` value of the frame-tree channel
FRAMES_MIRROR_OF = "frames"


@dataclass(frozen=True)
class Mirror:
    """How values of one type are mirrored: the schema (name, data, encoding), the message
    encoding and ``convert(value, t_ns) -> bytes``.

    The mirror channel of ``topic`` is ``prefix + topic`` (its leading ``/`` removed); ``topic``,
    when set, is a fixed channel (the frame tree's)."""

    schema_name: str
    schema_data: bytes
    convert: Callable[[Any, int], bytes]
    schema_encoding: str = "protobuf"
    message_encoding: str = "protobuf"
    prefix: str = "/mirror/"
    topic: str = ""

    def topic_of(self, topic: str) -> str:
        """The mirror channel of ``topic``."""
        return self.topic or self.prefix + topic.lstrip("/")


#: builds the mirror of a type (or of the key :data:`TRANSFORMS`), None when it has none
MirrorFactory = Callable[[Any], "Mirror | None"]
