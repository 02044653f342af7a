"""``radar.NavtechRadar``: a live Navtech radar (or the emulator) over the Colossus TCP protocol.

Connects to ``host:port``, reads the configuration into a :class:`~impala_msgs.RadarConfig`
(the readers' numbers: ``range_offset_bins`` 0.5 = bin centres, as the dataset readers put
them), asks for FFT data and yields one :class:`~impala_msgs.RadarBeam` per azimuth (power,
azimuth and index as :mod:`.convert` says; ``turn`` counts the encoder's wraps from 0, across
reconnections by the device time elapsed, so it stays the scan number of a recording served
from its start; within a connection by the encoder alone, so a device clock step changes no
turn number). Each beam is stamped with its device time mapped to mission time by
:class:`impala_flow.ClockSync` (the minimum-delay line of the (device time, receive time) pairs:
robust to network delay and jitter, tracks drift, detects a device clock step): the stamps keep
the device's spacing, on the mission clock every sensor of the graph shares. The mapping (offset,
drift, steps, residuals) is in the summary.

Faults: a lost connection (closed, reset, silent past ``silence_timeout_s``: a radar sends
keep-alives to an idle client), a bad signature or version, a payload over
``max_payload_bytes`` each give one warning line, then a reconnection with doubling backoff;
the beams lost meanwhile are counted (``beams_missing``, ``turns_lost``) and said. After
``reconnect_attempts`` failed attempts in a row (a connection that gave less than a whole
turn of beams counts as failed: a peer that breaks every stream early is not retried for ever),
or a configuration that changes mid-stream (another radar or geometry: the beams already emitted
would not match), the source stops with one line (:class:`NavtechError`). Every socket
operation has a timeout; :meth:`stop` returns at once and ``generate()`` leaves within one poll
(0.2 s). Under the real-time executor a streaming radar stops with the graph at its next beam,
a silent one within one poll (the executor's ``request_stop``).

A recorded run keeps what the driver knew (:meth:`source_metadata`, the MCAP metadata record
``impala_flow.source.<component>``): the endpoint, the device configuration, the counts (turns,
lost, reconnects) and the clock mapping at the end (offset, drift, steps, residuals); the beams'
stamps are the mapping applied.
"""

from __future__ import annotations

import math
import socket
import threading
import time
from collections import Counter
from collections.abc import Iterator
from typing import Any

import numpy as np

import impala_msgs
from impala_flow import ClockSync, Param

from ..datasets.common import DB_PER_COUNT_MAX, RANGE_OFFSET_MAX_BINS, navtech_config
from ..driver import RadarDriver
from .convert import azimuth_of_count, beam_power, index_of_count
from .protocol import (
    DEFAULT_PORT,
    MAX_PAYLOAD_BYTES,
    Configuration,
    FftData,
    MessageType,
    ProtocolError,
    StreamDecoder,
    encode_message,
)

__all__ = ["NavtechRadar", "NavtechError"]

_POLL_S = 0.2
_RECV_BYTES = 1 << 16
_NO_DOWN = np.zeros(0, dtype=np.float32)  # power-only: no falling-ramp spectrum


class NavtechError(RuntimeError):
    """The driver gave up (one line: what, where)."""


class _Dead(Exception):
    """This connection is over (the reason is the message); reconnect."""


