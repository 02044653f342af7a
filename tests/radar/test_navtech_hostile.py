"""radar.NavtechRadar against broken or hostile peers (a tiny fake radar per test, bytes written
from the SDK's layout): one clear line each, a clean reconnect or stop, never a hang."""

from __future__ import annotations

import logging
import socket
import struct
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from impala_radar.navtech.component import NavtechError, NavtechRadar

SIG = bytes.fromhex("00 01 03 03 07 07 0F 0F 1F 1F 3F 3F 7F 7F FE FE")
HANG_S = 30.0


def msg(t: int, payload: bytes = b"") -> bytes:
    return SIG + bytes([1, t]) + len(payload).to_bytes(4, "big") + payload


def config(azimuths: int = 8, bins: int = 4, encoder: int = 5600) -> bytes:
    # azimuth_samples, bin_size (0.1 mm), range_in_bins, encoder_size, rotation (mHz), packet rate; gain, offset
    return msg(10, struct.pack(">6H", azimuths, 438, bins, encoder, 4000, azimuths * 4) + struct.pack(">2f", 1.0, 0.0))


def fft(k: int, azimuths: int = 8, bins: int = 4, t0_s: int = 1_700_000_000) -> bytes:
    """Azimuth k of a turn: encoder count k x 5600 / azimuths, 1/(4 azimuths) s apart."""
    t_ns = k * 250_000_000 // azimuths
    head = struct.pack(">3H", 14, k & 0xFFFF, (k % azimuths) * 5600 // azimuths)
    return msg(30, head + struct.pack("<2I", t0_s + t_ns // 10**9, t_ns % 10**9) + bytes([k % 256] * bins))


class FakeRadar:
    """Accepts connections on loopback; ``script(conn, n)`` plays the n-th one (0-based)."""

    def __init__(self, script: Callable[[socket.socket, int], None]) -> None:
        self.lsock = socket.create_server(("127.0.0.1", 0))
        self.lsock.settimeout(0.2)
        self.port = self.lsock.getsockname()[1]
        self.script, self.stop, self.connections, self.received = script, threading.Event(), 0, bytearray()
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self) -> None:
        while not self.stop.is_set():
            try:
                conn, _ = self.lsock.accept()
            except TimeoutError:
                continue
            except OSError:
                return
            n, self.connections = self.connections, self.connections + 1
            threading.Thread(target=self.play, args=(conn, n), daemon=True).start()

    def play(self, conn: socket.socket, n: int) -> None:
        with conn:
            try:
                self.script(conn, n)
            except OSError:
                pass

    def close(self) -> None:
        self.stop.set()
        self.thread.join(5)
        self.lsock.close()


def drive(port: int, **params: Any) -> tuple[list[Any], BaseException | None, NavtechRadar]:
    """Iterate the driver's generate() in a thread until it ends (or HANG_S: a failure)."""
    radar = NavtechRadar("radar", port=port, reconnect_backoff_s=0.05, **params)
    radar.start()
    box: dict[str, Any] = {"beams": []}

    def run() -> None:
        try:
            for _, _, beam in radar.generate():
                box["beams"].append(beam)
        except BaseException as e:  # handed to the test
            box["error"] = e

    th = threading.Thread(target=run, daemon=True)
    th.start()
    th.join(HANG_S)
    hung = th.is_alive()
    radar.stop()
    th.join(5)
    assert not hung, "the driver hung"
    return box["beams"], box.get("error"), radar


def warnings(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.name.endswith("radar") and r.levelno >= logging.WARNING]


def test_short_reads_give_whole_beams():
    """The radar's bytes one at a time (the SDK's Python client reads a payload with one recv)."""
    def script(conn: socket.socket, n: int) -> None:
        data = config() + b"".join(fft(k) for k in range(20))
        for i in range(len(data)):
            conn.sendall(data[i:i + 1])
        conn.recv(64)  # the start request came; then the stream ends

    radar = FakeRadar(script)
    try:
        beams, err, drv = drive(radar.port, reconnect_attempts=0)
    finally:
        radar.close()
    assert isinstance(err, NavtechError) and "gave up after 1 failed attempt" in str(err)
    assert [(b.turn, b.index) for b in beams] == [(k // 8, k % 8) for k in range(20)]
    # sample k is count k: 0.5 dB per count, linear power 10^(k 0.5 / 10) as float32
    assert [b.up.tolist() for b in beams] == [[float(np.float32(10.0 ** (k * 0.5 / 10.0)))] * 4 for k in range(20)]
    assert drv.summary()["beams_missing"] == 0


@pytest.mark.parametrize("case, bad, line", [
    ("bad signature", b"\xde\xad" * 11, "bad signature at byte"),
    ("payload over the bound", SIG + bytes([1, 30]) + (2_000_000).to_bytes(4, "big"),
     "fft_data (30) message at byte"),
    ("another version", SIG + bytes([7, 1]) + bytes(4), "version 7, expected 1"),
])
def test_broken_bytes_one_line_then_reconnect_then_stop(caplog, case, bad, line):
    def script(conn: socket.socket, n: int) -> None:
        conn.sendall(config() + b"".join(fft(k) for k in range(3)) + bad + bytes(100))
        time.sleep(0.3)

    radar = FakeRadar(script)
    with caplog.at_level(logging.WARNING):
        try:
            beams, err, drv = drive(radar.port, reconnect_attempts=2)
        finally:
            radar.close()
    assert len(beams) == 9 and radar.connections == 3  # 3 beams per connection, then the bad bytes
    assert isinstance(err, NavtechError) and line in str(err) and "gave up after 3" in str(err)
    lines = warnings(caplog)
    assert sum(line in m for m in lines) == 2 and all("\n" not in m for m in lines)  # one line per failure
    assert drv.summary()["reconnects"] == 2


def test_a_configuration_change_mid_stream_stops_with_one_line():
    def script(conn: socket.socket, n: int) -> None:
        conn.sendall(config() + fft(0) + fft(1) + config(bins=6))
        time.sleep(0.5)

    radar = FakeRadar(script)
    try:
        beams, err, _ = drive(radar.port)
    finally:
        radar.close()
    assert len(beams) == 2 and radar.connections == 1
    assert isinstance(err, NavtechError)
    assert "configuration changed mid-stream (range_in_bins 4 -> 6)" in str(err) and "\n" not in str(err)


def test_silence_past_the_keepalive_period_reconnects_and_stop_is_prompt(caplog):
    def script(conn: socket.socket, n: int) -> None:
        if n == 0:
            conn.sendall(config() + fft(0))
        time.sleep(3)  # then nothing at all (a second connection: nothing at all)

    radar = FakeRadar(script)
    with caplog.at_level(logging.WARNING):
        try:
            beams, err, _ = drive(radar.port, silence_timeout_s=0.5, reconnect_attempts=1)
        finally:
            radar.close()
    assert len(beams) == 1 and isinstance(err, NavtechError) and "no message for" in str(err)
    assert any("not even a keep-alive" in m for m in warnings(caplog))

    # stop() ends a driver waiting on a silent radar within one poll
    radar = FakeRadar(script)
    drv = NavtechRadar("radar", port=radar.port, silence_timeout_s=60.0)
    drv.start()
    done = threading.Event()

    def run() -> None:
        for _ in drv.generate():
            pass
        done.set()

    th = threading.Thread(target=run, daemon=True)
    th.start()
    time.sleep(0.5)
    drv.stop()
    try:
        assert done.wait(5.0), "generate() did not leave after stop()"
    finally:
        radar.close()


def test_keepalives_are_counted_and_a_config_is_asked_for():
    """A radar that sends only keep-alives until asked for its configuration."""
    def script(conn: socket.socket, n: int) -> None:
        conn.settimeout(5)
        conn.sendall(msg(1))
        got = conn.recv(64)
        assert got == SIG + bytes([1, 20]) + bytes(4)  # configuration request
        conn.sendall(msg(1) + config())
        assert conn.recv(64) == SIG + bytes([1, 21]) + bytes(4)  # start FFT data
        conn.sendall(fft(0) + msg(1) + msg(99, b"xyz") + fft(1))
        time.sleep(0.3)

    radar = FakeRadar(script)
    try:
        beams, err, drv = drive(radar.port, reconnect_attempts=0)
    finally:
        radar.close()
    s = drv.summary()
    assert len(beams) == 2 and s["keepalives"] == 3 and s["messages_ignored"] == {99: 1}
    assert isinstance(err, NavtechError)


def test_refused_connection_gives_up_after_the_attempts(caplog):
    with socket.create_server(("127.0.0.1", 0)) as s:
        port = s.getsockname()[1]  # closed below: nothing listens there
    with caplog.at_level(logging.WARNING):
        _, err, drv = drive(port, reconnect_attempts=3)
    assert isinstance(err, NavtechError) and f"cannot connect to the radar at 127.0.0.1:{port}" in str(err)
    assert len(warnings(caplog)) == 3 and drv.summary()["connections"] == 0


def test_a_device_clock_step_is_detected_and_changes_no_turn():
    """The radar's clock jumps 2 s forward mid-stream, the azimuths running on: the clock
    estimator reports a step of that size; no beam is taken for lost, the turns count on."""
    def script(conn: socket.socket, n: int) -> None:
        conn.settimeout(5)
        conn.sendall(config())
        conn.recv(64)  # start FFT data
        t0 = time.monotonic()
        for k in range(80):  # 8 azimuths per turn at 4 Hz: one every 31.25 ms, paced
            time.sleep(max(0.0, t0 + k / 32 - time.monotonic()))
            conn.sendall(fft(k, t0_s=1_700_000_000 + (2 if k >= 48 else 0)))
        time.sleep(0.3)

    radar = FakeRadar(script)
    try:
        # forward steps are looked for once the estimate has settled (clock_confirm_reads observations,
        # one per read: here one per beam, 48 before the step)
        beams, err, drv = drive(radar.port, reconnect_attempts=0, clock_confirm_reads=16)
    finally:
        radar.close()
    s = drv.summary()
    assert [(b.turn, b.index) for b in beams] == [(k // 8, k % 8) for k in range(80)]
    assert s["beams_missing"] == 0 and s["turns_lost"] == 0 and s["clock"]["steps"] == 1
    step = s["clock"]["step_events"][0]
    assert abs(step["size_ns"] - 2_000_000_000) < 100_000_000
