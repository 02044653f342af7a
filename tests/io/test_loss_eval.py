"""A damaged chunk in a replayed mission: the replayer counts the lost samples per output and
the evaluator's report states the time ranges missing (truth from the official reader)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from mcap.reader import make_reader

from impala_eval.evaluator.component import TrajectoryEvaluator
from impala_eval.report import format_metrics
from impala_flow import msgs
from impala_flow.io import MissionWriter, Replayer, run_codecs
from impala_flow.testing import run_components

N = 600


def test_evaluator_report_states_the_gap(tmp_path: Path) -> None:
    path = tmp_path / "m.mcap"
    with MissionWriter(path, codecs=run_codecs(), chunk_size=4096, foxglove=False) as w:
        w.add_topic("truth/pose", msgs.Pose2D)
        w.add_topic("slam/pose", msgs.Pose2D)
        for i in range(N):
            t = 1_000_000_000 + i * 10_000_000
            w.write("truth/pose", t, msgs.Pose2D(0.1 * i, 0.0, 0.0))
            w.write("slam/pose", t + 1, msgs.Pose2D(0.1 * i, 0.01, 0.0))
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        truth = [(ch.topic, m.log_time) for _, ch, m in reader.iter_messages()]
    bad = summary.chunk_indexes[len(summary.chunk_indexes) // 2]
    data = bytearray(path.read_bytes())
    data[bad.chunk_start_offset + bad.chunk_length - 30] ^= 0x10
    path.write_bytes(bytes(data))

    lost = {"truth/pose": 0, "slam/pose": 0}
    expected_gaps = {}
    for topic, stream in (("truth/pose", "truth"), ("slam/pose", "estimate")):
        times = [t for tp, t in truth if tp == topic]
        inside = [t for t in times if bad.message_start_time <= t <= bad.message_end_time]
        lost[topic] = len(inside)
        before = max(t for t in times if t < min(inside))
        after = min(t for t in times if t > max(inside))
        expected_gaps[stream] = [[round(before * 1e-9, 6), round(after * 1e-9, 6)]]

    rep = Replayer("mission", path=str(path))
    ev = TrajectoryEvaluator("eval", report=str(tmp_path / "rep"), align="first")
    summary_run = run_components(rep, ev, connections=["mission.truth/pose -> eval.truth",
                                                       "mission.slam/pose -> eval.estimate"])
    assert summary_run.extra["mission"]["lost"] == lost and all(lost.values())
    figures = json.loads((tmp_path / "rep" / "metrics.json").read_text())
    assert figures["gaps"] == expected_gaps
    gap_s = sum(b - a for g in expected_gaps.values() for a, b in g)
    assert np.isclose(figures["gap_total_s"], gap_s)
    text = format_metrics(figures)
    text = format_metrics(figures)
    assert "DATA MISSING" in text and f"{expected_gaps['truth'][0][0]:.3f}" in text
