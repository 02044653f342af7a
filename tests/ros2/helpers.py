"""Reading back written ROS 2 files with mcap-ros2-support's generic decoder (the schemas stored in the file)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory


def ros_messages(path: Path) -> dict[str, list[tuple[int, str, Any]]]:
    """topic -> [(log time, schema name, decoded message)] of every CDR channel, in log-time order."""
    out: dict[str, list[tuple[int, str, Any]]] = {}
    factory = DecoderFactory()
    with open(path, "rb") as f:
        for schema, channel, message, decoded in make_reader(f, decoder_factories=[factory]).iter_decoded_messages(
                topics=_cdr_topics(path)):
            out.setdefault(channel.topic, []).append((message.log_time, schema.name, decoded))
    return out


def _cdr_topics(path: Path) -> list[str]:
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return [c.topic for c in summary.channels.values() if c.message_encoding == "cdr"]


def channels(path: Path) -> dict[str, tuple[str, str, str, dict[str, str]]]:
    """topic -> (schema name, schema encoding, message encoding, channel metadata) of every channel."""
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return {c.topic: (summary.schemas[c.schema_id].name, summary.schemas[c.schema_id].encoding, c.message_encoding,
                      dict(c.metadata)) for c in summary.channels.values()}


def ns(stamp: Any) -> int:
    """int ns of a builtin_interfaces/Time."""
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def yaw(q: Any) -> float:
    """Yaw of a quaternion about z (the textbook formula, independent of the writer's)."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def cdr_payloads(path: Path) -> dict[str, list[tuple[int, bytes]]]:
    """topic -> [(log time, CDR bytes)] of every CDR channel, in file order."""
    out: dict[str, list[tuple[int, bytes]]] = {}
    with open(path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(topics=_cdr_topics(path)):
            out.setdefault(channel.topic, []).append((message.log_time, bytes(message.data)))
    return out
