"""Navtech polar PNG reader and Oxford ground truth, on the 11 real Oxford scans.

The data folder is test data, never copied into the repo: found next to the repository
(``../shared/data/oxford-radar-robotcar-sample``) or under ``$IMPALA_FLOW_TEST_DATA``
(the data root, or the sample folder itself). Tests skip cleanly when it is absent.
"""

from pathlib import Path

import numpy as np
import pytest

import impala_msgs
from impala_flow import msgs
from impala_radar.datasets.navtech_png import read_navtech_png
from impala_radar.datasets.oxford import (
    NAVTECH_CTS350X,
    OxfordRelativePoses,
    compose_relative_poses,
    iter_oxford_folder,
    read_oxford_ground_truth,
    scan_to_beams,
)

from ..datasets import oxford_sample_or_skip


@pytest.fixture(scope="module")
def sample() -> Path:
    return oxford_sample_or_skip()


@pytest.fixture(scope="module")
def scan_paths(sample):
    return sorted((sample / "radar").glob("*.png"))


def test_config_range_bin():
    # 4.38 cm per bin: the value measured on the sample (see impala_radar.datasets.oxford)
    assert NAVTECH_CTS350X.range_per_bin_m == pytest.approx(0.0438, rel=1e-12)
    assert NAVTECH_CTS350X.doppler is False and NAVTECH_CTS350X.beams_per_turn == 400
    assert NAVTECH_CTS350X.rotation_hz == 4.0
    # the Oxford SDK puts bin k at its centre: (k + 0.5) * resolution
    assert NAVTECH_CTS350X.range_of_bin_m(0) == pytest.approx(0.0219, rel=1e-12)
    assert NAVTECH_CTS350X.range_of_bin_m(100) == pytest.approx(100.5 * 0.0438, rel=1e-12)
    assert NAVTECH_CTS350X.bin_of_range(100.5 * 0.0438) == pytest.approx(100.0, rel=1e-12)


def test_reader_geometry_parameters(sample):
    """range_resolution_m, range_offset_bins and azimuth_offset_deg reach every beam's config
    and azimuth, with the documented formulas."""
    from impala_radar.datasets.oxford import OxfordDataset

    pngs = sorted((sample / "radar").glob("*.png"))
    raw = read_navtech_png(pngs[0])
    base = OxfordDataset(sample, azimuth_offset_deg=0.0).read_scan(0)
    ds = OxfordDataset(sample, range_resolution_m=0.0438, range_offset_bins=0.0, azimuth_offset_deg=1.5)
    assert ds.config.range_per_bin_m == pytest.approx(0.0438, rel=1e-12)
    assert ds.config.range_offset_m == 0.0 and ds.config.n_bins == 3779 - 11
    assert ds.config.range_max_m == pytest.approx(3768 * 0.0438)
    shifted = ds.read_scan(0)
    expected = msgs.wrap_angle(np.radians(1.5) - raw.encoder * (2 * np.pi / 5600))
    assert np.allclose(shifted.azimuth_rad, expected, atol=1e-12)
    # a positive offset turns the scan counter-clockwise (to the left) by that angle
    assert np.allclose(msgs.wrap_angle(shifted.azimuth_rad - base.azimuth_rad), np.radians(1.5), atol=1e-12)
    # encoder counts increase: the CCW azimuth decreases over the turn (clockwise Navtech)
    steps = msgs.wrap_angle(np.diff(base.azimuth_rad))
    assert np.allclose(steps, -2 * np.pi / 400, atol=1e-9)


def test_scan_timestamps_and_azimuths(scan_paths):
    assert len(scan_paths) == 11
    scan = read_navtech_png(scan_paths[0])
    t = scan.timestamps_ns
    assert t.dtype == np.int64 and t.shape == (400,)
    assert np.all(np.diff(t) > 0)
    assert 240e6 < t[-1] - t[0] < 260e6  # one turn at 4 Hz, about 252 ms
    assert t[0] == int(scan_paths[0].stem) * 1000  # file name is the first beam time (us)
    assert np.allclose(np.diff(np.degrees(scan.azimuth_rad)), 0.9)
    assert scan.valid.all() and scan.power.shape == (400, 3768)
    assert scan.power.dtype == np.float32


