"""Sample: one timestamped datum flowing on a connection."""

from __future__ import annotations

from typing import Any

__all__ = ["Sample"]


class Sample:
    """A datum stamped with its acquisition time.

    ``timestamp`` is an ``int`` of nanoseconds on the mission clock (MCAP ``log_time``
    uses the same unit); ``seq`` counts the samples of the output that emitted it;
    ``origin`` names that output as ``component.port``. Arrays inside ``data`` are
    read-only once emitted, so a sample is shared, never copied, by every input it
    reaches, and checked once for validity (:mod:`impala_flow._ports`). ``nbytes`` caches the
    size of ``data`` once an input bounded in bytes has measured it (-1 until then; see
    :func:`impala_flow._ports.sample_nbytes`). ``entered_ns`` is set by the real-time executor
    only: the mission clock when the sample's origin entered the graph (the latency figures of
    :mod:`impala_flow._timing`); None otherwise.
    """

    __slots__ = ("timestamp", "data", "seq", "origin", "nbytes", "invalid", "entered_ns")

    def __init__(self, timestamp: int, data: Any, seq: int = 0, origin: str = "") -> None:
        self.timestamp = timestamp
        self.data = data
        self.seq = seq
        self.origin = origin
        self.nbytes = -1
        # why ``data`` is invalid ('' when valid, None before any input checked it): the first
        # input that checks a sample keeps the verdict, so a fanned-out sample is checked once
        self.invalid: str | None = None
        self.entered_ns: int | None = None

    @property
    def t_ns(self) -> int:
        return self.timestamp

    def __repr__(self) -> str:
        return f"Sample(t_ns={self.timestamp}, seq={self.seq}, origin={self.origin!r}, data={type(self.data).__name__})"
