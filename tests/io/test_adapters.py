"""Channel adapters (impala_flow.io._adapter): the engine reads a foreign channel through the adapter a plugin
registers, puts the samples (each with its own time, earlier than its message's log time) in order with the
native ones, counts what comes too late, and names the missing plugin when nothing reads a channel."""

from __future__ import annotations

import struct
from pathlib import Path

import pytest
from mcap.writer import Writer

from impala_flow import msgs
from impala_flow._registry import BrokenPlugin, Registry
from impala_flow.io import CodecRegistry, MissionReader, UnknownSchemaError

T0 = 1_000_000_000_000


class Spread:
    """A toy adapter: a message ``(t_first, n)`` gives n Scalars 10 ms apart from t_first."""

    value_type = msgs.Scalar

    def __init__(self, channel, context) -> None:
        self.channel, self.context = channel, context

    def adapt(self, payload, log_time_ns):
        t, n = struct.unpack("<qi", bytes(payload))
        return [(t + k * 10_000_000, msgs.Scalar(float(t + k * 10_000_000), "ns")) for k in range(n)]

    def notes(self):
        return [f"{self.channel.topic}: spread"]


def _write(path: Path, messages: list[tuple[str, int, int, int]]) -> None:
    """(topic, log time, first sample time, samples) on 'toy' channels, plus a 'plain' channel no one reads."""
    with open(path, "wb") as f:
        w = Writer(f)
        w.start()
        sid = w.register_schema("toy/Spread", "toy", b"")
        other = w.register_schema("toy/Unknown", "toy", b"")
        chans = {}
        for topic, log_t, t, n in messages:
            if topic not in chans:
                chans[topic] = w.register_channel(topic, "toy", other if topic == "/unknown" else sid)
            w.add_message(chans[topic], log_time=log_t, data=struct.pack("<qi", t, n), publish_time=log_t)
        w.finish()


def _codecs(**broken: BrokenPlugin) -> CodecRegistry:
    reg = Registry()
    reg.add_channel_adapter("toy", "toy/Spread", "toy", Spread)
    reg.broken.update(broken)
    return CodecRegistry.from_plugins(reg)


def test_adapted_samples_come_in_time_order_with_their_own_times(tmp_path):
    path = tmp_path / "toy.mcap"
    # each message logged 250 ms after its first sample (a radar turn logged when complete), two channels interleaved
    _write(path, [("/a", T0 + 250_000_000, T0, 25), ("/b", T0 + 260_000_000, T0 + 5_000_000, 25),
                  ("/a", T0 + 500_000_000, T0 + 250_000_000, 25), ("/unknown", T0 + 600_000_000, 0, 1)])
    with MissionReader(path, _codecs()) as r:
        got = [(m.topic, m.t_ns) for m in r.messages()]
        assert r.topic_type("/a") is msgs.Scalar
        assert r.skipped_counts() == {"/unknown": 1} and r.late == {}
        assert r.adapters()["/a"].notes() == ["/a: spread"]
    times = [t for _, t in got]
    assert times == sorted(times) and len(got) == 75
    assert [t for tp, t in got if tp == "/b"] == [T0 + 5_000_000 + k * 10_000_000 for k in range(25)]


def test_a_sample_later_than_the_window_is_dropped_and_counted(tmp_path):
    path = tmp_path / "late.mcap"
    # /b's samples are 15 s older than their log time (the window is 2 s): /a's of 10 s was given already
    _write(path, [("/a", T0, T0, 1), ("/a", T0 + 10_000_000_000, T0 + 10_000_000_000, 1),
                  ("/a", T0 + 12_000_000_000, T0 + 12_000_000_000, 1),
                  ("/b", T0 + 20_000_000_000, T0 + 5_000_000_000, 3)])
    with MissionReader(path, _codecs()) as r:
        got = [(m.topic, m.t_ns) for m in r.messages()]
        assert r.late == {"/b": 3}
    assert got == [("/a", T0), ("/a", T0 + 10_000_000_000), ("/a", T0 + 12_000_000_000)]


def test_a_channel_no_plugin_reads_names_the_missing_plugin(tmp_path):
    path = tmp_path / "missing.mcap"
    _write(path, [("/unknown", T0, T0, 1)])
    needs = BrokenPlugin("ros2", "impala_ros2.plugin", missing="mcap_ros2", install="pip install 'impala-flow[ros2]'")
    with MissionReader(path, _codecs(ros2=needs)) as r:
        assert not r.info().channels[0].decodable
        with pytest.raises(UnknownSchemaError, match=r"plugin 'ros2' needs mcap_ros2: pip install"):
            list(r.messages(["/unknown"]))


def test_a_factory_refusing_a_channel_says_why(tmp_path):
    def refuse(channel, context):
        raise ValueError("this toy definition is not read")

    reg = Registry()
    reg.add_channel_adapter("toy", "*", "toy", refuse)
    path = tmp_path / "refused.mcap"
    _write(path, [("/a", T0, T0, 1)])
    with MissionReader(path, CodecRegistry.from_plugins(reg)) as r:
        with pytest.raises(UnknownSchemaError, match="this toy definition is not read"):
            list(r.messages(["/a"]))
