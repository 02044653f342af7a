"""Foreign writers: the recorded streams written again in another middleware's messages.

A plugin registers a named output format (``registry.add_foreign_writer("ros2", make)`` in
``impala_flow_register``); a recording that asks for it (``MissionWriter(..., foreign=("ros2",))``,
the recorder's ``ros2`` parameter, ``impala-flow export --ros2``) calls ``make()`` once and
hands the :class:`ForeignWriter` it returns every stream, sample and frame-tree update. Unlike a
:class:`~impala_flow.io.Mirror` (one stateless conversion per type), a foreign writer is one
object per recording: one stream may give several channels (a pose and the path it grows), a
message may need several samples (a radar turn from its beams) and may be written late
(:meth:`ForeignWriter.finish`).

The channels it declares are written beside the streams, or alone (``native=False``: a file
other tools play back as it is). Beside them they carry the metadata ``impala_flow.mirror_of =
<topic>`` (:data:`~impala_flow.io.MIRROR_KEY`), so impala-flow's readers skip them as mirrors.
A foreign writer that declares a channel for the frame tree replaces the frame-tree mirror.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any, Protocol

__all__ = ["ForeignChannel", "ForeignWriter", "ForeignMessage", "ForeignWriterFactory"]


@dataclass(frozen=True)
class ForeignChannel:
    """One channel a foreign writer writes: its topic, schema and message encoding."""

    topic: str
    schema_name: str
    schema_data: bytes
    schema_encoding: str
    message_encoding: str
    metadata: tuple[tuple[str, str], ...] = ()


#: one message of a foreign writer: (its channel, log time in int ns, payload)
ForeignMessage = tuple[ForeignChannel, int, bytes]


class ForeignWriter(Protocol):
    """What a recording asks of a foreign writer (one object per recording file)."""

    #: the MCAP header profile of a file holding only this format's channels (``ros2``)
    profile: str
    #: True: it writes the frame tree (the frame-tree mirror is then not written)
    frames: bool

    def add_topic(self, topic: str, py_type: type, child_frame: str = "") -> list[ForeignChannel]:
        """The channels the stream ``topic`` of values of ``py_type`` is written on (none: skipped).
        ``child_frame``: the frame the stream's poses place on the frame tree ('' if none)."""
        ...

    def write(self, topic: str, t_ns: int, value: Any) -> Iterable[ForeignMessage]:
        """The messages one sample gives (none, one, or several on the topic's channels)."""
        ...

    def write_transforms(self, t_ns: int,
                         transforms: list[tuple[str, str, float, float, float, float]]) -> Iterable[ForeignMessage]:
        """The messages of one frame-tree update (parent, child, x_m, y_m, z_m, yaw_rad); none if it has no
        frame tree."""
        ...

    def finish(self) -> Iterable[ForeignMessage]:
        """The messages still held when the recording closes (a turn not yet complete)."""
        ...

    def summary(self) -> dict[str, Any]:
        """What it wrote and what it could not (counts), for the run summary."""
        ...


#: makes the foreign writer of one recording
ForeignWriterFactory = Callable[[], ForeignWriter]
