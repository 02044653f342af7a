"""CDR encoding of ROS 2 messages with mcap-ros2-support's encoder, from the definitions of :mod:`impala_ros2.msgdefs`.

The encoder (``serialize_dynamic``, what ``mcap_ros2.writer.Writer`` encodes with) is built once per schema from the
schema text stored in the file, so what is written is what a generic decoder reads back. A large ``int8[]`` array
that ends a message (an OccupancyGrid's cells) is appended in one piece (:func:`encode_with_tail`): the encoder
writes the message with an empty array, whose 4-byte length ends the buffer (CDR aligns it to 4), the length is
replaced and the raw bytes follow (one-byte elements need no alignment): the bytes the encoder would write value by
value.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from functools import cache
from typing import Any

from mcap_ros2._dynamic import serialize_dynamic

from ..msgdefs import SEPARATOR, schema_name, schema_text, short_name

__all__ = ["schema", "encode", "encode_with_tail", "element", "encode_with_elements"]


@cache
def schema(ros_type: str) -> tuple[str, bytes]:
    """(schema name as rosbag2 writes it, ``ros2msg`` schema data) of ``pkg/Type``."""
    return schema_name(ros_type), schema_text(ros_type).encode()


@cache
def _encoder(name: str, data: bytes) -> Callable[[Any], bytes]:
    return serialize_dynamic(name, data.decode())[name]


def encode(channel: Any, message: dict[str, Any]) -> bytes:
    """CDR bytes of ``message`` (a dict) in the schema of ``channel``."""
    return _encoder(channel.schema_name, channel.schema_data)(message)


def encode_with_tail(channel: Any, message: dict[str, Any], tail: bytes) -> bytes:
    """CDR bytes of ``message`` whose last field, a one-byte array, holds ``tail`` (``message`` has it empty)."""
    head = encode(channel, message)
    if head[-4:] != b"\0\0\0\0":
        raise ValueError(f"{channel.schema_name}: the message does not end with an empty array")
    return head[:-4] + struct.pack("<I", len(tail)) + tail


@cache
def _padded_encoder(ros_type: str) -> Callable[[Any], bytes]:
    """The encoder of ``ros_type`` placed after a 4-byte field (a synthetic ``impala_ros2/Padded`` message)."""
    short = short_name(ros_type)
    text = f"uint32 pad\n{short} element\n{SEPARATOR}\nMSG: {short}\n{schema_text(short)}"
    return serialize_dynamic("impala_ros2/Padded", text)["impala_ros2/Padded"]


def element(ros_type: str, message: dict[str, Any]) -> tuple[bytes, bytes]:
    """The CDR bytes of one ``ros_type`` message as a sequence element starting at offset 0 and at offset 4 modulo 8
    (without the 4-byte encapsulation header)."""
    name, data = schema(ros_type)
    at0 = _encoder(name, data)(message)[4:]
    at4 = _padded_encoder(ros_type)({"pad": 0, "element": message})[8:]
    return at0, at4


def encode_with_elements(channel: Any, message: dict[str, Any], elements: list[tuple[bytes, bytes]]) -> bytes:
    """CDR bytes of ``message`` whose last field, a sequence of messages, holds ``elements`` (from :func:`element`;
    ``message`` has it empty)."""
    head = encode(channel, message)
    if head[-4:] != b"\0\0\0\0":
        raise ValueError(f"{channel.schema_name}: the message does not end with an empty sequence")
    parts = [head[:-4], struct.pack("<I", len(elements))]
    offset = len(head) - 4  # counted from the end of the encapsulation header
    for at0, at4 in elements:
        if offset % 4:
            pad = 4 - offset % 4
            parts.append(bytes(pad))
            offset += pad
        b = at0 if offset % 8 == 0 else at4
        parts.append(b)
        offset += len(b)
    return b"".join(parts)
