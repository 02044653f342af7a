"""radar.NavtechRadar against the emulator on loopback, under the real-time executor as a graph
runs it: the beams equal the direct import's (real Oxford and RADIATE scans), 8- and 16-bit;
a cut connection is survived and its loss reported; the emulator's command."""

from __future__ import annotations

import logging
import os
import re
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

from impala_flow._network import Network
from impala_flow._realtime import RealTimeExecutor
from impala_flow.io import CodecRegistry, MissionReader
from impala_flow.plugins import load_registry
from impala_flow.testing import CollectingSink, connect
from impala_radar.datasets.component import DATASET_SOURCES
from impala_radar.navtech.component import NavtechRadar
from impala_radar.navtech.server import NavtechServer

from ._dataset_files import navtech_folder

DATA = Path(os.environ.get("IMPALA_FLOW_TEST_DATA", "/nonexistent"))
OXFORD = DATA / "oxford-radar-robotcar-sample"
FOG = DATA / "radiate-fog-6-0-head"
HANG_S = 120.0  # only to turn a hang into a failure


def need(folder: Path) -> Path:
    if not folder.is_dir():
        pytest.skip(f"test data {folder} absent (IMPALA_FLOW_TEST_DATA)")
    return folder


def direct(fmt: str, folder: Path, **params: Any) -> list[tuple[int, Any]]:
    """The beams of the direct import (the dataset source as a graph reads it)."""
    src = DATASET_SOURCES[fmt](fmt, folder=str(folder), **params)
    src.start()
    return [(t, b) for t, port, b in src.generate() if port == "beams"]


def live(server: NavtechServer, n_turns: int, **params: Any) -> tuple[list[int], list[Any], NavtechRadar, Any]:
    """Run NavtechRadar -> sink on the real-time executor (a user's graph) until a beam of turn
    ``n_turns`` arrives (the server loops: the recording's turns are 0..n_turns-1), then stop the
    run as Ctrl-C does; the stamps and beams of turns < ``n_turns``, the driver and the run summary."""
    radar = NavtechRadar("radar", port=server.port, **params)
    sink = CollectingSink("sink")
    net = Network(name="navtech-live")
    net.add(radar)
    net.add(sink)
    connect(net, "radar.beams -> sink.x")
    ex = RealTimeExecutor(net)
    box: dict[str, Any] = {}

    def run() -> None:
        try:
            box["summary"] = ex.run()
        except BaseException as e:  # re-raised in the test's thread
            box["error"] = e

    th = threading.Thread(target=run, daemon=True)
    th.start()
    deadline = time.monotonic() + HANG_S
    while time.monotonic() < deadline and th.is_alive():
        samples = getattr(sink, "samples", [])
        if samples and samples[-1].data.turn >= n_turns:
            break
        time.sleep(0.05)
    ex.stop_event.set()
    th.join(30)
    assert not th.is_alive(), "the real-time run did not stop"
    if "error" in box:
        raise box["error"]
    assert server.error is None
    kept = [s for s in sink.samples if s.data.turn < n_turns]
    assert len(kept) < len(sink.samples), "the run stopped before the recording was served"
    return [s.timestamp for s in kept], [s.data for s in kept], radar, box["summary"]


def turns(ref: list[tuple[int, Any]]) -> int:
    return ref[-1][1].turn + 1


def assert_same_beams(times: list[int], beams: list[Any], ref: list[tuple[int, Any]], exact_azimuth: bool) -> None:
    assert len(beams) == len(ref)
    ref_t = np.array([t for t, _ in ref], dtype=np.int64)
    for b, (_, r) in zip(beams, ref, strict=True):
        assert (b.turn, b.index) == (r.turn, r.index)
        assert b.up.dtype == r.up.dtype and np.array_equal(b.up, r.up)
        if exact_azimuth:
            assert b.azimuth_rad == r.azimuth_rad
        else:  # within one encoder count (2 pi / 5600)
            d = (b.azimuth_rad - r.azimuth_rad + np.pi) % (2 * np.pi) - np.pi
            assert abs(d) <= np.pi / 5600
    spacing_err_ns = np.abs(np.diff(np.array(times, dtype=np.int64)) - np.diff(ref_t))
    assert spacing_err_ns.max() < 1_000_000, f"stamp spacing off by {spacing_err_ns.max() / 1e6:.3f} ms"
    c, rc = beams[0].config, ref[0][1].config
    assert (c.n_bins, c.beams_per_turn, c.doppler) == (rc.n_bins, rc.beams_per_turn, False)
    assert c.rotation_hz == pytest.approx(rc.rotation_hz, abs=5e-4)  # the protocol's mHz
    assert c.range_per_bin_m == pytest.approx(rc.range_per_bin_m, rel=1e-6)  # float32 range gain
    assert c.range_offset_m == pytest.approx(rc.range_offset_m, abs=1e-6)


