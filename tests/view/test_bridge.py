"""view.FoxgloveBridge and `impala-flow view`: a real WebSocket client speaking Foxglove's
protocol receives serverInfo and advertise, subscribes, and decodes the binary messages
against the recording they came from. The client offers both subprotocols the Foxglove app
offers: foxglove-sdk >= 0.30 answers foxglove.sdk.v1, the successor of foxglove.websocket.v1
(same ops and binary framing)."""

from __future__ import annotations

import json
import re
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from websockets.sync.client import connect

from impala_flow import msgs
from impala_flow.cli import main
from impala_flow.io import MissionReader, MissionWriter, run_codecs
from impala_view.bridge import to_json

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
CLI = [sys.executable, "-c", "import sys; from impala_flow.cli import main; sys.exit(main())"]


@pytest.fixture(scope="module")
def mission(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("view") / "m.mcap"
    assert main(["simulate", "beynes", "-o", str(path), "--duration", "8s", "--no-progress"]) == 0
    return path


GRID_BYTES = 1024 * 1024 * 4  # a 1024 x 1024 float32 map: 4 MiB of cells per message
MiB = 1 << 20


@pytest.fixture(scope="module")
def grids(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """20 maps of 4 MiB at 10 Hz, each with a tick (its index) at the same time (a small stream
    a well-behaved client reads to know how far the view has gone)."""
    path = tmp_path_factory.mktemp("view") / "grids.mcap"
    grid = msgs.Grid(np.zeros((1024, 1024), np.float32), 0.1, 0.0, 0.0)
    with MissionWriter(path, codecs=run_codecs(), foxglove=False) as w:
        w.add_topic("map/grid", msgs.Grid)
        w.add_topic("tick", int)
        for k in range(20):
            w.write("map/grid", 10**9 + k * 10**8, grid)
            w.write("tick", 10**9 + k * 10**8, k)
    return path


def _lost(text: str, prefix: str) -> dict[tuple[str, str], int]:
    """The summary's 'LOST at view.X: n kind, m kind' lines: {(X, kind): n}."""
    out = {}
    for what, rest in re.findall(r"LOST at " + re.escape(prefix) + r"(\S+): (.*)", text):
        for n, kind in re.findall(r"(\d+) ([^,]+)", rest):
            out[(what, kind.strip())] = int(n)
    return out


def _rss_bytes(pid: int) -> int:
    with open(f"/proc/{pid}/status") as f:
        return next(int(line.split()[1]) * 1024 for line in f if line.startswith("VmRSS:"))


def _client(port: int, **kw):
    return connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS, ping_interval=None, compression=None,
                   open_timeout=60, **kw)


def _start_view(mission: Path, *extra: str) -> tuple[subprocess.Popen, int, list[str]]:
    p = subprocess.Popen([*CLI, "view", str(mission), "--port", "0", "--no-progress", *extra],
                         stderr=subprocess.PIPE, text=True)
    _STARTED.append(p)
    lines: list[str] = []
    assert p.stderr is not None
    for line in p.stderr:
        lines.append(line)
        m = re.search(r"ws://127\.0\.0\.1:(\d+)", line)
        if m:
            rest = threading.Thread(target=lambda: lines.extend(p.stderr), daemon=True)  # keep draining
            rest.start()
            return p, int(m.group(1)), lines
    raise AssertionError("".join(lines))


_STARTED: list[subprocess.Popen] = []


@pytest.fixture(autouse=True)
def _reap():
    yield
    while _STARTED:
        p = _STARTED.pop()
        if p.poll() is None:
            p.kill()
        p.wait(timeout=30)
        if p.stderr is not None:
            p.stderr.close()


def _advertised(ws, wanted: set[str], timeout_s: float = 30.0) -> tuple[dict, dict[str, dict]]:
    info, channels = None, {}
    while info is None or not wanted <= set(channels):
        msg = json.loads(ws.recv(timeout=timeout_s))
        if msg["op"] == "serverInfo":
            info = msg
        elif msg["op"] == "advertise":
            channels.update({c["topic"]: c for c in msg["channels"]})
    return info, channels


def _subscribe(ws, subscriptions: dict[int, dict]) -> None:
    """Subscribes {subscription id: advertised channel}. The SDK records a channel as advertised to
    a client just after sending the advertisement: a subscription sent back at once may find it
    unknown; 0.2 s later it never does."""
    time.sleep(0.2)
    ws.send(json.dumps({"op": "subscribe", "subscriptions": [
        {"id": i, "channelId": c["id"]} for i, c in subscriptions.items()]}))


def test_view_serves_the_recording_in_foxglove_schemas_and_json(mission: Path) -> None:
    p, port, lines = _start_view(mission, "--speed", "1")
    try:
        with connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS) as ws:
            assert ws.subprotocol in SUBPROTOCOLS
            info, ch = _advertised(ws, {"gps/pose", "odometer/speed"})
            assert info["name"] == "impala-flow"
            assert ch["gps/pose"]["encoding"] == "protobuf" and ch["gps/pose"]["schemaName"] == "foxglove.PoseInFrame"
            assert ch["odometer/speed"]["encoding"] == "json"
            _subscribe(ws, {1: ch["gps/pose"], 2: ch["odometer/speed"]})
            got: dict[int, tuple[int, bytes]] = {}
            while len(got) < 2:
                frame = ws.recv(timeout=30)
                if isinstance(frame, bytes) and frame[0] == 0x01:  # message data
                    sub, log_time = struct.unpack_from("<IQ", frame, 1)
                    got.setdefault(sub, (log_time, frame[13:]))
    finally:
        p.send_signal(signal.SIGINT)
        p.wait(timeout=30)
    assert p.returncode == 130  # interrupted cleanly, as `run` is
    with MissionReader(mission) as r:
        recorded = {(m.topic, m.t_ns): m.data for m in r.messages(["gps/pose", "odometer/speed"])}
    t_pose, payload = got[1]
    pose = PoseInFrame.FromString(payload)
    truth = recorded[("gps/pose", t_pose)]  # the sample of that log time, exactly
    assert (pose.pose.position.x, pose.pose.position.y) == (truth.x_m, truth.y_m)
    assert pose.timestamp.seconds * 10**9 + pose.timestamp.nanos == t_pose
    t_speed, payload = got[2]
    speed = json.loads(payload)
    assert speed == json.loads(json.dumps(to_json(recorded[("odometer/speed", t_speed)])))
    assert speed["speed_mps"] == recorded[("odometer/speed", t_speed)].speed_mps


