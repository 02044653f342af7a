"""The writer's second thread (``MissionWriter(threads=2)``, the default): chunks compressed and
written there give the same file, byte for byte, as one thread; its errors reach the caller."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

import impala_msgs
from impala_flow import msgs
from impala_flow.io import CodecRegistry, MissionReader, MissionWriter

from .test_recording import sample_values


def _write(path: Path, registry: CodecRegistry, threads: int, compression: str) -> None:
    """Many small chunks, with a topic declared and a metadata record written between them."""
    with MissionWriter(path, codecs=registry, threads=threads, compression=compression, chunk_size=2048,
                       flush_period_s=None, metadata={"graph": {"yaml": "name: t"}}) as w:
        for topic, (t, _) in sample_values(0).items():
            w.add_topic(topic, t)
        for i in range(120):
            for k, (topic, (_, v)) in enumerate(sample_values(i).items()):
                w.write(topic, 1_000_000_000 + i * 10_000_000 + k, v, seq=i)
            if i == 60:
                w.add_metadata("halfway", {"i": i})
                w.add_topic("late/grid", msgs.Grid)
                w.flush()
            if i > 60:
                w.write("late/grid", 1_000_000_000 + i * 10_000_000 + 9,
                        msgs.Grid(np.full((8, 8), i, np.float32), 0.2, 0.0, 0.0), seq=i)


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_two_threads_write_the_same_bytes_as_one(tmp_path: Path, registry: CodecRegistry, compression: str) -> None:
    one, two = tmp_path / "one.mcap", tmp_path / "two.mcap"
    _write(one, registry, 1, compression)
    _write(two, registry, 2, compression)
    data = two.read_bytes()
    assert data == one.read_bytes()
    with open(two, "rb") as f:  # and the file is one the reference library reads, CRCs checked
        reader = make_reader(f, validate_crcs=True)
        summary = reader.get_summary()
        assert summary is not None and len(summary.chunk_indexes) > 20
        n = sum(1 for _ in reader.iter_messages())
    with MissionReader(two, registry) as r:
        info = r.info()
        grids = [m.data for m in r.messages(["late/grid"])]
    assert n == info.message_count and not info.truncated
    assert info.metadata["halfway"] == {"i": "60"} and info.metadata["graph"] == {"yaml": "name: t"}
    assert [float(g.data[0, 0]) for g in grids] == [float(i) for i in range(61, 120)]


@pytest.mark.skipif(not os.path.exists("/dev/full"), reason="needs /dev/full (Linux)")
def test_a_failing_write_on_the_thread_is_raised_naming_the_file(registry: CodecRegistry) -> None:
    # /dev/full takes the open and refuses every write (ENOSPC): the thread's first write fails,
    # and the caller hears of it at its next write, or at close at the latest
    with pytest.raises(OSError, match=r"/dev/full: writing the recording failed: OSError: .*No space left"):
        with MissionWriter("/dev/full", codecs=registry, threads=2, chunk_size=1024) as w:
            w.add_topic("odo/speed", impala_msgs.Speed)
            for i in range(10_000):
                w.write("odo/speed", i, impala_msgs.Speed(float(i)))


def test_threads_is_one_or_two(tmp_path: Path, registry: CodecRegistry) -> None:
    with pytest.raises(ValueError, match="threads must be 1 or 2"):
        MissionWriter(tmp_path / "x.mcap", codecs=registry, threads=3)


GRAPH = """
components:
  src: {{type: t.Counter, params: {{n: 30000, period_ns: 1000}}}}
  sink: t.CollectingSink
connections: [src.out -> sink.x]
record: {{path: out-{threads}.mcap, streams: ["src.*"], chunk_size: 4096, threads: {threads}}}
"""


def test_a_graphs_recorder_writes_the_same_file_with_one_or_two_threads(tmp_path: Path) -> None:
    from impala_flow import Session
    from impala_flow.testing import CollectingSink, plugin_of

    from ..engine.components import Counter

    session = Session(extra_plugins={"t": plugin_of(Counter, CollectingSink)})
    for threads in (1, 2):
        (tmp_path / f"g{threads}.yaml").write_text(GRAPH.format(threads=threads))
        session.run(session.build(session.load(tmp_path / f"g{threads}.yaml")))
    one, two = (tmp_path / f"out-{n}.mcap" for n in (1, 2))

    def content(path: Path) -> tuple[list, list]:  # the metadata differ (the graph says threads: 1 or 2)
        with open(path, "rb") as f:
            reader = make_reader(f, validate_crcs=True)
            summary = reader.get_summary()
            assert summary is not None
            chunks = [(c.message_start_time, c.message_end_time, c.uncompressed_size, c.compressed_size)
                      for c in summary.chunk_indexes]
            return chunks, [(c.topic, m.log_time, m.sequence, m.data) for _, c, m in reader.iter_messages()]

    assert content(one) == content(two)
    with MissionReader(two) as r:
        assert [m.data for m in r.messages(["src/out"])] == [float(i) for i in range(30000)]
        assert r.info().chunk_count > 50


UNCLOSED = """
import sys
import impala_msgs
from impala_flow.io import MissionWriter, run_codecs
w = MissionWriter(sys.argv[1], codecs=run_codecs(), chunk_size=1024, threads=int(sys.argv[2]))
w.add_topic("odo/speed", impala_msgs.Speed)
for i in range(20_000):
    w.write("odo/speed", i, impala_msgs.Speed(float(i)))
"""  # the process ends without close()


def test_a_writer_never_closed_leaves_every_chunk_it_cut_with_two_threads_as_with_one(tmp_path: Path) -> None:
    import subprocess
    import sys

    root = Path(__file__).resolve().parents[2]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(root), str(root / "plugins")]))
    recovered = []
    for threads in (1, 2):
        path = tmp_path / f"unclosed-{threads}.mcap"
        subprocess.run([sys.executable, "-c", UNCLOSED, str(path), str(threads)], env=env, check=True, timeout=120)
        with MissionReader(path) as r:
            info = r.info()
            assert info.truncated
            recovered.append(info.recovered_count)
            assert [m.data.speed_mps for m in r.messages()] == [float(i) for i in range(info.recovered_count or 0)]
    assert recovered[0] == recovered[1] and recovered[1] > 19_000
