"""Older versions of standard messages still read: a recording of RadarBeam version 1 (before
``chirp``) decodes as today's RadarBeam with chirp 0; today's chirp round trips."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import impala_msgs
from impala_flow import msgs
from impala_flow.io import CodecError, CodecRegistry, MissionReader, MissionWriter
from impala_flow.io._codec import UpgradingCodec

CFG = impala_msgs.RadarConfig("r", 77e9, 1e9, 1e3, 1e3, 4, 0.02, 4.0, 8, 1.0, 100.0, doppler=False,
                              range_offset_m=-0.31)


def test_a_version_1_beam_recording_reads_as_chirp_0(tmp_path: Path) -> None:
    old = CodecRegistry()  # what a writer of version 1 had: RadarBeam without chirp
    old.add_type(impala_msgs.RadarBeamV1, plugin="impala_flow")
    path = tmp_path / "v1.mcap"
    up = [np.arange(4, dtype=np.float32) * i for i in range(3)]
    with MissionWriter(path, codecs=old) as w:
        w.add_topic("radar/beams", impala_msgs.RadarBeamV1)
        for i in range(3):
            beam = impala_msgs.RadarBeamV1(0.1 * i, 7, i, up[i], np.zeros(0, np.float32), CFG)
            w.write("radar/beams", 1000 + i, beam)
    with MissionReader(path, CodecRegistry.with_standard_types()) as r:
        got = [m.data for m in r.messages(["radar/beams"])]
    assert [type(b) for b in got] == [impala_msgs.RadarBeam] * 3
    assert [(b.azimuth_rad, b.turn, b.index, b.chirp) for b in got] == [(0.1 * i, 7, i, 0) for i in range(3)]
    assert all(np.array_equal(b.up, up[i]) and b.down.size == 0 for i, b in enumerate(got))
    assert got[0].config.range_offset_m == -0.31 and got[0].config.name == "r"


def test_chirp_round_trips_and_version_1_is_read_only(tmp_path: Path) -> None:
    reg = CodecRegistry.with_standard_types()
    path = tmp_path / "v2.mcap"
    with MissionWriter(path, codecs=reg) as w:
        w.add_topic("radar/beams", impala_msgs.RadarBeam)
        for i, ch in enumerate((impala_msgs.CHIRP_UP, impala_msgs.CHIRP_DOWN, 0)):
            w.write("radar/beams", 1000 + i, impala_msgs.RadarBeam(0.0, 0, i, np.ones(2, np.float32),
                                                            np.zeros(0, np.float32), CFG, ch))
    with MissionReader(path, reg) as r:
        assert [m.data.chirp for m in r.messages(["radar/beams"])] == [1, -1, 0]
    legacy = reg.for_schema("impala.RadarBeam", 1)
    assert isinstance(legacy, UpgradingCodec)
    with pytest.raises(CodecError, match="read-only"):
        legacy.encode(impala_msgs.RadarBeamV1(0.0, 0, 0, np.ones(2, np.float32), np.zeros(0, np.float32), CFG))


def test_a_version_1_recording_replays_through_a_graph_taking_todays_beams(tmp_path: Path) -> None:
    """The replayer declares what the reader decodes (today's RadarBeam), not the recorded version: a
    mission imported before ``chirp`` still feeds graphs/odometry_navtech.yaml."""
    from impala_flow.cli import main

    old = CodecRegistry()
    old.add_type(impala_msgs.RadarBeamV1, plugin="impala_flow")
    old.add_type(msgs.Pose2D, plugin="impala_flow")
    path = tmp_path / "v1.mcap"
    with MissionWriter(path, codecs=old) as w:
        w.add_topic("radar/beams", impala_msgs.RadarBeamV1)
        w.add_topic("truth/pose", msgs.Pose2D)
        for i in range(3):
            w.write("radar/beams", 1000 + i, impala_msgs.RadarBeamV1(0.1 * i, 7, i, np.ones(4, np.float32),
                                                              np.zeros(0, np.float32), CFG))
        w.write("truth/pose", 1000, msgs.Pose2D(0.0, 0.0, 0.0))
    graph = Path(__file__).resolve().parents[2] / "graphs" / "odometry_navtech.yaml"
    assert main(["validate", str(graph), "--var", f"mission={path}", "--var", f"out={tmp_path / 'o'}"]) == 0
