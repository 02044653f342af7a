"""RADIATE: the 6 real fog_6_0 scans through `impala-flow import radiate` (shape, timing from
the frame times, azimuth direction checked on the data, resolution, round trip through the
recorder), and GPS_IMU_Twist notes on synthetic files (the logs' quirks and the truth:
test_import_radiate_logs.py)."""

from __future__ import annotations

import math
from decimal import Decimal

import cv2
import numpy as np
import pytest
from PIL import Image

from impala_flow.msgs import wrap_angle

from ..datasets import radiate_head_or_skip
from ._dataset_files import radiate_folder, radiate_time
from ._import_cli import import_radiate


def _import(folder, out, *extra):
    beams, truth, _ = import_radiate(folder, out, *extra)
    return beams, truth


def _frame_times_ns(folder):
    """Frame times of Navtech_Polar.txt, parsed here with Decimal (independent of the reader)."""
    lines = (folder / "Navtech_Polar.txt").read_text().split("\n")
    return [int(Decimal(ln.split()[-1]) * 10**9) for ln in lines if ln.strip()]


@pytest.fixture(scope="module")
def real(tmp_path_factory):
    folder = radiate_head_or_skip()
    beams, _ = _import(folder, tmp_path_factory.mktemp("radiate") / "fog.mcap")
    return folder, beams


def test_real_scans_shape_resolution_and_round_trip(real):
    folder, beams = real
    pngs = sorted((folder / "Navtech_Polar").glob("*.png"))
    assert len(pngs) == 6 and len(beams) == 6 * 400
    cfg = beams[0][1].config
    assert cfg.name == "navtech-cts350x-radiate" and cfg.n_bins == 576 and cfg.beams_per_turn == 400
    assert cfg.range_per_bin_m == pytest.approx(0.17361, rel=1e-12)
    assert cfg.range_max_m == pytest.approx(100.0, abs=0.01)  # 576 x 0.17361 = 99.999 m
    assert cfg.range_offset_m == pytest.approx(0.5 * 0.17361)
    for k, png in enumerate(pngs):  # column j of scan k is beam (turn k, index j)
        pixels = np.asarray(Image.open(png))
        assert pixels.shape == (576, 400)
        turn = [b for _, b in beams[400 * k: 400 * (k + 1)]]
        assert {b.turn for b in turn} == {k} and [b.index for b in turn] == list(range(400))
        assert all(np.allclose(b.up, 10.0 ** (pixels[:, j] * 0.05), rtol=1e-6)  # half-dB counts -> power
                   for j, b in enumerate(turn))


