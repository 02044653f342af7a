"""CDR decoding of one channel with the definition stored in the file (mcap-ros2-support's DecoderFactory)."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory  # never mcap_ros2.reader: it warns (deprecated) on import

from impala_flow.io import AdaptedChannel

__all__ = ["decoder_of", "stamp_ns", "yaw_of", "ROS2MSG", "ROS2IDL", "CDR"]

ROS2MSG, ROS2IDL, CDR = "ros2msg", "ros2idl", "cdr"


def decoder_of(channel: AdaptedChannel) -> Callable[[bytes | memoryview], Any]:
    """``decode(payload) -> message`` (fields as attributes) for ``channel``; ValueError (one line) when its
    definition does not parse or a payload does not decode."""
    schema = Schema(id=1, name=channel.schema_name, encoding=channel.schema_encoding, data=channel.schema_data)
    try:
        decode = DecoderFactory().decoder_for(channel.message_encoding, schema)
    except Exception as e:  # noqa: BLE001 - the parser raises several kinds: one line either way
        raise ValueError(f"its ROS 2 definition does not parse ({type(e).__name__}: {e})") from None
    if decode is None:
        raise ValueError(f"schema encoding {channel.schema_encoding!r} with {channel.message_encoding!r} messages "
                         "is not ROS 2 ros2msg/cdr")

    def safe(payload: bytes | memoryview) -> Any:
        try:
            return decode(bytes(payload))
        except Exception as e:  # noqa: BLE001 - a short or garbled payload: one line, with where (the reader)
            raise ValueError(f"CDR payload of {len(payload)} bytes does not decode as {channel.schema_name} "
                             f"({type(e).__name__}: {e})") from None

    return safe


def stamp_ns(header: Any, log_time_ns: int) -> int:
    """A std_msgs/Header's stamp as int ns (sec * 10^9 + nanosec, exact); the log time when the stamp is zero."""
    t = int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)
    return t if t != 0 else int(log_time_ns)


def yaw_of(q: Any) -> float:
    """Yaw (rad, about z, counter-clockwise) of a geometry_msgs/Quaternion: atan2(2(wz + xy), 1 - 2(y^2 + z^2))."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))
