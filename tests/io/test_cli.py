"""impala-flow info / export / replay on real recordings."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader

import impala_msgs
from impala_flow import msgs
from impala_flow.cli import main
from impala_flow.io import MissionWriter, run_codecs


@pytest.fixture
def mission(tmp_path: Path) -> Path:
    path = tmp_path / "m.mcap"
    with MissionWriter(path, codecs=run_codecs(), chunk_size=2048,
                       metadata={"impala_flow.graph": {"yaml": "name: g"}}) as w:
        w.add_topic("slam/pose", msgs.Pose2D)
        w.add_topic("odo/speed", impala_msgs.Speed)
        w.add_topic("count", int)
        for k in range(100):
            w.write("slam/pose", k * 10_000_000, msgs.Pose2D(k * 1.0, 2.0, 0.5, np.eye(3)))
            w.write("odo/speed", k * 10_000_000, impala_msgs.Speed(k / 2))
            w.write("count", k * 10_000_000, k)
    return path


def test_info(mission: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["info", str(mission)]) == 0
    out = capsys.readouterr().out
    assert "complete" in out and "duration:     0.990 s" in out
    assert "slam/pose" in out and "impala.Pose2D" in out and "100" in out
    assert "Foxglove view of slam/pose" in out and "compression zstd" in out
    assert main(["info", str(mission), "--json"]) == 0
    d = json.loads(capsys.readouterr().out)
    assert d["truncated"] is False and d["message_count"] == 400


def test_info_truncated_and_bad_files(mission: Path, tmp_path: Path,
                                      capsys: pytest.CaptureFixture[str]) -> None:
    data = mission.read_bytes()
    mission.write_bytes(data[: len(data) * 2 // 3])
    assert main(["info", str(mission)]) == 0
    out = capsys.readouterr().out
    assert "TRUNCATED" in out and "messages recovered" in out
    for content, what in [(b"", "empty file"), (b"hello world", "not an MCAP file")]:
        bad = tmp_path / "bad.mcap"
        bad.write_bytes(content)
        assert main(["info", str(bad)]) == 1
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and str(bad) in err and what in err
        assert "Traceback" not in err


def test_export_csv(mission: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "pose.csv"
    assert main(["export", str(mission), "--topic", "slam/pose", "--csv", "-o", str(out)]) == 0
    rows = list(csv.reader(out.read_text().splitlines()))
    cov = [f"cov_xyt.{i}.{j}" for i in range(3) for j in range(3)]  # the covariance is not dropped
    assert rows[0] == ["t_ns", "x_m", "y_m", "theta_rad", *cov, "frame"]
    eye = [str(float(i == j)) for i in range(3) for j in range(3)]
    assert rows[1] == ["0", "0.0", "2.0", "0.5", *eye, "map"] and len(rows) == 101
    assert main(["export", str(mission), "--topic", "count", "--csv"]) == 0
    rows = list(csv.reader(io.StringIO(capsys.readouterr().out)))
    assert rows[0] == ["t_ns", "value"] and rows[-1] == ["990000000", "99"]
    assert main(["export", str(mission), "--topic", "nope", "--csv"]) == 2


def test_replay_binds_the_file_to_the_graph(mission: Path, tmp_path: Path) -> None:
    graph = tmp_path / "g.yaml"
    out = tmp_path / "again.mcap"
    graph.write_text(yaml.safe_dump({
        "name": "replay", "components": {
            "mission": {"type": "io.Replayer", "params": {"path": "missing.mcap",
                                                          "streams": ["odo/*"]}}},
        "record": {"path": str(out), "streams": [{"from": "mission.odo/speed",
                                                  "topic": "odo/speed"}]}}))
    assert main(["replay", str(mission), str(graph), "--no-progress"]) == 0
    assert main(["export", str(out), "--topic", "odo/speed", "--csv", "-o",
                 str(tmp_path / "s.csv")]) == 0
    rows = list(csv.reader((tmp_path / "s.csv").read_text().splitlines()))
    assert len(rows) == 101 and rows[-1][:2] == ["990000000", "49.5"]


def test_replay_finds_a_replayer_declared_in_an_included_file(mission: Path, tmp_path: Path) -> None:
    (tmp_path / "source.yaml").write_text(yaml.safe_dump({
        "components": {"mission": {"type": "io.Replayer", "params": {"path": "missing.mcap", "streams": ["odo/*"]}}}}))
    out = tmp_path / "again.mcap"
    graph = tmp_path / "g.yaml"
    graph.write_text(yaml.safe_dump({
        "name": "replay-included", "include": "source.yaml",
        "record": {"path": str(out), "streams": [{"from": "mission.odo/speed", "topic": "odo/speed"}]}}))
    assert main(["replay", str(mission), str(graph), "--no-progress"]) == 0
    with open(out, "rb") as f:
        topics = [ch.topic for _, ch, _ in make_reader(f).iter_messages()]
    # every recorded speed, replayed, and its JSON view for generic tools
    assert topics.count("odo/speed") == 100 and topics.count("/foxglove/odo/speed") == 100
