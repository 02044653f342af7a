"""Damaged-file corpus: cuts and bit flips in each record type. A damaged record never takes
the whole file down: what can be read is read, what was skipped is one line naming the file
and the offset, and the messages a damaged chunk held are counted per stream (the truth is
taken from the official ``mcap`` reader on the intact file)."""

from __future__ import annotations

import os
import struct
from pathlib import Path

import pytest
from mcap.reader import make_reader

import impala_msgs
from impala_flow.io import CodecRegistry, MissionReader, MissionWriter, RecordingError

N = 2000
MAGIC = 8


def _write(path: Path, registry: CodecRegistry, compression: str = "zstd") -> Path:
    with MissionWriter(path, codecs=registry, chunk_size=4096, compression=compression,
                       metadata={"graph": {"yaml": "a: 1"}, "notes": {"who": "test"}}) as w:
        w.add_topic("odo/speed", impala_msgs.Speed)
        w.add_topic("gyro/yaw", float)
        for i in range(N):
            w.write("odo/speed", i * 1000, impala_msgs.Speed(float(i)), i)
            if i % 4 == 0:
                w.write("gyro/yaw", i * 1000 + 1, float(i), i)
    return path


@pytest.fixture
def mission(tmp_path: Path, registry: CodecRegistry) -> Path:
    return _write(tmp_path / "m.mcap", registry)


