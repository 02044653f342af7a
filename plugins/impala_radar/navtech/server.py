"""The Navtech emulator: a recording served over the Colossus protocol (``impala-flow navtech-server``).

:class:`NavtechServer` serves a dataset folder (oxford, boreas, radiate: read by the plugin's
readers) or an imported mission (``radar/beams`` of an .mcap) as a Navtech radar would: the
configuration on connection, keep-alives to an idle client, and, once a client asks for FFT
data, one FFT message per beam at the recorded pace (``speed`` x real time) carrying the
recorded device time. At a ``speed`` other than 1 the radar is one turning ``speed`` times
faster, whose clock keeps real time: the device times are the recorded ones compressed by
``speed`` from the first (spacing / ``speed``) and the configuration's rotation rate is
``speed`` times the recorded one, so a client's clock mapping sees a real-time device clock (no
drift) and every turn's beams still span one rotation. One client at a time (the next one is
accepted when it leaves).

The device clock starts at the first start-FFT request and then runs on: a client that
reconnects (after ``drop_after_s`` cut its connection, say) gets the beams of the time it
comes back at; those due meanwhile are counted as ``beams_unsent``. ``jitter_ms`` delays each
send by a random 0..J ms (seeded; sends stay in order; device stamps unchanged), the network
jitter a live radar's stamps see. Without ``loop`` the server ends with the recording (the
client's connection closed); with it the recording restarts, its times shifted to run on.

Samples: the encoder count nearest the beam's azimuth (clockwise, :mod:`.convert`; for a
dataset folder the reader runs with no azimuth offset, so the counts are the recorded ones)
and the count (8-bit) or 16-bit value that gives the beam's power back (exactly, for real
Navtech scans). Boreas' chirp direction has no field in the protocol and is not sent.
"""

from __future__ import annotations

import select
import socket
import threading
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

import impala_msgs

from .convert import count_of_azimuth, counts_of_power
from .protocol import (
    DEFAULT_PORT,
    Configuration,
    FftData,
    MessageType,
    ProtocolError,
    StreamDecoder,
    encode_message,
)

__all__ = ["NavtechServer", "ServerError", "open_recording", "detect_format", "configuration_of", "serve_command"]

_POLL_S = 0.05
_TICK_S = 0.002  # send what is due at most this late (batches of beams)
_BATCH_BYTES = 1 << 20  # most bytes sent in one call
_SEND_TIMEOUT_S = 5.0  # a client that reads nothing this long is dropped
ENCODER_SIZE = 5600  # Navtech CTS350-X / CIR304-H


class ServerError(ValueError):
    """A source the emulator cannot serve (one line)."""


def detect_format(folder: Path) -> str:
    """Dataset format of a folder: RADIATE holds ``Navtech_Polar/``, Boreas ``applanix/``
    beside ``radar/``; any other folder with ``radar/`` is read as Oxford."""
    if (folder / "Navtech_Polar").is_dir():
        return "radiate"
    if (folder / "radar").is_dir():
        return "boreas" if (folder / "applanix").is_dir() else "oxford"
    raise ServerError(f"{folder}: no Navtech_Polar/ (radiate) nor radar/ (oxford, boreas) inside: not a dataset "
                      "folder (--format names one)")


def configuration_of(config: impala_msgs.RadarConfig, encoder_size: int = ENCODER_SIZE,
                     speed: float = 1.0) -> Configuration:
    """The Colossus configuration of a radar described by ``config`` (turning ``speed`` times
    faster): range per bin as ``bin_size`` (0.1 mm) x ``range_gain``, ``range_offset`` such that
    a client with bin centres (``range_offset_bins`` 0.5, the driver's default) gets
    ``config.range_offset_m`` back."""
    rpb = float(config.range_per_bin_m)
    bin_size = max(1, min(0xFFFF, int(round(rpb * 10_000.0))))
    return Configuration(
        azimuth_samples=int(config.beams_per_turn), bin_size=bin_size, range_in_bins=int(config.n_bins),
        encoder_size=int(encoder_size), rotation_speed_mhz=int(round(config.rotation_hz * speed * 1000.0)),
        packet_rate=int(round(config.beams_per_turn * config.rotation_hz * speed)),
        range_gain=rpb / (bin_size / 10_000.0),
        range_offset_m=round(float(config.range_offset_m) - 0.5 * rpb, 6) + 0.0)  # to the um, no -0


class _Recording:
    """A source's radar config and a factory of its ``(t_ns, RadarBeam)`` stream."""

    def __init__(self, what: str, config: impala_msgs.RadarConfig, beams: Any, offset_deg: float) -> None:
        self.what, self.config, self._beams, self.azimuth_offset_deg = what, config, beams, offset_deg

    def beams(self) -> Iterator[tuple[int, impala_msgs.RadarBeam]]:
        return self._beams()