def test_a_client_that_never_reads_does_not_hold_the_graph(mission: Path) -> None:
    """A client subscribes to the beams (360 per s here) and never reads again: the SDK keeps
    1 MiB / 0.1 MiB = 9 messages for it and drops the oldest (or disconnects it once its control
    queue is full too); either way the replay runs to its end by itself, every sample accounted
    for as sent, unwatched or dropped (counted per topic)."""
    p, port, lines = _start_view(mission, "--speed", "1", "--client-mb", "1", "--max-message-mb", "0.1")
    try:
        with connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS) as ws:
            _, ch = _advertised(ws, {"radar/beams"})
            _subscribe(ws, {1: ch["radar/beams"]})
            assert p.wait(timeout=120) == 0  # finished while this client read nothing
    finally:
        if p.poll() is None:
            p.kill()
    for _ in range(100):  # the drain thread reads the last lines
        if any("no sample dropped" in line or "LOST" in line for line in lines):
            break
        time.sleep(0.05)
    text = "".join(lines)
    m = re.search(r"view: (\d+) process calls, port=\d+, sent=(\d+), unwatched=(\d+)", text)
    assert m, text
    calls, sent, unwatched = map(int, m.groups())
    with MissionReader(mission) as r:
        recorded = sum(c.count for c in r.info().channels if not c.mirror_of)
    lost = _lost(text, "view.")
    # the SDK's slow-client drops are of messages already counted as sent (it drops them from the
    # client's queue): reported apart, never more than were sent
    slow = lost.pop(("clients", "slow-client drops (at least)"), 0)
    assert calls == recorded == sent + unwatched + sum(lost.values())
    assert slow <= sent


