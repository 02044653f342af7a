"""Bad files: each gives one RecordingError subclass naming the file and what is wrong,
and whatever is still valid stays readable."""

from __future__ import annotations

from pathlib import Path

import pytest
from mcap.reader import make_reader

import impala_msgs
from impala_flow.io import (
    BadMagicError,
    CodecRegistry,
    CorruptChunkError,
    CorruptSummaryError,
    EmptyFileError,
    MissionReader,
    MissionWriter,
    NotMcapError,
    RecordingError,
    TruncatedRecordingError,
)

N = 2000


@pytest.fixture
def good(tmp_path: Path, registry: CodecRegistry) -> Path:
    path = tmp_path / "good.mcap"
    with MissionWriter(path, codecs=registry, chunk_size=4096, compression="none",
                       metadata={"graph": {"yaml": "a: 1"}}) as w:
        w.add_topic("odo/speed", impala_msgs.Speed)
        for i in range(N):
            w.write("odo/speed", i * 1000, impala_msgs.Speed(float(i)), i)
    return path


def _chunks(path: Path) -> list:
    with open(path, "rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    return summary.chunk_indexes


def _one_line(e: RecordingError, path: Path) -> str:
    text = str(e)
    assert "\n" not in text and text.startswith(str(path)), text
    return text


def _values(r: MissionReader) -> list[float]:
    return [m.data.speed_mps for m in r.messages()]


def test_zero_length(tmp_path: Path, registry: CodecRegistry) -> None:
    path = tmp_path / "empty.mcap"
    path.write_bytes(b"")
    with pytest.raises(EmptyFileError) as e:
        MissionReader(path, registry)
    assert "empty file" in _one_line(e.value, path)


def test_not_mcap_at_all(tmp_path: Path, registry: CodecRegistry) -> None:
    for name, content in [("notes.mcap", b"name: graph\ncomponents: {}\n"),
                          ("image.mcap", b"\x89PNG\r\n\x1a\n" + bytes(100)), ("x", b"abc")]:
        path = tmp_path / name
        path.write_bytes(content)
        with pytest.raises(NotMcapError) as e:
            MissionReader(path, registry)
        assert "not an MCAP file" in _one_line(e.value, path)


def test_wrong_magic(good: Path, registry: CodecRegistry) -> None:
    data = bytearray(good.read_bytes())
    data[5:6] = b"9"  # "\x89MCAP9\r\n": an MCAP version we do not read
    good.write_bytes(bytes(data))
    with pytest.raises(BadMagicError) as e:
        MissionReader(good, registry)
    assert "wrong MCAP magic" in _one_line(e.value, good)


def test_truncated_footer(good: Path, registry: CodecRegistry) -> None:
    good.write_bytes(good.read_bytes()[:-12])  # cut inside the footer
    with pytest.raises(TruncatedRecordingError) as e:
        MissionReader(good, registry, strict=True)
    assert "truncated" in _one_line(e.value, good)
    with MissionReader(good, registry) as r:  # lenient: everything is still there
        info = r.info()
        assert info.truncated and info.recovered_count == N
        assert _values(r) == [float(i) for i in range(N)]
        assert info.metadata["graph"] == {"yaml": "a: 1"}


def test_cut_inside_a_chunk(good: Path, registry: CodecRegistry) -> None:
    chunks = _chunks(good)
    cut = chunks[5].chunk_start_offset + chunks[5].chunk_length // 2
    good.write_bytes(good.read_bytes()[:cut])
    with MissionReader(good, registry) as r:
        info = r.info()
        values = _values(r)
    assert info.truncated and 0 < info.recovered_count == len(values) < N
    assert values == [float(i) for i in range(len(values))]  # a prefix, in order


@pytest.mark.parametrize("compression", ["none", "zstd", "lz4"])
def test_flipped_bits_inside_a_chunk(tmp_path: Path, registry: CodecRegistry,
                                     compression: str) -> None:
    path = tmp_path / "m.mcap"
    with MissionWriter(path, codecs=registry, chunk_size=4096, compression=compression) as w:
        w.add_topic("odo/speed", impala_msgs.Speed)
        for i in range(N):
            w.write("odo/speed", i * 1000, impala_msgs.Speed(float(i)), i)
    chunks = _chunks(path)
    bad = chunks[2]
    data = bytearray(path.read_bytes())
    data[bad.chunk_start_offset + bad.chunk_length - 40] ^= 0x10
    path.write_bytes(bytes(data))
    with MissionReader(path, registry, strict=True) as r, \
            pytest.raises(CorruptChunkError) as e:
        _values(r)
    assert f"chunk at offset {bad.chunk_start_offset}" in _one_line(e.value, path)
    with MissionReader(path, registry) as r:
        values = _values(r)
        info = r.info()
    assert info.corrupt_chunks == 1 and len(info.problems) == 1
    assert str(path) in info.problems[0]
    assert 0 < len(values) < N and values == sorted(values)  # the other chunks still read
    with MissionReader(path, registry) as r:
        assert len(r.verify()) == 1


def test_flipped_bits_in_truncated_file_are_skipped_by_the_scan(
        good: Path, registry: CodecRegistry) -> None:
    chunks = _chunks(good)
    data = bytearray(good.read_bytes()[: chunks[-1].chunk_start_offset])  # cut, no footer
    data[chunks[1].chunk_start_offset + 200] ^= 0x01
    good.write_bytes(bytes(data))
    with MissionReader(good, registry) as r:
        info = r.info()
        values = _values(r)
    assert info.truncated and info.corrupt_chunks == 1 and len(values) == info.recovered_count
    assert values[0] == 0.0 and values == sorted(values)


def test_corrupt_summary(good: Path, registry: CodecRegistry) -> None:
    data = bytearray(good.read_bytes())
    data[-60] ^= 0xFF  # inside the summary section (chunk indexes), before the footer
    good.write_bytes(bytes(data))
    with pytest.raises(CorruptSummaryError) as e:
        MissionReader(good, registry, strict=True)
    assert "summary" in _one_line(e.value, good)
    with MissionReader(good, registry) as r:
        assert _values(r) == [float(i) for i in range(N)]
        assert any("summary" in p for p in r.info().problems)


def test_missing_file(tmp_path: Path, registry: CodecRegistry) -> None:
    with pytest.raises(RecordingError, match="cannot open"):
        MissionReader(tmp_path / "nope.mcap", registry)