def test_power_equals_png_pixels_read_with_pillow(scan_paths):
    from PIL import Image

    path = scan_paths[5]
    pixels = np.asarray(Image.open(path))
    scan = read_navtech_png(path)
    assert np.array_equal(scan.power, pixels[:, 11:].astype(np.float32) / np.float32(255))
    stamps_us = [int.from_bytes(bytes(row[:8].tolist()), "little") for row in pixels[:3]]
    assert (scan.timestamps_ns[:3] // 1000).tolist() == stamps_us


def test_scan_to_beams(scan_paths):
    scan = read_navtech_png(scan_paths[1])
    beams = scan_to_beams(scan, 7, NAVTECH_CTS350X)
    assert len(beams) == 400
    times = [t for t, _ in beams]
    assert times == sorted(times) and all(type(t) is int for t in times)
    t0, b0 = beams[0]
    assert isinstance(b0, impala_msgs.RadarBeam) and b0.turn == 7 and b0.index == 0
    assert b0.down.dtype == np.float32 and b0.down.size == 0
    # linear power from the half-dB pixel counts: P = 10^(count * 0.5 / 10)
    import cv2

    counts = cv2.imread(str(scan_paths[1]), cv2.IMREAD_UNCHANGED)[0, 11:].astype(np.float64)
    assert np.allclose(b0.up, 10.0 ** (counts * 0.05), rtol=1e-6) and b0.config is NAVTECH_CTS350X
    assert b0.config.name == "navtech-cts350x-oxford"
    # clockwise encoder angle -> counter-clockwise beam azimuth
    assert b0.azimuth_rad == pytest.approx(-scan.azimuth_rad[0])
    assert beams[-1][1].azimuth_rad == pytest.approx(2 * np.pi - scan.azimuth_rad[-1])


def test_truth_distances_between_the_scans(sample, scan_paths):
    rel = read_oxford_ground_truth(sample / "gt" / "radar_odometry.csv")
    ours = np.isin(rel.source_radar_t_ns, [int(p.stem) * 1000 for p in scan_paths])
    assert ours.sum() == 11
    step_m = np.hypot(rel.x_m[ours], rel.y_m[ours])
    assert np.all((step_m > 1.5) & (step_m < 2.6))
    # the pose time is the middle of the scan
    mid = rel.source_t_ns[ours] - rel.source_radar_t_ns[ours]
    assert np.all(np.abs(mid - 126e6) < 3e6)


def _rel(x, y, yaw):
    n = len(x)
    t = np.arange(n + 1, dtype=np.int64) * 250_000_000
    z = np.zeros(n, dtype=np.int64)
    return OxfordRelativePoses(t[1:].copy(), t[:-1].copy(), z, z, np.asarray(x, float),
                               np.asarray(y, float), np.asarray(yaw, float))


def test_composition_straight_and_circle():
    steps = [1.0, 2.0, 0.5, 1.5]
    t, xyt = compose_relative_poses(_rel(steps, [0] * 4, [0] * 4), origin_xyt=(1.0, 2.0, np.pi / 2))
    assert np.allclose(xyt[:, 0], 1.0)
    assert np.allclose(xyt[:, 1], 2.0 + np.concatenate([[0.0], np.cumsum(steps)]))
    assert t.tolist() == [0, 250_000_000, 500_000_000, 750_000_000, 1_000_000_000]
    # twelve identical chords of a circle, turning 30 degrees each, close the loop
    a = np.radians(30.0)
    chord = 2 * 10.0 * np.sin(a / 2)
    step = _rel([chord * np.cos(a / 2)] * 12, [chord * np.sin(a / 2)] * 12, [a] * 12)
    _, ring = compose_relative_poses(step)
    assert np.allclose(ring[-1], ring[0], atol=1e-9)
    assert np.allclose(np.hypot(ring[:, 0], ring[:, 1] - 10.0), 10.0)  # centre on the left
    with pytest.raises(ValueError, match="chain"):
        broken = _rel([1.0, 1.0], [0, 0], [0, 0])
        broken.destination_t_ns[1] += 1
        compose_relative_poses(broken)


def test_ground_truth_frame_matches_gps(sample):
    """Independent check of the frame convention: the composed odometry is a rigid motion
    of the GPS track (easting, northing) only with y and yaw flipped to y-left / CCW."""
    rel = read_oxford_ground_truth(sample / "gt" / "radar_odometry.csv")
    gps = np.loadtxt(sample / "gps" / "gps.csv", delimiter=",", skiprows=1, usecols=(0, 8, 9))

    def aligned_rms(r):
        t, xyt = compose_relative_poses(r)
        t_s = t * 1e-9
        ref = np.column_stack([np.interp(t_s, gps[:, 0] * 1e-6, gps[:, 2]),
                               np.interp(t_s, gps[:, 0] * 1e-6, gps[:, 1])])
        p = xyt[:, :2] - xyt[:, :2].mean(0)
        q = ref - ref.mean(0)
        u, _, vt = np.linalg.svd(p.T @ q)
        d = np.diag([1.0, np.sign(np.linalg.det(u @ vt))])  # proper rotation only
        rot = (u @ d @ vt).T
        return np.sqrt(np.mean(np.sum((p @ rot.T - q) ** 2, axis=1)))

    mirrored = OxfordRelativePoses(rel.source_t_ns, rel.destination_t_ns, rel.source_radar_t_ns,
                                   rel.destination_radar_t_ns, rel.x_m, -rel.y_m, -rel.yaw_rad)
    assert aligned_rms(rel) < 10.0
    assert aligned_rms(mirrored) > 10 * aligned_rms(rel)


def test_iter_oxford_folder(sample):
    items = list(iter_oxford_folder(sample))
    config = next(m for _, s, m in items if s == "beams").config
    assert config.n_bins == 3768 and config.range_offset_m == pytest.approx(0.0219)
    # rotation measured on the file times: the scans start about 0.25 s apart
    starts = np.diff(sorted(int(p.stem) for p in (sample / "radar").glob("*.png")))
    assert config.rotation_hz == pytest.approx(1e6 / np.median(starts), abs=1e-3)
    times = [t for t, _, _ in items]
    assert times == sorted(times)
    beams = [m for _, s, m in items if s == "beams"]
    truth = [(t, m) for t, s, m in items if s == "truth"]
    assert len(beams) == 11 * 400
    assert [b.turn for b in beams[::400]] == list(range(11))
    assert len(truth) == 12 and all(isinstance(m, msgs.Pose2D) for _, m in truth)
    assert truth[0][1].as_array().tolist() == [0.0, 0.0, 0.0]
    xy = np.array([m.as_array()[:2] for _, m in truth])
    step_m = np.hypot(*np.diff(xy, axis=0).T)
    assert np.all((step_m > 1.5) & (step_m < 2.6))
    assert xy[-1, 0] > 15.0  # driving forward along x
    # each scan's truth pose sits at the middle of its beams
    first_scan = [t for t, s, m in items if s == "beams" and m.turn == 0]
    assert abs(truth[1][0] - (first_scan[0] + first_scan[-1]) / 2) < 2e6
