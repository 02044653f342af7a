"""Lost data is never silent, and ``info --verify`` tells the truth: exit codes and lines of
``info``, ``export`` and ``replay`` on damaged recordings (truth from the official reader)."""

from __future__ import annotations

import csv
import json
import struct
from pathlib import Path

import pytest
import yaml
from mcap.reader import make_reader

import impala_msgs
from impala_flow import msgs
from impala_flow.cli import main
from impala_flow.io import MissionReader, MissionWriter, run_codecs

N = 1000
TOPICS = ("odo/speed", "gps/pose")  # recorded; the file also holds their Foxglove mirrors


@pytest.fixture
def mission(tmp_path: Path) -> Path:
    path = tmp_path / "m.mcap"
    with MissionWriter(path, codecs=run_codecs(), chunk_size=4096) as w:
        w.add_topic("odo/speed", impala_msgs.Speed)
        w.add_topic("gps/pose", msgs.Pose2D)
        for i in range(N):
            w.write("odo/speed", i * 1_000_000, impala_msgs.Speed(float(i)), i)
            if i % 10 == 0:
                w.write("gps/pose", i * 1_000_000, msgs.Pose2D(float(i), 0.0, 0.0), i)
    return path


def _official(path: Path) -> tuple[list, dict[str, int], list[tuple[str, int]]]:
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        msgs_ = [(ch.topic, m.log_time) for _, ch, m in reader.iter_messages() if ch.topic in TOPICS]
    counts: dict[str, int] = {}
    for topic, _ in msgs_:
        counts[topic] = counts.get(topic, 0) + 1
    return summary.chunk_indexes, counts, msgs_


def _damage_chunk(path: Path, k: int) -> tuple[object, dict[str, int]]:
    """Flip a bit inside chunk k; return its chunk index and its messages per topic."""
    chunks, _, truth = _official(path)
    bad = chunks[k]
    lost: dict[str, int] = {}
    for topic, t in truth:
        if bad.message_start_time <= t <= bad.message_end_time:
            lost[topic] = lost.get(topic, 0) + 1
    data = bytearray(path.read_bytes())
    data[bad.chunk_start_offset + bad.chunk_length - 30] ^= 0x10
    path.write_bytes(bytes(data))
    return bad, lost


