"""`impala-flow import oxford` writes the real scans as a mission file (read back with the
bare mcap library) that replays the same beams as the PNG reader."""

from __future__ import annotations

import numpy as np
from mcap.reader import make_reader

from impala_flow.cli import main
from impala_flow.io import MissionReader
from impala_radar.navtech import read_navtech_png

from ..datasets import oxford_sample_or_skip


def test_import_oxford_writes_every_valid_beam_and_the_truth(tmp_path, capsys):
    folder = oxford_sample_or_skip()
    out = tmp_path / "oxford.mcap"
    assert main(["import", "oxford", str(folder), "-o", str(out), "--no-progress"]) == 0
    pngs = sorted((folder / "radar").glob("*.png"))
    scans = [read_navtech_png(p) for p in pngs]
    n_valid = sum(int(s.valid.sum()) for s in scans)
    with open(out, "rb") as f:  # independent reader: the mcap library itself
        counts: dict[str, int] = {}
        times: list[int] = []
        for _, channel, message in make_reader(f).iter_messages(log_time_order=True):
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == "radar/beams":
                times.append(message.log_time)
    assert counts["radar/beams"] == n_valid
    assert counts["truth/pose"] == len(pngs) + 1  # identity at the scan before the first file
    first = scans[0]
    assert times[: int(first.valid.sum())] == first.timestamps_ns[first.valid].tolist()
    with MissionReader(out) as r:  # the project's reader decodes the same values
        beams = [m.data for m in r.messages(["radar/beams"])]
    assert np.array_equal(beams[0].up, first.power[np.flatnonzero(first.valid)[0]])
    assert beams[0].down.size == 0


def test_import_rejects_a_folder_without_scans(tmp_path, capsys):
    assert main(["import", "oxford", str(tmp_path), "-o", str(tmp_path / "x.mcap")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"impala-flow import: error: {tmp_path}: no radar/ folder of Navtech PNG scans"]
