"""Boreas: the real 2024 frame through `impala-flow import boreas` (shape, timing, azimuth
order, resolution, round trip through the recorder), the resolution by date, and the
applanix ground truth on synthetic files whose motion is known."""

from __future__ import annotations

import math

import numpy as np
import pytest
from PIL import Image

from impala_flow.cli import main
from impala_flow.io import MissionReader
from impala_flow.msgs import wrap_angle
from impala_radar.datasets.boreas import BOREAS_POSE_COLUMNS
from impala_radar.datasets.formats import open_dataset

from ..datasets import boreas_frame_or_skip
from ._dataset_files import navtech_folder


def _read(path):
    with MissionReader(path) as r:
        return ([m.data for m in r.messages(["radar/beams"])], [m.t_ns for m in r.messages(["radar/beams"])],
                [(m.t_ns, m.data) for m in r.messages(["truth/pose"])] if "truth/pose" in r.topics else [])


def test_real_frame_imports_as_400_beams_of_6848_bins_and_300_m(tmp_path, capsys):
    folder = boreas_frame_or_skip()
    png = sorted((folder / "radar").glob("*.png"))[0]
    out = tmp_path / "boreas.mcap"
    assert main(["import", "boreas", str(folder), "-o", str(out), "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "6848 bins x 0.04381 m = 300.0 m" in text and "beams:        400" in text
    assert "rows dropped: 0" in text and "chirp direction" in text
    pixels = np.asarray(Image.open(png))  # independent decoder: Pillow
    assert pixels.shape == (400, 6859) and set(np.unique(pixels[:, 10])) == {0, 255}  # chirp, not validity
    beams, times, _ = _read(out)
    assert len(beams) == 400  # every azimuth kept
    cfg = beams[0].config
    assert cfg.name == "navtech-cir304h-boreas" and cfg.n_bins == 6848 == pixels.shape[1] - 11
    assert int(png.stem) > 1632182400 * 10**6 and cfg.range_per_bin_m == pytest.approx(0.04381, rel=1e-12)
    assert cfg.range_max_m == pytest.approx(6848 * 0.04381) and 299.0 < cfg.range_max_m < 301.0
    # range: the Boreas documentation's `range_m = bin_index * resolution + radar_offset`, radar_offset -0.31 m
    k = np.array([0, 1, 57, 6847])
    assert np.allclose(cfg.range_of_bin_m(k), k * 0.04381 - 0.31, rtol=0, atol=1e-12)
    # chirp: column 10 = 255 is an up-chirp (pyboreas: chirp_type = col10 == 255, 1 = 'up-chirp'), 0 down
    assert [b.chirp for b in beams] == [1 if f == 255 else -1 for f in pixels[:, 10]]
    assert {b.chirp for b in beams[0::2]} == {-1} and {b.chirp for b in beams[1::2]} == {1}  # they alternate
    # timing: the row stamps (us) of the PNG, in order, one turn ~ 0.25 s
    stamps_us = [int.from_bytes(bytes(row[:8].tolist()), "little") for row in pixels]
    assert times == [s * 1000 for s in stamps_us] and times[0] == int(png.stem) * 1000
    assert np.all(np.diff(times) > 0) and 0.24e9 < times[-1] - times[0] < 0.26e9
    # azimuth: clockwise encoder -> CCW azimuth decreasing by 0.9 deg per row, in acquisition order
    encoder = pixels[:, 8].astype(int) + 256 * pixels[:, 9].astype(int)
    az = np.array([b.azimuth_rad for b in beams])
    assert np.allclose(az, wrap_angle(-encoder * 2 * np.pi / 5600), atol=1e-12)
    assert np.allclose(wrap_angle(np.diff(az)), -np.radians(0.9), atol=1e-9)
    assert [b.index for b in beams] == list(range(400)) and {b.turn for b in beams} == {0}
    # round trip: linear power of the half-dB counts, P = 10^(count * 0.5 / 10)
    assert all(np.allclose(b.up, 10.0 ** (pixels[i, 11:] * 0.05), rtol=1e-6) for i, b in enumerate(beams))


@pytest.mark.parametrize(("t0_us", "res"), [(1632182400 * 10**6 - 1, 0.0596), (1632182400 * 10**6, 0.04381)])
def test_resolution_by_date(tmp_path, t0_us, res):
    navtech_folder(tmp_path, n_scans=1, t0_us=t0_us, n_bins=30)
    ds = open_dataset("boreas", str(tmp_path))
    assert ds.config.range_per_bin_m == pytest.approx(res, rel=1e-12) and ds.config.n_bins == 30


def _poses_csv(path, t_us, east, north, roll, heading):
    rows = [",".join(BOREAS_POSE_COLUMNS)]
    for t, e, n, r, h in zip(t_us, east, north, roll, heading, strict=True):
        rows.append(f"{t},{float(e)!r},{float(n)!r},0.5,0,0,0,{float(r)!r},0.0,{float(h)!r},0,0,0")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(rows) + "\n")


def test_truth_straight_drive_is_forward_along_x(tmp_path):
    """The radar frame z-down (roll = pi, as in the dataset): x axis at 'heading' CCW from east.
    A car driving 2.5 m per scan along that axis is x += 2.5, y = 0, yaw = 0 in frame odom."""
    scans = navtech_folder(tmp_path, n_scans=4)
    t_us = [int(p.stem) for p in scans]
    h = 0.3
    d = 2.5 * np.arange(4)
    _poses_csv(tmp_path / "applanix" / "radar_poses.csv", t_us, 100 + d * math.cos(h), 50 + d * math.sin(h),
               [math.pi] * 4, [h] * 4)
    out = tmp_path.parent / f"{tmp_path.name}-b.mcap"  # beside the dataset folder (inside is refused)
    assert main(["import", "boreas", str(tmp_path), "-o", str(out), "--no-progress"]) == 0
    _, _, truth = _read(out)
    assert [t for t, _ in truth] == [t * 1000 for t in t_us]  # GPSTime = PNG name
    xyt = np.array([p.as_array() for _, p in truth])
    assert np.allclose(xyt, np.column_stack([d, np.zeros(4), np.zeros(4)]), atol=1e-9)


def test_truth_left_turn_is_positive_yaw_and_y(tmp_path):
    """A circle to the left (CCW seen from above) of radius 20 m: heading grows, the car ends
    up on its left (y > 0) with yaw = the angle turned; the same motion with the frame z up
    (roll = 0) has its heading of opposite sign and gives the same poses."""
    scans = navtech_folder(tmp_path, n_scans=5)
    t_us = [int(p.stem) for p in scans]
    a = np.radians(10.0) * np.arange(5)  # turned angle
    east, north = 20 * np.sin(a), 20 * (1 - np.cos(a))  # start heading east
    for roll, sign in ((math.pi, 1.0), (0.0, -1.0)):
        _poses_csv(tmp_path / "applanix" / "radar_poses.csv", t_us, east, north, [roll] * 5, list(sign * a))
        report_ds = open_dataset("boreas", str(tmp_path))
        from impala_radar.datasets.common import ImportReport

        t, xyt = report_ds.truth(ImportReport())
        assert np.allclose(xyt[:, 2], a, atol=1e-12)
        assert np.allclose(xyt[:, :2], np.column_stack([east, north]), atol=1e-9)
        assert np.all(xyt[1:, 1] > 0)