def test_verify_a_whole_file(mission: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _, counts, _ = _official(mission)
    assert main(["info", str(mission), "--verify", "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["verified"] and info["problems"] == []
    assert {c["topic"]: c["count"] for c in info["channels"] if not c["mirror_of"]} == counts


def test_verify_counts_a_corrupt_chunk_once_and_reports_readable_counts(
        mission: Path, capsys: pytest.CaptureFixture[str]) -> None:
    chunks, counts, _ = _official(mission)
    bad, lost = _damage_chunk(mission, 3)
    assert main(["info", str(mission), "--verify", "--json"]) == 1
    info = json.loads(capsys.readouterr().out)
    assert info["corrupt_chunks"] == 1 and info["chunk_count"] == len(chunks)
    assert len(info["problems"]) == 1 and f"chunk at offset {bad.chunk_start_offset}" in info["problems"][0]
    readable = {c["topic"]: c["count"] for c in info["channels"] if not c["mirror_of"]}
    assert readable == {t: counts[t] - lost.get(t, 0) for t in counts}
    assert main(["info", str(mission), "--verify"]) == 1
    out = capsys.readouterr().out
    assert "DAMAGED" in out and "readable messages" in out and "complete" not in out


def test_verify_checks_message_indexes(mission: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A flipped bit in a Message Index entry (what Foxglove's reader rejects) fails verify."""
    chunks, _, _ = _official(mission)
    ci = chunks[2]
    at = min(ci.message_index_offsets.values())
    data = bytearray(mission.read_bytes())
    (n,) = struct.unpack_from("<I", data, at + 9 + 2)
    assert n >= 16
    data[at + 9 + 6 + 8 + 7] ^= 0x01  # high byte of the first entry's offset in the chunk
    mission.write_bytes(bytes(data))
    assert main(["info", str(mission)]) == 0  # plain info reads the summary only
    capsys.readouterr()
    assert main(["info", str(mission), "--verify"]) == 1
    out = capsys.readouterr().out
    assert f"chunk at offset {ci.chunk_start_offset}: message index" in out and "no such message" in out


def test_verify_summary_crc_and_truncation(mission: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = bytearray(mission.read_bytes())
    data[-60] ^= 0xFF  # inside the summary section
    mission.write_bytes(bytes(data))
    assert main(["info", str(mission), "--verify"]) == 1
    out = capsys.readouterr().out
    assert "summary" in out and "complete" not in out
    mission.write_bytes(bytes(data[: len(data) // 2]))
    assert main(["info", str(mission), "--verify"]) == 1
    assert "TRUNCATED" in capsys.readouterr().out


def test_export_refuses_a_lossy_csv_unless_allowed(mission: Path, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    _, counts, _ = _official(mission)
    bad, lost = _damage_chunk(mission, 2)
    out = tmp_path / "speed.csv"
    assert main(["export", str(mission), "--topic", "odo/speed", "--csv", "-o", str(out)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and f"{lost['odo/speed']} messages of 'odo/speed' lost" in err
    assert f"t={bad.message_start_time * 1e-9:.3f}" in err and not out.exists()
    assert main(["export", str(mission), "--topic", "odo/speed", "--csv", "-o", str(out), "--allow-loss"]) == 0
    rows = list(csv.reader(out.read_text().splitlines()))
    assert len(rows) - 1 == counts["odo/speed"] - lost["odo/speed"]


def _graph(tmp_path: Path) -> Path:
    graph = tmp_path / "g.yaml"
    graph.write_text(yaml.safe_dump({
        "name": "replay", "components": {
            "mission": {"type": "io.Replayer", "params": {"path": "missing.mcap"}}},
        "record": {"path": str(tmp_path / "again.mcap"),
                   "streams": [{"from": "mission.odo/speed", "topic": "odo/speed"}]}}))
    return graph


def test_replay_prints_lost_lines_and_json(mission: Path, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    bad, lost = _damage_chunk(mission, 2)
    out = tmp_path / "summary.json"
    assert main(["replay", str(mission), str(_graph(tmp_path)), "--no-progress", "--summary-json", str(out)]) == 0
    err = capsys.readouterr().err
    for topic, n in lost.items():
        assert f"LOST at mission.{topic}: {n} unreadable" in err
    summary = json.loads(out.read_text())
    assert {k: v["unreadable"] for k, v in summary["lost"].items()} == {f"mission.{t}": n for t, n in lost.items()}
    assert all(v["missing_s"] for v in summary["lost"].values())  # the time ranges missing
    assert summary["lost_total"] == sum(lost.values())
    assert summary["extra"]["mission"]["lost"] == lost


def test_replay_of_a_bad_file_exits_1_with_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.mcap"
    bad.write_bytes(b"hello world")
    assert main(["replay", str(bad), str(_graph(tmp_path)), "--no-progress"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and str(bad) in err and "not an MCAP file" in err
    # a directory is a rosbag2 folder of split files: its bad part is named, one line; one holding none is refused
    assert main(["replay", str(tmp_path), str(_graph(tmp_path)), "--no-progress"]) == 1
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and str(bad) in err and "not an MCAP file" in err
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["replay", str(empty), str(_graph(tmp_path)), "--no-progress"]) == 1
    assert "a directory with no .mcap file" in capsys.readouterr().err


def test_replay_start_past_the_end_is_refused(mission: Path, tmp_path: Path,
                                              capsys: pytest.CaptureFixture[str]) -> None:
    # the mission spans (N - 1) ms: a start 5 s after its first sample replays nothing
    assert main(["replay", str(mission), str(_graph(tmp_path)), "--no-progress", "--set", "mission.start_s=5"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1] == (f"impala-flow replay: error: component 'mission', in start(): ValueError: {mission}: "
                       f"start_s 5.0 is past the end of the recording ({(N - 1) / 1000:.3f} s): nothing would be "
                       "replayed")


def test_info_lists_attachments_and_mirrors_apart(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "a.mcap"
    with MissionWriter(path, codecs=run_codecs()) as w:
        w.add_topic("slam/pose", msgs.Pose2D)
        for i in range(10):
            w.write("slam/pose", i, msgs.Pose2D(0.0, 0.0, 0.0))
    data = path.read_bytes()
    with MissionReader(path) as r:
        assert r.info().mirror_count == 10 and r.info().message_count == 20
    del data
    assert main(["info", str(path)]) == 0
    assert "10 of them Foxglove mirror copies" in capsys.readouterr().out


def test_run_prints_the_same_lost_lines_as_replay(mission: Path, tmp_path: Path,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    """`run` with a replayer reading a damaged file says what it lost, as `replay` does."""
    bad, lost = _damage_chunk(mission, 2)
    graph = _graph(tmp_path)
    out = tmp_path / "summary.json"
    assert main(["run", str(graph), "--set", f"mission.path={mission}", "--no-progress",
                 "--summary-json", str(out)]) == 0
    err = capsys.readouterr().err
    for topic, n in lost.items():
        assert f"LOST at mission.{topic}: {n} unreadable (damaged chunks; missing t=" in err
    assert "no sample dropped" not in err
    summary = json.loads(out.read_text())
    assert summary["lost_total"] == sum(lost.values())
