"""`impala-flow import oxford` writes the real scans as a mission file (read back with the
bare mcap library) that replays the same beams as the PNG reader."""

from __future__ import annotations

import numpy as np
import pytest
from mcap.reader import make_reader

from impala_flow.cli import main
from impala_flow.io import MissionReader
from impala_flow.msgs import wrap_angle
from impala_radar.datasets.navtech_png import read_navtech_png

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
    # every beam of every scan in acquisition order; its power the linear power of the PNG's
    # half-dB counts, P = 10^(count * 0.5 / 10) (count = pixel = 255 x the reader's value)
    rows = [(k, i) for k, s in enumerate(scans) for i in np.flatnonzero(s.valid).tolist()]
    assert [(b.turn, b.index) for b in beams] == rows
    assert all(np.allclose(b.up, 10.0 ** (np.rint(scans[k].power[i] * 255) * 0.05), rtol=1e-6)
               for b, (k, i) in zip(beams, rows, strict=True))
    assert beams[0].down.size == 0
    # the measured defaults (impala_radar.datasets.oxford): 4.38 cm bins, centred
    assert beams[0].config.range_offset_m == pytest.approx(0.5 * 0.0438)


def test_import_prints_what_it_read(tmp_path, capsys):
    folder = oxford_sample_or_skip()
    out = tmp_path / "oxford.mcap"
    assert main(["import", "oxford", str(folder), "-o", str(out), "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "dataset:      oxford" in text
    assert "3768 bins x 0.04380 m = 165.0 m (bin 0 at 0.0219 m)" in text  # 3768 * 0.0438 = 165.04
    assert "turns:        11" in text and "beams:        4400" in text
    assert "rows dropped: 0" in text and "truth poses:  12" in text
    assert [p.name for p in tmp_path.iterdir()] == ["oxford.mcap"]  # no temporary file left
    # the mission file carries the same block: `impala-flow info` shows it
    assert main(["info", str(out)]) == 0
    info = capsys.readouterr().out
    assert "metadata impala_flow.source.oxford:" in info
    assert "3768 bins x 0.04380 m = 165.0 m" in info and "turns: 11" in info and "rows_dropped: 0" in info
    with open(out, "rb") as f:  # written as an MCAP metadata record (the official reader sees it)
        from mcap.reader import make_reader

        records = {m.name: m.metadata for m in make_reader(f).iter_metadata()}
    assert records["impala_flow.source.oxford"]["beams"] == "4400"


def test_import_range_resolution_and_azimuth_offset_options(tmp_path):
    folder = oxford_sample_or_skip()
    out = tmp_path / "oxford.mcap"
    assert main(["import", "oxford", str(folder), "-o", str(out), "--no-progress",
                 "--range-resolution-m", "0.0438", "--azimuth-offset-deg", "-2"]) == 0
    first = read_navtech_png(sorted((folder / "radar").glob("*.png"))[0])
    with MissionReader(out) as r:
        beam = next(iter(r.messages(["radar/beams"]))).data
    assert beam.config.range_per_bin_m == pytest.approx(0.0438, rel=1e-12)
    assert beam.config.range_offset_m == pytest.approx(0.0219, rel=1e-12)
    assert beam.azimuth_rad == pytest.approx(float(wrap_angle(np.radians(-2.0) - first.azimuth_rad[0])))


def test_import_rejects_a_folder_without_scans(tmp_path, capsys):
    data = tmp_path / "data"
    data.mkdir()
    assert main(["import", "oxford", str(data), "-o", str(tmp_path / "x.mcap")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"impala-flow import: error: {data}: no radar/ folder of Navtech PNG scans"]
    assert not (tmp_path / "x.mcap").exists()