def test_oxford_live_equals_the_import():
    folder = need(OXFORD)
    ref = direct("oxford", folder)  # azimuth offset -0.95 deg, bin centres, 0.5 dB per count
    with NavtechServer(folder, port=0, loop=True) as server:
        times, beams, radar, summary = live(server, turns(ref), azimuth_offset_deg=-0.95)
    assert server.counts["samples_clipped"] == 0 and server.counts["loops"] >= 1
    assert_same_beams(times, beams, ref, exact_azimuth=True)
    s = radar.summary()
    assert s["beams"] > len(ref) and s["reconnects"] == 0 and s["beams_missing"] == 0
    assert 0 < s["clock"]["observations"] <= s["beams"]  # one per read of the socket


def test_radiate_live_equals_the_import_16_bit():
    folder = need(FOG)
    ref = direct("radiate", folder)  # azimuth offset -2.3 deg
    with NavtechServer(folder, port=0, high_precision=True, loop=True) as server:
        times, beams, _, _ = live(server, turns(ref), azimuth_offset_deg=-2.3)
    assert server.counts["samples_clipped"] == 0
    assert_same_beams(times, beams, ref, exact_azimuth=False)


def test_network_jitter_20_ms_keeps_the_device_spacing():
    """Sends delayed by a random 0-20 ms: the stamps still keep the device's spacing within 1 ms."""
    folder = need(FOG)
    ref = direct("radiate", folder)
    with NavtechServer(folder, port=0, jitter_ms=20.0, loop=True) as server:
        times, beams, radar, _ = live(server, turns(ref), azimuth_offset_deg=-2.3)
    assert_same_beams(times, beams, ref, exact_azimuth=False)
    clock = radar.summary()["clock"]
    assert clock["steps"] == 0 and clock["observations"] > 0


def test_an_imported_mission_served_gives_its_beams(tmp_path):
    """``impala-flow import`` then the emulator on the .mcap: the recorded beams come back."""
    folder = need(FOG)
    mission = tmp_path / "fog.mcap"
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    subprocess.run([sys.executable, "-m", "impala_flow", "import", "radiate", str(folder), "-o", str(mission),
                    "--no-progress"], check=True, capture_output=True, env=env, timeout=300)
    with MissionReader(mission, CodecRegistry.from_plugins(load_registry())) as r:
        ref = [(m.t_ns, m.data) for m in r.messages(["radar/beams"])]
    # the import added RADIATE's -2.3 deg: the emulator takes it off, the driver puts it back
    with NavtechServer(mission, port=0, loop=True, azimuth_offset_deg=-2.3) as server:
        times, beams, _, _ = live(server, turns(ref), azimuth_offset_deg=-2.3)
    assert_same_beams(times, beams, ref, exact_azimuth=False)


def test_synthetic_8_bit_every_count(tmp_path):
    """Every count 0..255 through the 8-bit path gives the import's power (synthetic scans)."""
    navtech_folder(tmp_path / "ox", n_scans=3, n_bins=256)
    ref = direct("oxford", tmp_path / "ox", azimuth_offset_deg=0.0)
    with NavtechServer(tmp_path / "ox", port=0, loop=True) as server:
        times, beams, _, _ = live(server, turns(ref))
    assert_same_beams(times, beams, ref, exact_azimuth=True)


def test_cut_connection_is_survived_and_the_loss_reported(caplog):
    folder = need(OXFORD)
    ref = direct("oxford", folder)
    by_key = {(b.turn, b.index): b for _, b in ref}
    with caplog.at_level(logging.WARNING), NavtechServer(folder, port=0, drop_after_s=0.8, loop=True) as server:
        _, beams, radar, _ = live(server, turns(ref), azimuth_offset_deg=-0.95, reconnect_backoff_s=0.1)
    s = radar.summary()
    assert server.counts["connections_cut"] >= 2 and s["reconnects"] >= 2
    # every beam received is the import's beam of the same turn and index (turns counted across the gaps)
    for b in beams:
        r = by_key[(b.turn, b.index)]
        assert np.array_equal(b.up, r.up) and b.azimuth_rad == r.azimuth_rad
    # the driver's count of the beams lost: received + lost = every azimuth up to the last one received
    last_turn, last_index, _ = radar._last
    assert s["beams"] + s["beams_missing"] == last_turn * 400 + last_index + 1
    assert 0 < len(ref) - len(beams) <= s["beams_missing"]
    assert s["gaps"] and "beam(s) lost" in s["gaps"]
    lines = [r.getMessage() for r in caplog.records if r.name.endswith("radar")]
    assert any("connection closed by the radar" in m and "reconnecting in" in m for m in lines)
    assert any("beam(s) lost" in m for m in lines)
    assert all("\n" not in m for m in lines)


