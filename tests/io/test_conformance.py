"""Conformance: every valid MCAP file reads, whoever wrote it.

The corpus is generated here by the official ``mcap.writer.Writer`` with every combination
of ``use_chunking``, ``index_types``, ``use_statistics``, ``use_summary_offsets``,
compression and repeated channels/schemas (off: no summary section at all); nothing binary
is committed. Each file must give exactly the messages of the official streaming reader
(``NonSeekingReader``, file order), stably sorted by log time, the same counts, and pass
``verify()``.
"""

from __future__ import annotations

import itertools
import random
from pathlib import Path

import pytest
from mcap.reader import NonSeekingReader, make_reader
from mcap.writer import CompressionType, IndexType, Writer

from impala_flow.io import MissionReader

INDEX_TYPES = {
    "none": IndexType.NONE,
    "chunk": IndexType.CHUNK,
    "message": IndexType.MESSAGE,
    "chunk+message": IndexType.CHUNK | IndexType.MESSAGE,
    "all": IndexType.ALL,
}
COMPRESSION = {"none": CompressionType.NONE, "lz4": CompressionType.LZ4, "zstd": CompressionType.ZSTD}
TOPICS = ("imu", "gps/pose", "radar/beams")
N = 300


def write_foreign(path: Path, *, chunking: bool, index: str, statistics: bool, offsets: bool,
                  compression: str, repeat: bool) -> None:
    """A file as another tool writes it: JSON messages on three channels, log times that go
    back and forth (chunks overlap in time), ties across channels, a metadata record and an
    attachment."""
    rng = random.Random(7)
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=2048, compression=COMPRESSION[compression], index_types=INDEX_TYPES[index],
                   use_chunking=chunking, use_statistics=statistics, use_summary_offsets=offsets,
                   repeat_channels=repeat, repeat_schemas=repeat)
        w.start(profile="", library="conformance-test")
        sid = w.register_schema("demo.Msg", "jsonschema", b'{"type": "object"}')
        cids = [w.register_channel(t, "json", sid, {"k": t}) for t in TOPICS]
        for i in range(N):
            t = 1_000_000_000 + i * 1_000_000 + rng.randrange(-3, 4) * 400_000  # jitter: out of order
            cid = cids[i % 3]
            w.add_message(cid, t, f'{{"i": {i}}}'.encode(), t + 5, sequence=i)
            if i % 50 == 0:
                w.add_message(cids[(i + 1) % 3], t, f'{{"tie": {i}}}'.encode(), t, sequence=10_000 + i)
        w.add_metadata("calibration", {"sensor": "radar", "offset_ns": "12"})
        w.add_attachment(1, 2, "notes.txt", "text/plain", b"hello")
        w.finish()


def official(path: Path) -> list[tuple[str, int, bytes, int]]:
    """The official streaming reader's messages in file order, stably sorted by log time."""
    with open(path, "rb") as f:
        msgs = [(ch.topic, m.log_time, m.data, m.sequence)
                for _, ch, m in NonSeekingReader(f).iter_messages(log_time_order=False)]
    return sorted(msgs, key=lambda m: m[1])


COMBOS = list(itertools.product([True, False], INDEX_TYPES, [True, False], [True, False], COMPRESSION,
                                [True, False]))


@pytest.mark.parametrize(("chunking", "index", "statistics", "offsets", "compression", "repeat"),
                         [c for c in COMBOS if c[0] or c[4] == "none"],  # compression needs chunks
                         ids=lambda v: str(v))
def test_reads_like_the_official_reader(tmp_path: Path, chunking: bool, index: str, statistics: bool,
                                        offsets: bool, compression: str, repeat: bool) -> None:
    path = tmp_path / "foreign.mcap"
    write_foreign(path, chunking=chunking, index=index, statistics=statistics, offsets=offsets,
                  compression=compression, repeat=repeat)
    truth = official(path)
    assert len(truth) == N + N // 50
    with MissionReader(path, strict=True) as r:
        got = [(m.topic, m.t_ns, m.data, m.seq) for m in r.messages(raw=True)]
        assert got == truth
        info = r.info()
        assert not info.truncated and info.problems == () and info.corrupt_chunks == 0
        assert info.message_count == len(truth)
        assert {c.topic: c.count for c in info.channels} == {
            t: sum(m[0] == t for m in truth) for t in TOPICS}
        assert (info.start_ns, info.end_ns) == (truth[0][1], truth[-1][1])
        assert info.metadata["calibration"] == {"sensor": "radar", "offset_ns": "12"}
        assert [a[0] for a in info.attachments] == ["notes.txt"]
        # a time window and one topic: the official messages in that window, nothing else
        lo, hi = truth[100][1], truth[200][1]
        window = [(m.topic, m.t_ns, m.data, m.seq) for m in r.messages(["gps/pose"], lo, hi, raw=True)]
        assert window == [m for m in truth if m[0] == "gps/pose" and lo <= m[1] < hi]
        assert r.verify() == []
        assert r.info().message_count == len(truth)


def test_official_reader_agrees_on_our_corpus_kinds(tmp_path: Path) -> None:
    """The corpus covers what the issue lists: no chunks, no indexes, no statistics, no summary."""
    kinds = {}
    for chunking, index, statistics, repeat in [(False, "all", True, True), (True, "none", True, True),
                                                (True, "all", False, True), (True, "none", False, False)]:
        path = tmp_path / f"{chunking}-{index}-{statistics}-{repeat}.mcap"
        write_foreign(path, chunking=chunking, index=index, statistics=statistics, offsets=False,
                      compression="none", repeat=repeat)
        with open(path, "rb") as f:
            summary = make_reader(f).get_summary()
        kinds[(chunking, index, statistics, repeat)] = summary
    assert kinds[(False, "all", True, True)].chunk_indexes == []  # no chunks
    assert kinds[(True, "none", True, True)].chunk_indexes == []  # chunks, no index
    assert kinds[(True, "all", False, True)].statistics is None  # no statistics
    assert kinds[(True, "none", False, False)] is None  # no summary section at all
