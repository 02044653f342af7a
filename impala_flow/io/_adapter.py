"""Channel adapters: read channels of a foreign encoding (a rosbag2's ROS 2 messages) as the project's samples.

A plugin registers, for a (schema encoding, schema name, message encoding) key, a factory
``make(channel, context) -> ChannelAdapter`` (``registry.add_channel_adapter(...)`` in
``impala_flow_register``; schema name ``"*"``: every schema of that encoding without its own
adapter). The run's :class:`~impala_flow.io.CodecRegistry` carries it to the
:class:`~impala_flow.io.MissionReader`, which reads a channel with no native codec through its
adapter: every message (payload bytes, log time) becomes zero or more ``(t_ns, sample)``, each
with its own time (one ROS image of a radar turn becomes hundreds of beams). The reader puts
them in time order through a bounded reordering window (an adapter may hold samples back until
the next message, and give them from an optional ``finish()`` at the end); a sample still earlier than what was
already given is dropped and counted (:attr:`MissionReader.late`), never silently.

A factory that cannot read the channel raises ``ValueError`` with one line (e.g. a schema
encoding it refuses): the channel is then listed as undecodable with that line. ``adapt``
raises ``ValueError`` for a message it cannot read; the reader names the file, topic and time.
The engine registers no adapter itself and knows nothing of what they read.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, Protocol

__all__ = ["ChannelAdapter", "AdapterFactory", "AdaptedChannel", "AdapterContext", "ANY_SCHEMA"]

#: schema name of a factory serving every schema of its encodings without a factory of its own
ANY_SCHEMA = "*"


@dataclass(frozen=True)
class AdaptedChannel:
    """One recorded channel as the adapter sees it."""

    topic: str
    schema_name: str
    schema_encoding: str
    schema_data: bytes
    message_encoding: str
    metadata: dict[str, str] = field(default_factory=dict)


@dataclass(frozen=True)
class AdapterContext:
    """What a factory may know besides its channel: every channel of the file, the payloads and log
    times of a channel's first ``n`` messages (``head(topic, n) -> [(bytes, t_ns), ...]``: e.g. a
    sensor's configuration published on another topic, or the first stamps to measure a rate) and
    the options the user gave (``io.Replayer``'s ``adapter_params``, ``import ... --config KEY=VALUE``)."""

    path: str
    channels: tuple[AdaptedChannel, ...]
    head: Callable[[str, int], list[tuple[bytes, int]]]
    params: dict[str, Any] = field(default_factory=dict)


class ChannelAdapter(Protocol):
    """Reads one foreign channel: ``value_type`` is the type of the samples it gives."""

    value_type: type

    def adapt(self, payload: memoryview, log_time_ns: int) -> Iterable[tuple[int, Any]]:
        """The samples of one message, ``(t_ns, value)`` in time order (ValueError: unreadable)."""
        ...

    def notes(self) -> list[str]:
        """One line each: how the samples were made (times spread, geometry from where), what was dropped."""
        ...

    # optional: ``finish() -> Iterable[(t_ns, value)]``, the samples an adapter held back (e.g. a radar turn waiting
    # for the next turn's stamp to spread its beams up to it), asked for when the reading ends


#: builds the adapter of one channel (ValueError: refused, with one line saying why)
AdapterFactory = Callable[[AdaptedChannel, AdapterContext], ChannelAdapter]
