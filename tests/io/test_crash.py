"""Crash safety: a real recorder process killed with SIGKILL mid-mission."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

from impala_flow.io import CodecRegistry, MissionReader

ROOT = Path(__file__).resolve().parents[2]
SCRIPT = """
import sys
import numpy as np
from impala_flow import msgs
import impala_msgs
from impala_flow.io import MissionWriter, run_codecs
w = MissionWriter(sys.argv[1], codecs=run_codecs(),
                  chunk_size=64 * 1024, metadata={"graph": {"yaml": "name: crash"}})
w.add_topic("odo/speed", impala_msgs.Speed)
w.add_topic("radar/image", msgs.Grid)
i = 0
while True:  # a long mission: only SIGKILL ends it
    w.write("odo/speed", i * 1_000_000, impala_msgs.Speed(float(i)), i)
    if i % 10 == 0:
        w.write("radar/image", i * 1_000_000, msgs.Grid(np.full((16, 16), i, np.float32),
                                                        0.2, 0.0, 0.0), i)
    if i == 20_000:
        print("halfway", flush=True)
    i += 1
"""


def test_sigkill_mid_recording_leaves_a_readable_prefix(tmp_path: Path) -> None:
    path = tmp_path / "crash.mcap"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(ROOT / "plugins")]))
    proc = subprocess.Popen([sys.executable, "-c", SCRIPT, str(path)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        line = proc.stdout.readline() if proc.stdout else ""
        assert line.strip() == "halfway", proc.stderr.read() if proc.stderr else ""
    finally:
        os.kill(proc.pid, signal.SIGKILL)
        proc.communicate(timeout=30)
    assert proc.returncode == -signal.SIGKILL

    with MissionReader(path, CodecRegistry.with_standard_types()) as r:
        info = r.info()
        speeds = [(m.t_ns, m.data.speed_mps, m.seq) for m in r.messages(["odo/speed"])]
        images = list(r.messages(["radar/image"]))
    assert info.truncated and info.recovered_count is not None
    assert info.metadata["graph"] == {"yaml": "name: crash"}
    # everything written before "halfway" but the chunk in progress is there, in order
    assert len(speeds) > 20_000 - 2_000
    assert speeds == [(i * 1_000_000, float(i), i) for i in range(len(speeds))]
    mirrored = sum(c.count for c in info.channels if c.mirror_of)
    # recovered counts the recorded messages; the Foxglove mirror copies are shown apart
    assert info.recovered_count == len(speeds) + len(images)
    assert info.mirror_count == mirrored == len(images) and info.message_count == len(speeds) + 2 * len(images)
    assert all(float(m.data.data[0, 0]) == m.seq for m in images)


def test_a_file_cut_anywhere_keeps_each_sample_with_its_mirror_or_neither(tmp_path: Path) -> None:
    """The deterministic twin of the SIGKILL test: the file is cut at many offsets; every chunk
    holds a sample and its Foxglove mirror together, so what is recovered pairs up exactly."""
    import numpy as np

    import impala_msgs
    from impala_flow import msgs
    from impala_flow.io import MissionWriter, run_codecs

    path = tmp_path / "whole.mcap"
    n = 3_000
    with MissionWriter(path, codecs=run_codecs(), chunk_size=4 * 1024) as w:
        w.add_topic("odo/speed", impala_msgs.Speed)
        w.add_topic("radar/image", msgs.Grid)
        for i in range(n):
            w.write("odo/speed", i * 1_000_000, impala_msgs.Speed(float(i)), i)
            if i % 10 == 0:
                w.write("radar/image", i * 1_000_000, msgs.Grid(np.full((16, 16), i, np.float32), 0.2, 0.0, 0.0), i)
    whole = path.read_bytes()
    cuts = np.linspace(len(whole) // 10, len(whole) - 64, 40).astype(int)
    for cut in cuts:
        part = tmp_path / "part.mcap"
        part.write_bytes(whole[:cut])
        with MissionReader(part, CodecRegistry.with_standard_types()) as r:
            info = r.info()
            speeds = [m.seq for m in r.messages(["odo/speed"])]
            images = [m.seq for m in r.messages(["radar/image"])]
        assert info.truncated, cut
        assert speeds == list(range(len(speeds))) and images == list(range(0, 10 * len(images), 10)), cut
        assert info.mirror_count == len(images), (cut, info.mirror_count, len(images))