def _official(path: Path) -> tuple[list, list[tuple[str, int]]]:
    """(chunk indexes, (topic, log time) of every message) by the official reader."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        return summary.chunk_indexes, [(ch.topic, m.log_time) for _, ch, m in reader.iter_messages()]


def _records(path: Path) -> list[tuple[int, int, int]]:
    """(offset, opcode, length) of every record of the data section, walked by hand."""
    data = path.read_bytes()
    out, pos = [], MAGIC
    while pos < len(data) - MAGIC:
        op, length = struct.unpack_from("<BQ", data, pos)
        out.append((pos, op, length))
        if op == 0x0F:  # data end
            break
        pos += 9 + length
    return out


def _flip(path: Path, at: int, mask: int = 0x80) -> None:
    data = bytearray(path.read_bytes())
    data[at] ^= mask
    path.write_bytes(bytes(data))


def _one_line(problem: str, path: Path, offset: int) -> None:
    assert "\n" not in problem and problem.startswith(str(path)) and f"offset {offset}" in problem, problem


def _speeds(r: MissionReader) -> list[float]:
    return [m.data.speed_mps for m in r.messages(["odo/speed"])]


@pytest.mark.parametrize("cut_footer", [False, True], ids=["indexed", "scanned"])
def test_bit_flip_in_header_string(mission: Path, registry: CodecRegistry, cut_footer: bool) -> None:
    _flip(mission, MAGIC + 9 + 4)  # first byte of the profile string: invalid UTF-8
    if cut_footer:
        mission.write_bytes(mission.read_bytes()[:-10])
    with MissionReader(mission, registry) as r:
        assert _speeds(r) == [float(i) for i in range(N)]
        problems = r.info().problems
    assert len(problems) == 1
    _one_line(problems[0], mission, MAGIC)
    assert "Header" in problems[0]


@pytest.mark.parametrize("cut_footer", [False, True], ids=["indexed", "scanned"])
def test_header_length_of_2_pow_62(mission: Path, registry: CodecRegistry, cut_footer: bool) -> None:
    data = bytearray(mission.read_bytes())
    struct.pack_into("<Q", data, MAGIC + 1, 2**62)
    mission.write_bytes(bytes(data[:-10] if cut_footer else data))
    with MissionReader(mission, registry) as r:  # no MemoryError, no EndOfFile
        assert _speeds(r) == [float(i) for i in range(N)]
        info = r.info()
    assert info.metadata["notes"] == {"who": "test"}
    assert len(info.problems) == 1
    _one_line(info.problems[0], mission, MAGIC)
    assert str(2**62) in info.problems[0] and "skipped" in info.problems[0]


def test_bit_flip_in_a_metadata_record(mission: Path, registry: CodecRegistry) -> None:
    at = next(pos for pos, op, _ in _records(mission) if op == 0x0C)  # the first metadata record
    _flip(mission, at + 9 + 4)  # its name: invalid UTF-8
    with MissionReader(mission, registry) as r:
        assert _speeds(r) == [float(i) for i in range(N)]
        info = r.info()
    assert len(info.problems) == 1 and "Metadata" in info.problems[0]
    _one_line(info.problems[0], mission, at)
    assert len(info.metadata) == 1  # the other metadata record is still there


def test_metadata_length_of_2_pow_62(mission: Path, registry: CodecRegistry) -> None:
    at = next(pos for pos, op, _ in _records(mission) if op == 0x0C)
    data = bytearray(mission.read_bytes())
    struct.pack_into("<Q", data, at + 1, 2**62)
    mission.write_bytes(bytes(data))
    with MissionReader(mission, registry) as r:
        assert _speeds(r) == [float(i) for i in range(N)]
        info = r.info()
    assert len(info.problems) == 1
    _one_line(info.problems[0], mission, at)


def test_chunk_length_of_2_pow_62_without_summary(mission: Path, registry: CodecRegistry) -> None:
    """A chunk whose length field is destroyed in a cut file: the chunks after it still read."""
    chunks, truth = _official(mission)
    bad = chunks[3]
    data = bytearray(mission.read_bytes()[: chunks[-1].chunk_start_offset])  # cut: no summary
    struct.pack_into("<Q", data, bad.chunk_start_offset + 1, 2**62)
    mission.write_bytes(bytes(data))
    with MissionReader(mission, registry) as r:
        speeds = _speeds(r)
        info = r.info()
    lost = {t for topic, t in truth if topic == "odo/speed"
            and bad.message_start_time <= t <= bad.message_end_time}
    kept = [t for topic, t in truth if topic == "odo/speed" and t < chunks[-1].message_start_time]
    assert speeds == [t / 1000 for t in kept if t not in lost]
    assert info.truncated
    assert any(f"offset {bad.chunk_start_offset}" in p and "skipped" in p for p in info.problems)


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
@pytest.mark.parametrize("cut_footer", [False, True], ids=["indexed", "scanned"])
def test_lost_messages_counted_per_stream(tmp_path: Path, registry: CodecRegistry, compression: str,
                                          cut_footer: bool) -> None:
    path = _write(tmp_path / "m.mcap", registry, compression)
    chunks, truth = _official(path)
    bad = chunks[4]
    in_bad = [(topic, t) for topic, t in truth if bad.message_start_time <= t <= bad.message_end_time]
    data = bytearray(path.read_bytes())
    data[bad.chunk_start_offset + bad.chunk_length - 30] ^= 0x10
    if cut_footer:
        data = data[:-10]
    path.write_bytes(bytes(data))
    with MissionReader(path, registry) as r:
        got = [(m.topic, m.t_ns) for m in r.messages()]
        lost = r.lost_counts()
        losses = list(r.losses)
    assert got == [m for m in truth if m not in in_bad]
    expected = {topic: sum(1 for t, _ in in_bad if t == topic) for topic in ("odo/speed", "gyro/yaw")}
    assert lost == expected and all(n > 0 for n in expected.values())
    for loss in losses:
        times = [t for topic, t in in_bad if topic == loss.topic]
        assert (loss.start_ns, loss.end_ns, loss.offset) == (min(times), max(times), bad.chunk_start_offset)
    # a window that excludes the damaged chunk loses nothing
    with MissionReader(path, registry) as r:
        list(r.messages(start_ns=bad.message_end_time + 1))
        assert r.lost_counts() == {}


def test_directory_and_fifo_are_one_line_errors(tmp_path: Path, registry: CodecRegistry) -> None:
    with pytest.raises(RecordingError) as e:
        MissionReader(tmp_path, registry)
    assert str(e.value) == f"{tmp_path}: a directory, not an MCAP recording"
    fifo = tmp_path / "pipe.mcap"
    os.mkfifo(fifo)
    with pytest.raises(RecordingError) as e:  # no writer on the FIFO: open() would block forever
        MissionReader(fifo, registry)
    assert str(e.value) == f"{fifo}: a FIFO, not an MCAP recording"


def test_reserved_and_private_records_are_skipped(tmp_path: Path, registry: CodecRegistry) -> None:
    """Records of opcodes a reader does not know are valid MCAP: skipped by length."""
    path = _write(tmp_path / "m.mcap", registry)
    chunks, truth = _official(path)
    at = chunks[2].chunk_start_offset
    data = path.read_bytes()
    private = struct.pack("<BQ", 0x80, 5) + b"hello"
    path.write_bytes(data[:at] + private + data[at:chunks[-1].chunk_start_offset])  # cut: scan path
    with MissionReader(path, registry) as r:
        assert [m.topic for m in r.messages()] == [t for t, time in truth if time < chunks[-1].message_start_time]
        assert r.info().problems == ()
