"""Recordings read by the TypeScript reader Foxglove itself uses (@mcap/core, indexed), their
protobuf channels decoded from the schemas stored in the file (protobufjs): the same messages,
per channel, as the official Python reader, and the same values. Skips cleanly where node or
the npm registry is not available (the packages are installed once per machine, in a cache)."""

from __future__ import annotations

import json
import math
import subprocess
from pathlib import Path

import pytest
from mcap.reader import make_reader

from impala_flow.cli import main
from impala_flow.io import MissionReader

from .._node import node_script

HERE = Path(__file__).resolve().parent
PACKAGES = ["@mcap/core@2", "@mcap/support@1", "protobufjs@7"]


@pytest.fixture(scope="module")
def node_reader() -> list[str]:
    return node_script(HERE / "ts_read_mcap.js", PACKAGES, "@mcap/core")


def _ts_read(reader: list[str], path: Path) -> dict:
    r = subprocess.run([*reader, str(path)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def _official_counts(path: Path) -> dict[str, int]:
    counts: dict[str, int] = {}
    with open(path, "rb") as f:
        for _, channel, _ in make_reader(f).iter_messages():
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
    return counts


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    d = tmp_path_factory.mktemp("ts")
    mission = d / "mission.mcap"
    assert main(["simulate", "beynes", "-o", str(mission), "--duration", "4s", "--no-progress"]) == 0
    out = d / "rslam"
    graph = Path(__file__).resolve().parents[2] / "graphs" / "rslam.yaml"
    assert main(["run", str(graph), "--var", f"mission={mission}", "--var", f"out={out}", "--no-progress"]) == 0
    processed = next(out.glob("*.mcap"))
    return {"simulated": mission, "processed": processed}


@pytest.mark.parametrize("which", ["simulated", "processed"])
def test_the_typescript_reader_reads_every_message_and_decodes_the_foxglove_channels(
        node_reader: list[str], recordings: dict[str, Path], which: str) -> None:
    path = recordings[which]
    ts = _ts_read(node_reader, path)
    assert ts["counts"] == _official_counts(path)
    foxglove = [t for t in ts["counts"] if t.startswith("/foxglove/")]
    assert foxglove and all(ts["decoded"].get(t) == ts["counts"][t] for t in foxglove)
    # the first pose mirrored, as Foxglove decodes it, is the pose impala-flow recorded
    pose_topic = next(t for t in foxglove if "pose" in t)
    first = ts["firsts"][pose_topic]
    with MissionReader(path) as r:
        rec = next(iter(r.messages([pose_topic[len("/foxglove/"):]])))
    assert int(first["log_time"]) == rec.t_ns
    p = first["value"]["pose"]
    assert p["position"]["x"] == rec.data.x_m and p["position"]["y"] == rec.data.y_m
    assert 2 * math.atan2(p["orientation"].get("z", 0.0), p["orientation"]["w"]) == pytest.approx(
        rec.data.theta_rad, abs=1e-12)