def test_the_command_serves_and_stops_cleanly():
    folder = need(FOG)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    proc = subprocess.Popen([sys.executable, "-m", "impala_flow", "navtech-server", str(folder), "--port", "0"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    try:
        port = None
        for _ in range(3):
            line = proc.stdout.readline()
            m = re.match(r"listening:\s+127\.0\.0\.1:(\d+)", line)
            if m:
                port = int(m.group(1))
                break
        assert port, "no 'listening:' line"
        radar = NavtechRadar("radar", port=port)
        radar.start()
        got = []
        for _, _, beam in radar.generate():
            got.append(beam)
            if len(got) == 500:
                break
        radar.stop()
        assert [b.index for b in got[:400]] == list(range(400)) and got[400].turn == 1
        proc.send_signal(2)  # Ctrl-C
        out, err = proc.communicate(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert re.search(r"sent:\s+\d+ FFT messages", out) and "interrupted" in err


def test_the_emulator_speaks_the_protocol(tmp_path):
    """Byte level, a plain socket as the client: configuration on connection, keep-alives while
    idle, then FFT data with the recorded encoder counts, device times and counts."""
    paths = navtech_folder(tmp_path / "ox", n_scans=2, n_bins=16)
    img = np.asarray(Image.open(paths[0]))  # row k: time (us), encoder count, flag, 16 counts
    with NavtechServer(tmp_path / "ox", port=0, keepalive_s=0.3) as server, \
            socket.create_connection(("127.0.0.1", server.port), timeout=10) as sock:
        def read(n: int) -> bytes:
            out = b""
            while len(out) < n:
                chunk = sock.recv(n - len(out))
                assert chunk, "the emulator closed the connection"
                out += chunk
            return out

        def message() -> tuple[int, bytes]:
            head = read(22)
            assert head[:16] == bytes.fromhex("00 01 03 03 07 07 0F 0F 1F 1F 3F 3F 7F 7F FE FE") and head[16] == 1
            return head[17], read(int.from_bytes(head[18:22], "big"))

        t, payload = message()
        assert t == 10
        # 400 azimuths, 438 x 0.1 mm (4.38 cm), 16 bins, 5600 counts, rotation in mHz: 1 / (400 x 625 us) = 4 Hz
        assert [int.from_bytes(payload[i:i + 2], "big") for i in range(0, 12, 2)] == [400, 438, 16, 5600, 4000, 1600]
        assert [message()[0] for _ in range(2)] == [1, 1]  # keep-alives to an idle client
        sock.sendall(bytes.fromhex("00 01 03 03 07 07 0F 0F 1F 1F 3F 3F 7F 7F FE FE") + bytes([1, 21, 0, 0, 0, 0]))
        t, payload = message()
        while t == 1:  # a keep-alive sent before the request arrived
            t, payload = message()
        for k in range(3):
            if k:
                t, payload = message()
            assert t == 30 and int.from_bytes(payload[:2], "big") == 14
            assert int.from_bytes(payload[4:6], "big") == 7 + 14 * k  # the encoder count of row k
            t_us = 1_700_000_000_000_000 + 625 * k
            assert int.from_bytes(payload[6:10], "little") == t_us // 1_000_000
            assert int.from_bytes(payload[10:14], "little") == (t_us % 1_000_000) * 1000
            assert payload[14:] == img[k, 11:].tobytes()  # the PNG's pixels: the radar's counts


@pytest.mark.parametrize("args, line", [
    (["/nonexistent"], "/nonexistent: no such file or folder"),
    (["{tmp}"], "no Navtech_Polar/ (radiate) nor radar/ (oxford, boreas) inside"),
    (["{synthetic}", "--speed", "0"], "speed 0.0: expected a finite value > 0"),
    (["{synthetic}", "--port", "70000"], "port 70000: expected 0..65535"),
    (["{synthetic}", "--jitter-ms", "-1"], "jitter -1.0 ms: expected 0..10000 ms"),
])
def test_the_command_refuses_bad_input_in_one_line(tmp_path, capsys, args, line):
    from impala_flow.cli import main

    navtech_folder(tmp_path / "ox", n_scans=1, n_bins=8)
    argv = [a.format(tmp=tmp_path / "empty", synthetic=tmp_path / "ox") for a in args]
    (tmp_path / "empty").mkdir()
    assert main(["navtech-server", *argv]) == 2
    err = capsys.readouterr().err.strip()
    assert line in err and "\n" not in err