def open_recording(source: str | Path, fmt: str | None = None, azimuth_offset_deg: float = 0.0) -> _Recording:
    """The beams of a dataset folder (``fmt`` or detected) or an imported mission (.mcap)."""
    path = Path(source)
    if path.is_dir():
        from ..datasets.common import DatasetError
        from ..datasets.component import DATASET_SOURCES

        fmt = fmt or detect_format(path)
        if fmt not in DATASET_SOURCES:
            raise ServerError(f"--format {fmt}: expected one of {', '.join(DATASET_SOURCES)}")

        def make() -> Any:
            # no azimuth offset: the beams' azimuths are the encoder's angle, the counts recorded
            return DATASET_SOURCES[fmt](fmt, folder=str(path), azimuth_offset_deg=0.0)

        try:
            first = make()
            first.open()
        except DatasetError as e:
            raise ServerError(str(e)) from None

        def beams() -> Iterator[tuple[int, impala_msgs.RadarBeam]]:
            src = make()
            src.open()
            for t, port, msg in src.generate():
                if port == "beams":
                    yield t, msg

        return _Recording(f"{fmt} folder {path}", first.dataset.config, beams, 0.0)
    if path.is_file():
        from impala_flow.io import CodecRegistry, MissionReader, RecordingError

        def reader() -> Any:
            from impala_flow.plugins import load_registry

            return MissionReader(path, CodecRegistry.from_plugins(load_registry()))

        try:
            with reader() as r:
                if "radar/beams" not in r.topics:
                    raise ServerError(f"{path}: no radar/beams topic (topics: {', '.join(r.topics) or 'none'})")
                first = next(iter(r.messages(["radar/beams"])), None)
        except RecordingError as e:
            raise ServerError(str(e)) from None
        if first is None:
            raise ServerError(f"{path}: radar/beams holds no beam")

        def mission_beams() -> Iterator[tuple[int, impala_msgs.RadarBeam]]:
            with reader() as r:
                for rec in r.messages(["radar/beams"]):
                    yield rec.t_ns, rec.data

        return _Recording(f"mission {path}", first.data.config, mission_beams, azimuth_offset_deg)
    raise ServerError(f"{path}: no such file or folder (a dataset folder or an imported .mcap mission)")


