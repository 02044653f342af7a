"""io.FoxgloveBridge and `impala-flow view`: a real WebSocket client speaking Foxglove's
protocol receives serverInfo and advertise, subscribes, and decodes the binary messages
against the recording they came from. The client offers both subprotocols the Foxglove app
offers: foxglove-sdk >= 0.30 answers foxglove.sdk.v1, the successor of foxglove.websocket.v1
(same ops and binary framing)."""

from __future__ import annotations

import json
import re
import signal
import struct
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from websockets.sync.client import connect

from impala_flow.cli import main
from impala_flow.io import MissionReader
from impala_io.bridge import to_json

SUBPROTOCOLS = ["foxglove.sdk.v1", "foxglove.websocket.v1"]
CLI = [sys.executable, "-c", "import sys; from impala_flow.cli import main; sys.exit(main())"]


@pytest.fixture(scope="module")
def mission(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("view") / "m.mcap"
    assert main(["simulate", "beynes", "-o", str(path), "--duration", "8s", "--no-progress"]) == 0
    return path


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


def test_view_serves_the_recording_in_foxglove_schemas_and_json(mission: Path) -> None:
    p, port, lines = _start_view(mission, "--speed", "1")
    try:
        with connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS) as ws:
            assert ws.subprotocol in SUBPROTOCOLS
            info, ch = _advertised(ws, {"gps/pose", "odometer/speed"})
            assert info["name"] == "impala-flow"
            assert ch["gps/pose"]["encoding"] == "protobuf" and ch["gps/pose"]["schemaName"] == "foxglove.PoseInFrame"
            assert ch["odometer/speed"]["encoding"] == "json"
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [
                {"id": 1, "channelId": ch["gps/pose"]["id"]}, {"id": 2, "channelId": ch["odometer/speed"]["id"]}]}))
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
    --backlog 32 messages for it and drops the oldest (or disconnects it once its control queue
    is full too); either way the replay runs to its end by itself, every sample accounted for
    as sent or unwatched."""
    p, port, lines = _start_view(mission, "--speed", "1", "--backlog", "32")
    try:
        with connect(f"ws://127.0.0.1:{port}", subprotocols=SUBPROTOCOLS) as ws:
            _, ch = _advertised(ws, {"radar/beams"})
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": ch["radar/beams"]["id"]}]}))
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
    assert calls == recorded == sent + unwatched


def test_a_bad_file_is_one_line_exit_1(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "x.mcap"
    bad.write_bytes(b"not mcap")
    assert main(["view", str(bad), "--port", "0"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and str(bad) in err
