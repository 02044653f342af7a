"""MissionWriter -> MissionReader round trips, checked independently with the mcap library."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

import impala_msgs
from impala_flow import msgs
from impala_flow.io import (
    CodecError,
    CodecRegistry,
    MissionReader,
    MissionWriter,
    UnknownSchemaError,
    run_codecs,
)
from impala_flow.msgs import message

from .helpers import assert_same


def sample_values(i: int) -> dict[str, tuple[type, object]]:
    cfg = impala_msgs.RadarConfig("r", 77e9, 1e9, 1e3, 1e3, 4, 0.02, 4.0, 8, 1.0, 100.0)
    return {
        "gps/pose": (msgs.Pose2D, msgs.Pose2D(float(i), -float(i), 0.1 * i, np.eye(3) * i, "map")),
        "radar/beams": (impala_msgs.RadarBeam, impala_msgs.RadarBeam(
            0.1, i, 3, np.array([i, np.nan, np.inf, -np.inf], ">f4"),
            np.zeros(0, np.float32), cfg)),
        "slam/map": (msgs.Grid, msgs.Grid(np.full((4, 5), i, np.uint8), 0.5, 1.0, 2.0)),
        "odo/speed": (impala_msgs.Speed, impala_msgs.Speed(float(i))),
        "count": (int, i),
        "note": (str, f"sample {i}"),
    }


def write_mission(path: Path, registry: CodecRegistry, n: int = 50, **kw: object) -> dict:
    expected: dict[str, list] = {}
    with MissionWriter(path, codecs=registry, **kw) as w:  # type: ignore[arg-type]
        for topic, (t, _) in sample_values(0).items():
            w.add_topic(topic, t)
        for i in range(n):
            for k, (topic, (_, v)) in enumerate(sample_values(i).items()):
                t_ns = 1_000_000_000 + i * 10_000_000 + k
                w.write(topic, t_ns, v, seq=i)
                expected.setdefault(topic, []).append((t_ns, v, i))
    return expected


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_round_trip_all_compressions(tmp_path: Path, registry: CodecRegistry,
                                     compression: str) -> None:
    path = tmp_path / f"m-{compression}.mcap"
    expected = write_mission(path, registry, compression=compression, chunk_size=4096)
    with MissionReader(path, registry) as r:
        got: dict[str, list] = {}
        times = []
        for m in r.messages():
            got.setdefault(m.topic, []).append((m.t_ns, m.data, m.seq))
            times.append(m.t_ns)
        info = r.info()
    assert times == sorted(times)
    assert set(got) == set(expected)
    for topic, items in expected.items():
        assert [t for t, _, _ in got[topic]] == [t for t, _, _ in items]
        assert [s for _, _, s in got[topic]] == [s for _, _, s in items]
        for (_, a, _), (_, b, _) in zip(items, got[topic], strict=True):
            assert_same(a, b, topic)
    assert info.compression == compression and not info.truncated
    assert info.chunk_count > 3 and info.message_count == 50 * 6 + 2 * 50  # + 2 mirrors
    assert info.start_ns == 1_000_000_000 and info.duration_ns == 49 * 10_000_000 + 5
    counts = {c.topic: c.count for c in info.channels}
    assert counts["gps/pose"] == 50 and counts["/foxglove/gps/pose"] == 50


def test_file_is_valid_mcap_for_the_mcap_library(tmp_path: Path,
                                                 registry: CodecRegistry) -> None:
    path = tmp_path / "m.mcap"
    expected = write_mission(path, registry, chunk_size=2048)
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        assert len(summary.chunk_indexes) > 1
        msgs_by_topic: dict[str, list] = {}
        for schema, channel, m in reader.iter_messages():
            assert m.log_time == m.publish_time
            msgs_by_topic.setdefault(channel.topic, []).append((schema, m))
    schema, first = msgs_by_topic["gps/pose"][0]
    assert schema.name == "impala.Pose2D" and schema.encoding == "impala-flow/v1"
    assert json.loads(schema.data)["fields"][0] == {"kind": "float", "name": "x_m"}
    assert [m.log_time for _, m in msgs_by_topic["gps/pose"]] == \
        [t for t, _, _ in expected["gps/pose"]]
    assert first.sequence == 0 and msgs_by_topic["gps/pose"][7][1].sequence == 7


def test_metadata_is_stored(tmp_path: Path, registry: CodecRegistry) -> None:
    path = tmp_path / "m.mcap"
    meta = {"graph": {"yaml": "name: g\n", "path": "g.yaml"},
            "plugins": {"io": "0.1.0", "radar": "0.1.0"},
            "params": {"slam.cell_size": 0.4}}  # non-string values stored as JSON
    write_mission(path, registry, n=3, metadata=meta)
    with MissionReader(path, registry) as r:
        got = r.info().metadata
    assert got["graph"] == meta["graph"] and got["plugins"] == meta["plugins"]
    assert got["params"] == {"slam.cell_size": "0.4"}
    with open(path, "rb") as f:
        names = {m.name for m in make_reader(f).iter_metadata()}
    assert {"graph", "plugins", "params"} <= names


def test_seek_by_time_reads_only_overlapping_chunks(tmp_path: Path,
                                                    registry: CodecRegistry,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    path = tmp_path / "m.mcap"
    with MissionWriter(path, codecs=registry, chunk_size=1024, compression="none") as w:
        w.add_topic("x", float)
        for i in range(10_000):
            w.write("x", i * 1_000, float(i))
    import impala_flow.io._mcapfile as mf

    loaded = []
    real = mf.read_chunk
    monkeypatch.setattr(mf, "read_chunk", lambda *a: loaded.append(a[2]) or real(*a))
    with MissionReader(path, registry) as r:
        n_chunks = r.info().chunk_count
        got = [(m.t_ns, m.data) for m in r.messages(start_ns=5_000_000, end_ns=5_010_000)]
    assert got == [(5_000_000 + k * 1000, 5000.0 + k) for k in range(10)]
    assert n_chunks > 100 and len(loaded) <= 2


def test_topic_selection_and_raw(tmp_path: Path, registry: CodecRegistry) -> None:
    path = tmp_path / "m.mcap"
    write_mission(path, registry, n=5)
    with MissionReader(path, registry) as r:
        assert [m.topic for m in r.messages(["odo/speed"])] == ["odo/speed"] * 5
        raw = list(r.messages(["odo/speed"], raw=True))
        assert raw[0].data == registry.for_type(impala_msgs.Speed).encode(impala_msgs.Speed(0.0))
        assert r.topic_type("slam/map") is msgs.Grid
        assert "/foxglove/gps/pose" not in r.topics
        with pytest.raises(KeyError, match="no topic 'nope'"):
            list(r.messages(["nope"]))


def test_unknown_schema_names_the_channel_and_others_still_read(tmp_path: Path) -> None:
    @message("plugin.Secret", version=1)
    class Secret:
        code: int

    writer_reg = run_codecs()
    writer_reg.add_type(Secret, plugin="secretplugin")
    path = tmp_path / "m.mcap"
    with MissionWriter(path, codecs=writer_reg) as w:
        w.add_topic("spy/secret", Secret)
        w.add_topic("odo/speed", impala_msgs.Speed)
        for i in range(10):
            w.write("spy/secret", i, Secret(i))
            w.write("odo/speed", i, impala_msgs.Speed(i))
    with MissionReader(path, CodecRegistry.with_standard_types()) as r:
        got = list(r.messages())
        assert {m.topic for m in got} == {"odo/speed"} and len(got) == 10
        assert "spy/secret" in r.undecodable
        with pytest.raises(UnknownSchemaError, match="'spy/secret'.*'plugin.Secret'"):
            r.messages(["spy/secret"])
        assert not {c.topic: c.decodable for c in r.info().channels}["spy/secret"]
    with MissionReader(path, CodecRegistry(), strict=True) as r, \
            pytest.raises(UnknownSchemaError):
        list(r.messages())


def test_writer_refuses_wrong_types_and_unknown_topics(tmp_path: Path,
                                                       registry: CodecRegistry) -> None:
    with MissionWriter(tmp_path / "m.mcap", codecs=registry) as w:
        w.add_topic("p", msgs.Pose2D)
        with pytest.raises(CodecError, match="'p' records Pose2D, got Speed"):
            w.write("p", 0, impala_msgs.Speed(1.0))
        with pytest.raises(KeyError, match="add_topic"):
            w.write("q", 0, 1.0)
        with pytest.raises(ValueError, match="added twice"):
            w.add_topic("p", msgs.Pose2D)
        with pytest.raises(CodecError, match="no codec for Python type"):
            w.add_topic("z", dict)
    with pytest.raises(ValueError, match="compression"):
        MissionWriter(tmp_path / "x.mcap", codecs=registry, compression="gzip")


def test_overlapping_chunks_are_merged_in_time_order(tmp_path: Path,
                                                     registry: CodecRegistry) -> None:
    path = tmp_path / "m.mcap"
    with MissionWriter(path, codecs=registry, chunk_size=200, compression="none") as w:
        w.add_topic("a", int)
        w.add_topic("b", int)
        for i in range(100):  # "b" lags: chunks overlap in time
            w.write("a", i * 10, i)
            w.write("b", max(0, i * 10 - 95), i)
    with MissionReader(path, registry) as r:
        got = [(m.t_ns, m.topic, m.data) for m in r.messages()]
    assert [t for t, _, _ in got] == sorted(t for t, _, _ in got)
    assert len(got) == 200


def test_record_replay_record_is_identical(tmp_path: Path, registry: CodecRegistry) -> None:
    first, second = tmp_path / "a.mcap", tmp_path / "b.mcap"
    write_mission(first, registry, n=20)
    with MissionReader(first, registry) as r, \
            MissionWriter(second, codecs=registry) as w:
        for topic in r.topics:
            w.add_topic(topic, r.topic_type(topic))
        for m in r.messages():
            w.write(m.topic, m.t_ns, m.data, m.seq)

    def payloads(p: Path) -> list:
        with MissionReader(p, registry) as r:
            return [(m.topic, m.t_ns, m.seq, m.data) for m in r.messages(raw=True)]

    assert payloads(first) == payloads(second)


@pytest.mark.parametrize("cut", [False, True])
def test_reads_files_written_by_the_bare_mcap_writer(tmp_path: Path, registry: CodecRegistry,
                                                     cut: bool) -> None:
    """Interoperability: schemas and channels inside chunks, as mcap.writer puts them."""
    from mcap.writer import Writer

    path = tmp_path / "bare.mcap"
    codec = registry.for_type(impala_msgs.Speed)
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=512)
        w.start()
        sid = w.register_schema(codec.schema_name, codec.schema_encoding, codec.schema_data())
        cid = w.register_channel("odo/speed", codec.message_encoding, sid)
        for i in range(500):
            w.add_message(cid, i, codec.encode(impala_msgs.Speed(float(i))), i, i)
        w.finish()
    if cut:
        path.write_bytes(path.read_bytes()[:-100])
    with MissionReader(path, registry) as r:
        values = [m.data.speed_mps for m in r.messages()]
        assert r.info().truncated == cut
    assert values == [float(i) for i in range(500)]