def test_real_scans_timing_from_frame_times(real):
    folder, beams = real
    frames = _frame_times_ns(folder)
    t = np.array([ti for ti, _ in beams], dtype=np.int64)
    assert np.all(np.diff(t) >= 0)
    gaps = np.diff(frames)
    period = int(np.median(gaps))  # median of (t[k+m] - t[k]) / m, m = max(1, min(20, n // 4)) = 1 here
    assert 0.23e9 < period < 0.25e9  # "about 0.25 s"; here 0.233-0.244 s between frames
    assert beams[0][1].config.rotation_hz == pytest.approx(1e9 / period, abs=1e-3)
    for k in range(6):
        tk = t[400 * k: 400 * (k + 1)]
        span = min(period, gaps[k]) if k < 5 else period
        assert tk[0] == frames[k]
        assert tk.tolist() == [frames[k] + j * span // 400 for j in range(400)]
        assert tk[-1] < (frames[k + 1] if k < 5 else frames[k] + period)


def _cartesian(beams, azimuth_sign, cell_m=0.25, half_m=60.0):
    """Vehicle-frame image (row 0 = +x forward, column 0 = +y left) of one turn's beams."""
    power = 10.0 * np.log10(np.stack([b.up for b in beams]).astype(np.float32))  # beams x bins, dB
    az = azimuth_sign * np.array([b.azimuth_rad for b in beams])
    n = int(half_m / cell_m)
    xs = (np.arange(2 * n) - n + 0.5)[::-1] * cell_m
    x, y = np.meshgrid(xs, xs, indexing="ij")
    col = (np.mod(np.arctan2(y, x) - az[0], 2 * np.pi) / (2 * np.pi) * len(az) * np.sign(
        wrap_angle(az[1] - az[0]))) % len(az)
    cfg = beams[0].config
    rbin = cfg.bin_of_range(np.hypot(x, y))
    return cv2.remap(np.ascontiguousarray(power.T), col.astype(np.float32), rbin.astype(np.float32),
                     cv2.INTER_LINEAR, borderValue=0.0)


def test_real_scans_rotation_direction(real):
    """Which way do the columns turn? Two consecutive scans give the same forward translation
    under both hypotheses (a mirror about the forward axis keeps it): ~2.8 m per 0.24 s. What
    tells them apart is the road: RADIATE drives in the UK, on the left, so the nearest wall
    must be on the car's left. With the reader's (clockwise) azimuths, it is, on every scan."""
    _, beams = real
    turns = [[b for _, b in beams[400 * k: 400 * (k + 1)]] for k in range(6)]
    for sign in (1.0, -1.0):  # reader's azimuths, and their mirror
        a, b = _cartesian(turns[0], sign), _cartesian(turns[1], sign)
        (dcol, drow), response = cv2.phaseCorrelate(a, b, cv2.createHanningWindow(a.shape[::-1], cv2.CV_32F))
        assert response > 0.3
        assert 1.5 < drow * 0.25 < 4.0  # the world moves back: the car drives forward ~10 m/s
        assert abs(dcol * 0.25) < 0.3
    for turn in turns:
        pts = [(r, b.azimuth_rad, p) for b in turn for r, p in zip(  # power in dB (the pixels' scale)
            turn[0].config.range_of_bin_m(np.arange(576)), 10.0 * np.log10(b.up), strict=True)]
        r, az, p = map(np.array, zip(*pts, strict=True))
        x, y = r * np.cos(az), r * np.sin(az)
        band = (np.abs(x) < 20) & (r > 3)
        edges = np.arange(-15, 15.01, 0.5)
        prof = np.histogram(y[band], edges, weights=p[band])[0] / np.maximum(np.histogram(y[band], edges)[0], 1)
        yc = (edges[:-1] + edges[1:]) / 2
        left = yc[yc > 1][np.argmax(prof[yc > 1])]
        right = -yc[yc < -1][np.argmax(prof[yc < -1])]
        assert left < 5.0 < 8.0 < right  # nearest wall ~4 m on the left, >= 9 m on the right


def _gps(folder, times, lat, lon, yaw):
    (folder / "GPS_IMU_Twist").mkdir()
    lines = []
    for k, (t, la, lo, th) in enumerate(zip(times, lat, lon, yaw, strict=True), start=1):
        q = (0.0, 0.0, math.sin(th / 2), math.cos(th / 2))
        cov = "0, 0, 0"
        body = [f"{la!r}, {lo!r}, 50.0", cov, cov, cov, ", ".join(repr(v) for v in q)] + [cov] * 13
        (folder / "GPS_IMU_Twist" / f"{k:06d}.txt").write_text("\n".join(body) + "\n")
        lines.append(f"Frame: {k:06d} Time: {radiate_time(t)}")
    (folder / "GPS_IMU_Twist.txt").write_text("\n".join(lines) + "\n")


def test_gps_outside_the_scans_is_a_note(tmp_path, capsys):
    radiate_folder(tmp_path, ["100.00", "100.25"])
    _gps(tmp_path, ["164.0", "164.1"], [56.0, 56.0001], [-3.2, -3.2], [0.0, 0.0])
    _, truth = _import(tmp_path, tmp_path / "r.mcap")
    assert truth == []
    out = capsys.readouterr().out
    assert "do not overlap the scans" in out and "truth poses:  0" in out


def test_without_gps_a_note(tmp_path, capsys):
    radiate_folder(tmp_path, ["100.00", "100.25"])
    beams, truth = _import(tmp_path, tmp_path / "r.mcap")
    assert len(beams) == 800 and truth == []
    assert "no GPS_IMU_Twist/ folder" in capsys.readouterr().out