def test_a_bad_file_is_one_line_exit_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "x.mcap"
    bad.write_bytes(b"not mcap")
    assert main(["view", str(bad), "--port", "0"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and str(bad) in err


def _stop(p: subprocess.Popen, lines: list[str]) -> str:
    p.send_signal(signal.SIGINT)
    assert p.wait(timeout=120) == 130  # stops even with a client that does not read
    for _ in range(200):  # the drain thread reads the last lines
        if any("no sample dropped" in line or "LOST" in line for line in lines):
            break
        time.sleep(0.05)
    return "".join(lines)


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads the server's RSS in /proc")
def test_a_client_that_never_reads_holds_at_most_its_byte_budget(grids: Path) -> None:
    """Issue 24 item 3: a client subscribes to 4 MiB maps and never reads. The server used to
    queue 1024 messages per client (4 GiB here); now it keeps --client-mb 48 // 5 MiB = 9
    messages for it. A second client reads the ticks, so the test knows 80 maps went out while
    the first one slept: the server's RSS grows by less than the budget plus what is in flight
    (far below the 80 x 4 MiB = 320 MiB that queuing all would take), and the summary counts
    the slow client's drops."""
    budget = 48 * MiB
    p, port, lines = _start_view(grids, "--loop", "--speed", "4", "--client-mb", "48", "--max-message-mb", "5")
    with _client(port, max_size=None, max_queue=1) as sleeper:  # reads nothing after the advertise
        _, ch = _advertised(sleeper, {"map/grid"})
        _subscribe(sleeper, {1: ch["map/grid"]})
        with _client(port) as reader:
            _, ch = _advertised(reader, {"tick"})
            _subscribe(reader, {2: ch["tick"]})
            ticks, base = 0, 0
            while ticks < 90:
                frame = reader.recv(timeout=60)
                if isinstance(frame, bytes) and frame[0] == 0x01:
                    ticks += 1
                    if ticks == 10:  # the sleeper's queue is being filled: the server's footprint now
                        base = _rss_bytes(p.pid)
            growth = _rss_bytes(p.pid) - base
        text = _stop(p, lines)
    assert growth < budget + 4 * GRID_BYTES + 32 * MiB, (growth / MiB, text)
    assert "backlog=9" in text and f"client_bytes={budget}" in text
    assert _lost(text, "view.")[("clients", "slow-client drops (at least)")] >= 1, text


def test_oversized_messages_and_extra_clients_are_dropped_and_counted_per_topic(grids: Path) -> None:
    """Maps over --max-message-mb are never sent (one warning, counted per topic); with a second
    client over --max-clients 1 nothing is sent (one warning, counted per topic). Every sample
    the view processed is sent, unwatched or counted as dropped."""
    p, port, lines = _start_view(grids, "--loop", "--speed", "4", "--client-mb", "8", "--max-message-mb", "1",
                                 "--max-clients", "1")
    with _client(port, max_size=None) as a:
        _, ch = _advertised(a, {"map/grid", "tick"})
        _subscribe(a, {1: ch["map/grid"], 2: ch["tick"]})
        subs = []
        while len(subs) < 30:
            frame = a.recv(timeout=60)
            if isinstance(frame, bytes) and frame[0] == 0x01:
                subs.append(struct.unpack_from("<I", frame, 1)[0])
        assert set(subs) == {2}  # ticks only: no map went out
        with _client(port) as _b:  # a second client: over --max-clients 1
            for _ in range(1200):
                if any("max_clients=1" in line for line in lines):
                    break
                time.sleep(0.05)
            text = _stop(p, lines)
    lost = _lost(text, "view.")
    assert lost[("map/grid", "oversized")] >= 10 and lost[("tick", "clients over max_clients")] >= 1, text
    assert sum(line.count("over max_message_bytes=1048576") for line in text.splitlines()) == 1, text
    assert len([line for line in text.splitlines() if "max_clients=1" in line and "WARNING" in line]) <= 2, text
    m = re.search(r"view: (\d+) process calls, port=\d+, sent=(\d+), unwatched=(\d+)", text)
    calls, sent, unwatched = map(int, m.groups())
    assert sent >= 30 and calls == sent + unwatched + sum(n for (_, kind), n in lost.items() if kind in (
        "oversized", "clients over max_clients")), text


def test_invalid_frames_are_one_error_line_per_kind_with_a_count(mission: Path) -> None:
    """20 plain HTTP requests and 600 invalid frames of two kinds: the SDK's ERROR line per
    occurrence (59 000 lines in 20 s before) is one line per kind, and the summary counts each."""
    p, port, lines = _start_view(mission, "--speed", "1", "--loop")
    for _ in range(20):  # not WebSocket: the SDK drops the connection
        with socket.create_connection(("127.0.0.1", port), timeout=60) as http:
            http.sendall(b"GET / HTTP/1.0\r\n\r\n")
            while http.recv(4096):
                pass
    with _client(port) as ws:
        _advertised(ws, set())
        answered = 0
        for batch in range(1, 61):  # the SDK answers each with an error status, queued with the control
            for _ in range(5):  # messages (--client-mb // --max-message-mb = 16 at most): send in batches
                ws.send(b"\x07garbage")
                ws.send("{not json")
            while answered < 10 * batch:
                msg = ws.recv(timeout=60)
                answered += isinstance(msg, str) and json.loads(msg).get("op") == "status"
    text = _stop(p, lines)
    assert answered == 600
    errors = [line for line in text.splitlines() if line.startswith("ERROR")]
    assert len(errors) == 3 and sum("Invalid message from" in e for e in errors) == 2, text
    assert "'Invalid message from ADDR: Unknown binary opcode N': 300" in text, text
    assert "'Invalid message from ADDR: key must be a string at line N column N': 300" in text, text
    assert "'Dropping client ADDR: handshake failed': 20" in text, text


def test_the_view_listens_on_loopback_and_says_where(mission: Path) -> None:
    """Loopback by default: the listening socket of the server (read in /proc/PID/net/tcp) is
    127.0.0.1, the address it prints."""
    p, port, lines = _start_view(mission, "--speed", "1", "--loop")
    if not Path(f"/proc/{p.pid}/net/tcp").exists():
        pytest.skip("reads /proc/PID/net/tcp")
    with open(f"/proc/{p.pid}/net/tcp") as f:
        listening = [row.split()[1] for row in f.read().splitlines()[1:] if row.split()[3] == "0A"]
    assert f"0100007F:{port:04X}" in listening, listening
    _stop(p, lines)


def test_a_port_in_use_or_a_bad_host_is_one_line(mission: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert main(["view", str(mission), "--port", str(port), "--no-progress"]) == 1
        err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"cannot listen on 127.0.0.1:{port}" in err[0] and "in use" in err[0], err
    assert main(["view", str(mission), "--host", "no-such-host.invalid", "--port", "0", "--no-progress"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot listen on no-such-host.invalid:0" in err[0], err


@pytest.mark.parametrize("args, where", [
    (["--client-mb", "nan"], "--client-mb nan"), (["--client-mb", "inf"], "--client-mb inf"),
    (["--client-mb", "-1"], "--client-mb -1"), (["--max-message-mb", "x"], "--max-message-mb 'x'"),
    (["--client-mb", "16", "--max-message-mb", "8"], "--client-mb 16: holds 2 message(s)"),
    (["--max-message-mb", "0.0001"], "--max-message-mb 0.0001"), (["--max-clients", "0"], "--max-clients 0"),
    (["--max-clients", "1.5"], "--max-clients '1.5'"), (["--port", "abc"], "--port 'abc'"),
    (["--port", "70000"], "--port 70000"),
])
def test_bad_budgets_are_one_line_exit_2(mission: Path, capsys: pytest.CaptureFixture[str], args: list[str],
                                         where: str) -> None:
    assert main(["view", str(mission), "--port", "0", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and where in err, err