class NavtechRadar(RadarDriver):
    """A Navtech radar over its Colossus TCP protocol (port 6317), or ``impala-flow
    navtech-server`` serving a recording: one beam per azimuth, stamped with the device time on
    the mission clock; reconnects after a lost connection and counts what was lost."""

    host = Param(str, default="127.0.0.1", doc="the radar's address")
    port = Param(int, default=DEFAULT_PORT, ge=1, le=65535, doc="the radar's TCP port (Navtech: 6317)")
    connect_timeout_s = Param(float, default=2.0, gt=0.0, le=60.0, doc="wait for a connection this long")
    silence_timeout_s = Param(float, default=3.0, gt=0.0, le=600.0,
                              doc="no message for this long (not even a keep-alive): the connection is dead")
    reconnect_backoff_s = Param(float, default=0.2, gt=0.0, le=60.0,
                                doc="wait before the first reconnection attempt; doubled after each failure")
    reconnect_backoff_max_s = Param(float, default=5.0, gt=0.0, le=600.0, doc="longest wait between attempts")
    reconnect_attempts = Param(int, default=10, ge=0, le=1_000_000,
                               doc="failed attempts in a row before the source stops (0: stop at the first loss)")
    max_payload_bytes = Param(int, default=MAX_PAYLOAD_BYTES, ge=64, le=MAX_PAYLOAD_BYTES,
                              doc="largest message payload accepted (the SDK's bound; a bigger one is a broken peer)")
    azimuth_offset_deg = Param(float, default=0.0, ge=-360.0, le=360.0,
                               doc="constant added to every azimuth, counter-clockwise positive (mounting yaw)")
    range_offset_bins = Param(float, default=0.5, ge=-RANGE_OFFSET_MAX_BINS, le=RANGE_OFFSET_MAX_BINS,
                              doc="range of bin 0 in bins, added to the radar's range offset: 0.5 = bin centres "
                              "(the dataset readers' convention)")
    db_per_count = Param(float, default=0.5, gt=0.0, le=DB_PER_COUNT_MAX,
                         doc="the samples' log scale: beams carry linear power 10^(count x this / 10)")
    sensor_name = Param(str, default="navtech", doc="name of the RadarConfig of the beams")
    clock_window_s = Param(float, default=20.0, gt=0.0, le=3600.0,
                           doc="device time the clock estimator fits offset and drift over")
    clock_step_ms = Param(float, default=50.0, gt=0.0, le=3_600_000.0,
                          doc="a jump of the device clock larger than this is a step (detected, counted, re-estimated)")
    clock_confirm_reads = Param(int, default=1000, ge=1, le=1_000_000,
                                doc="clock observations (one per socket read: its newest beam) in a row later than "
                                "the clock line by more than clock_step_ms that make a backward step of the device "
                                "clock (fewer: a stall of the host or the network; a step back larger than "
                                "clock_step_ms between two beams is found at once); forward steps are found "
                                "after this many observations (the estimate settled)")

    def __init__(self, name: str | None = None, **params: Any) -> None:
        super().__init__(name, **params)
        self._stop = threading.Event()
        self._sock: socket.socket | None = None
        self.config: impala_msgs.RadarConfig | None = None
        self.device_config: Configuration | None = None
        self.clock: Any = None
        self.counts: Counter = Counter()
        self.unknown_types: Counter = Counter()
        self.lost_lines: list[str] = []
        self._last: tuple[int, int, int] | None = None  # (turn, index, device ns) of the last beam
        self._gap = False  # the next beam follows a reconnection
        self._last_t = -(1 << 63)

    # --- lifecycle ---------------------------------------------------------------------------
    def start(self) -> None:
        self._stop.clear()
        self.clock = None  # made at the first configuration

    def stop(self) -> None:
        self._stop.set()
        sock = self._sock
        if sock is not None:
            try:
                sock.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass

    def request_stop(self) -> None:
        self._stop.set()  # the session's loop sees it within one poll (_POLL_S)

    def source_metadata(self) -> dict[str, str]:
        """What a recording of this radar keeps (strings: an MCAP metadata record)."""
        out = {k: str(v) for k, v in self.summary().items() if k not in ("clock", "messages_ignored")}
        if self.device_config is not None:
            d = self.device_config
            out["device_config"] = " ".join(f"{k}={getattr(d, k)}" for k in (
                "azimuth_samples", "bin_size", "range_in_bins", "encoder_size", "rotation_speed_mhz", "packet_rate",
                "range_gain", "range_offset_m"))
        if self.clock is not None:
            out.update({f"clock_{k}": str(v) for k, v in self.clock.summary().items()
                        if k not in ("window_points", "window_bytes")})
        return out

    def summary(self) -> dict[str, Any]:
        c = self.counts
        out: dict[str, Any] = {
            "endpoint": f"{self.host}:{self.port}", "connections": c["connections"],
            "reconnects": c["reconnects"], "beams": c["beams"], "turns": c["turns"],
            "beams_missing": c["beams_missing"], "turns_lost": c["turns_lost"],
            "beams_dropped": c["beams_dropped"], "keepalives": c["keepalives"],
            "stamps_held": c["stamps_held"]}
        if self.unknown_types:
            out["messages_ignored"] = dict(sorted((int(k), v) for k, v in self.unknown_types.items()))
        if self.lost_lines:
            out["gaps"] = "; ".join(self.lost_lines[:5]) + (f"; ... ({len(self.lost_lines)} in all)"
                                                             if len(self.lost_lines) > 5 else "")
        if self.clock is not None:
            out["clock"] = self.clock.summary()
        return out

    # --- the stream ----------------------------------------------------------------------------
    def generate(self) -> Iterator[tuple[int, str, Any]]:
        failures = 0
        where = f"{self.host}:{self.port}"
        while not self._stop.is_set():
            try:
                sock = socket.create_connection((self.host, self.port), timeout=self.connect_timeout_s)
            except OSError as e:
                failures += 1
                self._give_up_or_wait(f"cannot connect to the radar at {where} ({e.strerror or e})", failures)
                continue
            self._sock = sock
            self.counts["connections"] += 1
            if self.counts["connections"] > 1:
                self.counts["reconnects"] += 1
                self._gap = True
            beams_before = self.counts["beams"]
            try:
                yield from self._session(sock)
                return  # stopped
            except (_Dead, ProtocolError, OSError) as e:
                if self._stop.is_set():
                    return
                turn_beams = self.device_config.azimuth_samples if self.device_config else 1
                if self.counts["beams"] - beams_before >= turn_beams:
                    failures = 0  # a connection that gave a whole turn worked: a new loss starts a new count
                failures += 1
                why = e.strerror if isinstance(e, OSError) and e.strerror else str(e)
                self._give_up_or_wait(f"radar at {where}: {why}", failures)
            finally:
                self._sock = None
                self._close(sock)

    def _give_up_or_wait(self, why: str, failures: int) -> None:
        if self._stop.is_set():
            return
        if failures > self.reconnect_attempts:
            raise NavtechError(f"{why}; gave up after {failures} failed attempt(s) in a row "
                               f"(reconnect_attempts {self.reconnect_attempts})")
        wait_s = min(self.reconnect_backoff_max_s, self.reconnect_backoff_s * 2.0 ** (failures - 1))
        self.log.warning("%s: reconnecting in %.1f s (attempt %d of %d)", why, wait_s, failures,
                         self.reconnect_attempts)
        self._stop.wait(wait_s)

    def _close(self, sock: socket.socket) -> None:
        try:
            sock.settimeout(0.0)
            sock.send(encode_message(MessageType.STOP_FFT_DATA))  # best effort, never blocks
        except OSError:
            pass
        sock.close()

    def _session(self, sock: socket.socket) -> Iterator[tuple[int, str, Any]]:
        sock.settimeout(_POLL_S)
        dec = StreamDecoder(self.max_payload_bytes)
        t_connect = last_rx = time.monotonic()
        cfg: Configuration | None = None
        requested = False
        while not self._stop.is_set():
            try:
                data = sock.recv(_RECV_BYTES)
            except TimeoutError:
                now = time.monotonic()
                if now - last_rx > self.silence_timeout_s:
                    raise _Dead(f"no message for {now - last_rx:.1f} s (not even a keep-alive; silence_timeout_s "
                                f"{self.silence_timeout_s:g})") from None
                if cfg is None and not requested and now - t_connect > min(1.0, self.silence_timeout_s / 2):
                    sock.sendall(encode_message(MessageType.CONFIGURATION_REQUEST))
                    requested = True
                continue
            if not data:
                raise _Dead("connection closed by the radar")
            host_ns = self.now_ns()
            last_rx = time.monotonic()
            items: list[Any] = []
            for m in dec.feed(data):
                if m.type in (MessageType.FFT_DATA, MessageType.HIGH_PRECISION_FFT_DATA):
                    items.append(FftData.decode(m.payload, m.type == MessageType.HIGH_PRECISION_FFT_DATA))
                elif m.type == MessageType.CONFIGURATION:
                    items.append(Configuration.decode(m.payload))
                elif m.type == MessageType.KEEP_ALIVE:
                    self.counts["keepalives"] += 1
                else:
                    self.unknown_types[m.type] += 1
            # one clock observation per read: the newest beam of the bytes received at host_ns (its
            # delay is the smallest of them); every beam is then mapped on that line
            observed = False
            for it in items:
                if isinstance(it, Configuration):
                    first = cfg is None
                    cfg = self._configure(it)
                    if first:
                        sock.sendall(encode_message(MessageType.START_FFT_DATA))
                    continue
                if cfg is None:
                    self.counts["beams_dropped"] += 1  # data before any configuration: no geometry
                    continue
                if not observed:
                    newest = max(f.device_ns for f in items if isinstance(f, FftData))
                    self.clock.update(newest, host_ns)
                    observed = True
                item = self._beam(it, cfg)
                if item is not None:
                    yield item
            if dec.error is not None:
                raise dec.error

    def _configure(self, new: Configuration) -> Configuration:
        why = new.problem()
        if why:
            raise NavtechError(f"radar at {self.host}:{self.port}: configuration refused: {why}")
        old = self.device_config
        fields = ("azimuth_samples", "bin_size", "range_in_bins", "encoder_size", "rotation_speed_mhz",
                  "range_gain", "range_offset_m")
        if old is not None and any(getattr(old, f) != getattr(new, f) for f in fields):
            diff = ", ".join(f"{f} {getattr(old, f)} -> {getattr(new, f)}" for f in fields
                             if getattr(old, f) != getattr(new, f))
            raise NavtechError(f"radar at {self.host}:{self.port}: configuration changed mid-stream ({diff}): "
                               "the beams sent so far have the old geometry; restart the graph")
        if old is None:
            self.device_config = new
            self.clock = ClockSync(window_s=self.clock_window_s, step_threshold_ns=int(self.clock_step_ms * 1e6),
                                   confirm_count=self.clock_confirm_reads)
            self.config = navtech_config(
                self.sensor_name, new.range_in_bins, new.range_per_bin_m,
                range_offset_m=new.range_offset_m + self.range_offset_bins * new.range_per_bin_m,
                beams_per_turn=new.azimuth_samples, rotation_hz=new.rotation_hz)
        return self.device_config  # type: ignore[return-value]

    def _beam(self, fft: FftData, cfg: Configuration) -> tuple[int, str, Any] | None:
        values = fft.values()
        if fft.azimuth >= cfg.encoder_size or values.size != cfg.range_in_bins:
            self.counts["beams_dropped"] += 1
            if self.counts["beams_dropped"] == 1:
                self.log.warning("radar at %s:%d: beam dropped: azimuth %d (encoder size %d), %d samples "
                                 "(configuration: %d bins); further ones are counted in the summary",
                                 self.host, self.port, fft.azimuth, cfg.encoder_size, values.size, cfg.range_in_bins)
            return None
        n = cfg.azimuth_samples
        index = index_of_count(fft.azimuth, n, cfg.encoder_size)
        device_ns = fft.device_ns
        turn = self._turn(index, n, device_ns, cfg.rotation_hz)
        t = int(self.clock.to_mission_ns(device_ns))
        if t < self._last_t:  # the estimate moved back: never yield out of order
            self.counts["stamps_held"] += 1
            t = self._last_t
        self._last_t = t
        config = self.config
        beam = impala_msgs.RadarBeam(azimuth_of_count(fft.azimuth, cfg.encoder_size, self.azimuth_offset_deg),
                                     turn, index, beam_power(values, self.db_per_count, fft.high_precision),
                                     _NO_DOWN, config)
        self.counts["beams"] += 1
        return t, "beams", beam

    def _turn(self, index: int, n: int, device_ns: int, rotation_hz: float) -> int:
        """The beam's turn. Within a connection the encoder tells (index not after the last
        one's: the next turn): TCP loses nothing, and a device clock step changes no turn number
        (as the readers number a recording's scans, a scan missing from a log is no turn). After
        a reconnection, the turns elapsed by the device time (the position predicted from the
        last beam, rounded)."""
        last = self._last
        if last is None:
            turn = 0
            self.counts["turns"] += 1
        else:
            last_turn, last_index, last_ns = last
            wrap = 1 if index <= last_index else 0
            dt_s = (device_ns - last_ns) / 1e9
            if self._gap:
                predicted = last_turn + last_index / n + dt_s * rotation_hz - index / n
                turn = max(last_turn + wrap, int(math.floor(predicted + 0.5)))
            else:
                turn = last_turn + wrap
            missing = (turn - last_turn) * n + index - last_index - 1
            if missing > 0:
                self.counts["beams_missing"] += missing
                if self._gap or turn - last_turn > 1:
                    lost = max(0, turn - last_turn - 1)
                    self.counts["turns_lost"] += lost
                    line = (f"{missing} beam(s) lost ({lost} whole turn(s)) over {dt_s:.3f} s of device time, "
                            f"turn {last_turn} beam {last_index} to turn {turn} beam {index}")
                    self.lost_lines.append(line)
                    self.log.warning("radar at %s:%d: %s", self.host, self.port, line)
            if turn != last_turn:
                self.counts["turns"] += 1
        self._gap = False
        self._last = (turn, index, device_ns)
        return turn