class NavtechServer:
    """Serve ``source`` (a dataset folder or a mission .mcap) on ``host:port`` (``port=0``: a
    free port, :attr:`port` after construction). ``start()`` runs it in a thread, ``stop()``
    ends it; also a context manager. ``counts`` says what was sent; ``finished`` is set when
    the recording is over (without ``loop``) or the server stopped."""

    def __init__(self, source: str | Path, host: str = "127.0.0.1", port: int = DEFAULT_PORT, *,
                 speed: float = 1.0, jitter_ms: float = 0.0, drop_after_s: float | None = None, loop: bool = False,
                 fmt: str | None = None, high_precision: bool = False, encoder_size: int = ENCODER_SIZE,
                 azimuth_offset_deg: float = 0.0, db_per_count: float = 0.5, keepalive_s: float = 1.0,
                 seed: int = 0) -> None:
        if not (speed > 0 and np.isfinite(speed)):
            raise ServerError(f"speed {speed}: expected a finite value > 0")
        if not (0 <= jitter_ms <= 10_000):
            raise ServerError(f"jitter {jitter_ms} ms: expected 0..10000 ms")
        if drop_after_s is not None and not drop_after_s > 0:
            raise ServerError(f"drop after {drop_after_s} s: expected a value > 0")
        if not 0 <= port <= 0xFFFF:
            raise ServerError(f"port {port}: expected 0..65535 (0: a free port)")
        if not 1 <= encoder_size <= 0xFFFF:
            raise ServerError(f"encoder size {encoder_size}: expected 1..65535")
        self.recording = open_recording(source, fmt, azimuth_offset_deg)
        self.config = configuration_of(self.recording.config, encoder_size, float(speed))
        why = self.config.problem()
        if why:
            raise ServerError(f"{source}: this radar cannot be described by a Navtech configuration: {why}")
        self.speed, self.jitter_ns = float(speed), int(jitter_ms * 1e6)
        self.drop_after_s, self.loop = drop_after_s, loop
        self.high_precision, self.db_per_count = high_precision, float(db_per_count)
        self.keepalive_s = keepalive_s
        self._rng = np.random.default_rng(seed)
        self.counts: Counter = Counter()
        self.finished = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None
        self._lsock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        try:
            self._lsock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            self._lsock.bind((host, port))
            self._lsock.listen(1)
        except OSError as e:
            self._lsock.close()
            raise ServerError(f"cannot listen on {host}:{port} ({e.strerror or e})") from None
        self._lsock.settimeout(_POLL_S)
        self.host, self.port = self._lsock.getsockname()[:2]

    # --- lifecycle ---------------------------------------------------------------------------
    def start(self) -> NavtechServer:
        self._thread = threading.Thread(target=self.serve, name="navtech-server", daemon=True)
        self._thread.start()
        return self

    def stop(self, timeout_s: float = 5.0) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout_s)
        self._lsock.close()

    def __enter__(self) -> NavtechServer:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # --- the stream ----------------------------------------------------------------------------
    def _messages(self) -> Iterator[tuple[int, bytes]]:
        """``(device t_ns, FFT message)`` of each beam, the recording restarted (times shifted)
        with ``loop``; device times compressed by ``speed`` from the first (the module doc)."""
        enc, offset = self.config.encoder_size, self.recording.azimuth_offset_deg
        shift, sweep = 0, 0
        t0: int | None = None
        period_ns = int(round(1e9 / (self.recording.config.rotation_hz * self.recording.config.beams_per_turn)))
        while True:
            first = last = None
            for t, beam in self.recording.beams():
                t += shift  # the recorded time, run on by the loops
                first = t if first is None else first
                last = t
                t0 = first if t0 is None else t0
                if self.speed != 1.0:  # a radar turning `speed` times faster, its clock at real time
                    t = t0 + int(round((t - t0) / self.speed))
                if t < 0:
                    raise ServerError(f"beam at t = {t} ns: a device time before 1970 cannot be sent")
                values, clipped = counts_of_power(beam.up, self.db_per_count, self.high_precision)
                self.counts["samples_clipped"] += clipped
                fft = FftData(sweep, count_of_azimuth(beam.azimuth_rad, enc, offset), t // 1_000_000_000,
                              t % 1_000_000_000, values.astype(">u2").tobytes() if self.high_precision
                              else values.tobytes(), self.high_precision)
                sweep = (sweep + 1) & 0xFFFF
                yield t, encode_message(fft.type, fft.encode())
            if not self.loop or first is None:
                return
            shift += last - first + period_ns
            self.counts["loops"] += 1

    def serve(self) -> None:
        """Run until stopped or (without ``loop``) the recording ends."""
        try:
            self._serve()
        except BaseException as e:  # kept for the caller (the thread would swallow it)
            self.error = e
            raise
        finally:
            self._drop("")
            self.finished.set()

    # client state (the server's thread only)
    _client: socket.socket | None = None
    _dec: StreamDecoder | None = None
    _streaming = False
    _conn_t0 = _last_tx = 0.0

    def _serve(self) -> None:
        messages = self._messages()
        clock0: tuple[int, float] | None = None  # (device t_ns, monotonic s) at the first start
        pending: tuple[float, int, bytes] | None = None  # (due, device t_ns, message)
        last_due = 0.0

        def pull() -> tuple[float, int, bytes] | None:
            nonlocal last_due
            item = next(messages, None)
            if item is None or clock0 is None:
                return None
            due = clock0[1] + (item[0] - clock0[0]) / 1e9  # device times run at real time (the module doc)
            if self.jitter_ns:
                due += float(self._rng.integers(0, self.jitter_ns + 1)) / 1e9
            last_due = due = max(due, last_due)  # sends stay in order
            return due, item[0], item[1]

        while not self._stop.is_set():
            if self._client is None:
                if not self._accept():
                    return  # the listening socket was closed
                started = False
            else:
                started = self._serve_client(_POLL_S if clock0 is None else _TICK_S)
            if started and clock0 is None:
                first = next(messages, None)
                if first is None:
                    return
                clock0 = (first[0], time.monotonic())
                pending = (clock0[1], first[0], first[1])
            if clock0 is None:
                continue
            pending = self._send_due(pending, pull)
            if pending is None:  # the recording is over: refuse new clients at once
                self.counts["finished"] = 1
                self._lsock.close()
                return

    def _accept(self) -> bool:
        try:
            client, _ = self._lsock.accept()
        except TimeoutError:
            return True
        except OSError:
            return False
        client.settimeout(_SEND_TIMEOUT_S)
        client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._client, self._dec, self._streaming = client, StreamDecoder(4096), False
        self._conn_t0 = time.monotonic()
        self.counts["connections"] += 1
        self._send_config()
        return True

    def _drop(self, why: str) -> None:
        if self._client is not None:
            self._client.close()
            if why:
                self.counts[why] += 1
        self._client, self._dec, self._streaming = None, None, False

    def _send(self, data: bytes | bytearray) -> bool:
        """Send to the client; a client gone or not reading for 5 s is dropped (False)."""
        if self._client is None:
            return False
        try:
            self._client.sendall(data)
        except OSError:
            self._drop("clients_lost")
            return False
        self._last_tx = time.monotonic()
        return True

    def _send_config(self) -> None:
        if self._send(encode_message(MessageType.CONFIGURATION, self.config.encode())):
            self.counts["configurations"] += 1

    def _serve_client(self, wait_s: float) -> bool:
        """Read the client's requests (waiting up to ``wait_s``), cut it after
        ``drop_after_s``, keep an idle one alive; True if it asked for FFT data."""
        started = False
        client = self._client
        assert client is not None and self._dec is not None
        readable, _, _ = select.select([client], [], [], wait_s)
        if readable:
            try:
                data = client.recv(4096)
            except OSError:
                data = b""
            if not data:
                self._drop("clients_left")
                return False
            try:
                requests = self._dec.feed(data)
            except ProtocolError:
                self._drop("clients_refused")  # bytes that are no Colossus message
                return False
            for m in requests:
                if m.type == MessageType.START_FFT_DATA:
                    self._streaming = started = True
                elif m.type == MessageType.STOP_FFT_DATA:
                    self._streaming = False
                elif m.type == MessageType.CONFIGURATION_REQUEST:
                    self._send_config()
        now = time.monotonic()
        if self._client is not None and self.drop_after_s is not None and now - self._conn_t0 >= self.drop_after_s:
            self._drop("connections_cut")
        elif self._client is not None and not self._streaming and now - self._last_tx >= self.keepalive_s:
            if self._send(encode_message(MessageType.KEEP_ALIVE)):
                self.counts["keepalives"] += 1
        return started

    def _send_due(self, pending: tuple[float, int, bytes] | None,
                  pull: Any) -> tuple[float, int, bytes] | None:
        """Send (or, with no client streaming, skip) every beam due now; the next one."""
        now = time.monotonic()
        batch = bytearray()
        n = 0
        streaming = self._client is not None and self._streaming
        while pending is not None and pending[0] <= now and len(batch) < _BATCH_BYTES:
            if streaming:
                batch += pending[2]
                n += 1
            else:
                self.counts["beams_unsent"] += 1
            pending = pull()
        if batch and self._send(batch):
            self.counts["fft_messages"] += n
            self.counts["bytes"] += len(batch)
        elif batch:
            self.counts["beams_unsent"] += n
        return pending


def serve_command(args: Any) -> int:
    """``impala-flow navtech-server``: serve until the recording ends (no ``--loop``) or Ctrl-C."""
    import signal
    import sys

    from impala_flow.cli import EXIT_USAGE, CommandError

    try:
        server = NavtechServer(args.source, args.host, args.port, speed=args.speed, jitter_ms=args.jitter_ms,
                               drop_after_s=args.drop_after, loop=args.loop, fmt=args.format,
                               high_precision=args.high_precision, azimuth_offset_deg=args.azimuth_offset_deg,
                               db_per_count=args.db_per_count, seed=args.seed)
    except ServerError as e:
        raise CommandError(str(e), EXIT_USAGE) from None
    c, cfg = server.recording.config, server.config
    print(f"serving:      {server.recording.what}")
    print(f"radar:        {cfg.azimuth_samples} azimuths/turn at {cfg.rotation_speed_mhz / 1000:.3f} Hz, "
          f"{cfg.range_in_bins} bins x {c.range_per_bin_m:.5f} m, encoder {cfg.encoder_size} counts, "
          f"{'16' if server.high_precision else '8'}-bit FFT data")
    print(f"listening:    {server.host}:{server.port}", flush=True)
    stop = threading.Event()
    previous = {sig: signal.signal(sig, lambda *_: stop.set()) for sig in (signal.SIGINT, signal.SIGTERM)}
    server.start()
    try:
        while not server.finished.wait(0.2) and not stop.is_set():
            pass
    finally:
        server.stop()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if stop.is_set():
        print("stopped:      interrupted (Ctrl-C or SIGTERM)", file=sys.stderr)
    n = server.counts
    print(f"sent:         {n['fft_messages']} FFT messages ({n['bytes'] / 1e6:.1f} MB), {n['keepalives']} "
          f"keep-alives, {n['configurations']} configurations; {n['connections']} connection(s), "
          f"{n['connections_cut']} cut (--drop-after), {n['beams_unsent']} beams due with no client streaming"
          + (f", {n['loops']} loop(s)" if n["loops"] else "")
          + (f", {n['samples_clipped']} samples clipped to the sample range" if n["samples_clipped"] else ""))
    if server.error is not None:
        raise CommandError(f"navtech-server: {server.error}")
    return 0
