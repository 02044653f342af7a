"""RADIATE logs read as recorded, through `impala-flow import radiate` on synthetic folders
(each quirk of the real logs) and on the real Edinburgh head when it is there: unpadded
nanoseconds, fixes written twice, a GPS clock step back, stale fixes, missing GPS files, a
radar time going back, a late-stamped backlog, a 1.6 s radar gap, frames from 401, and the
truth: GPS positions, heading from the course over ground while moving, unknown at rest."""

from __future__ import annotations

import math
import re
from decimal import Decimal

import numpy as np
import pytest

from impala_flow.msgs import HEADING_UNKNOWN_VAR_RAD2, wrap_angle
from impala_radar.datasets.common import ImportReport
from impala_radar.datasets.formats import open_dataset

from ..datasets import _find
from ._dataset_files import radiate_folder, radiate_gps
from ._import_cli import import_block, import_radiate

P_NS = 250_000_000
T0_NS = 1_549_986_548_010_563_645  # a RADIATE time with a leading zero in its nanoseconds


def _radiate_ns(text):
    """RADIATE's rule, with Decimal: the digits after the point are nanoseconds (left-padded)."""
    s, _, frac = text.partition(".")
    return int((Decimal(s) + Decimal(int(frac or "0")) / Decimal(10**9)) * 10**9)


def _first_beam_times(beams):
    out = {}
    for t, b in beams:
        out.setdefault(b.turn, t)
    return [out[k] for k in sorted(out)]


def test_unpadded_nanoseconds_read_as_radiates_sdk(tmp_path, capsys):
    s0 = T0_NS // 10**9  # one frame a second (a 1 Hz turn), every fraction with leading zeros
    times = [(s0 + k) * 10**9 + j for k, j in enumerate([10_563_645, 7, 12_345, 999, 4_000_000, 1])]
    radiate_folder(tmp_path, times, rows=4, cols=8)
    written = [ln.split()[-1] for ln in (tmp_path / "Navtech_Polar.txt").read_text().splitlines()]
    assert written[0] == "1549986548.10563645" and sum(len(w.split(".")[1]) < 9 for w in written) == 6
    beams, _, _ = import_radiate(tmp_path, tmp_path / "r.mcap")
    assert _first_beam_times(beams) == [_radiate_ns(w) for w in written] == times
    block = import_block(capsys.readouterr().out)
    assert block["padded times"].startswith("6 of 6 lines of Navtech_Polar.txt")


def test_radar_time_going_back_or_repeated_is_dropped_and_reported(tmp_path, capsys):
    t = [T0_NS + k * P_NS for k in range(6)]
    radiate_folder(tmp_path, [t[0], t[1], t[1] - 150_000_000, t[2], t[2], t[3]], rows=4, cols=8)
    beams, _, _ = import_radiate(tmp_path, tmp_path / "r.mcap")
    assert _first_beam_times(beams) == [t[0], t[1], t[2], t[3]]  # frames 3 and 5 dropped, the rest read
    assert [b.turn for _, b in beams][::8] == [0, 1, 2, 3]
    out = capsys.readouterr().out
    assert "turns:        4" in out
    assert import_block(out)["times back"] == ("radar: 2 line(s) dropped (time going back or repeated): "
                                         "line 3 (frame 000003, -0.150 s); line 5 (frame 000005, +0.000 s)")


def test_a_1_6_s_radar_gap_is_reported_and_no_beam_spreads_over_it(tmp_path, capsys):
    t = [T0_NS + k * P_NS for k in range(10)] + [T0_NS + 9 * P_NS + 1_600_000_000 + k * P_NS for k in range(10)]
    radiate_folder(tmp_path, t, rows=4, cols=8)
    beams, _, _ = import_radiate(tmp_path, tmp_path / "r.mcap")
    assert _first_beam_times(beams) == t  # no frame retimed: the frames after the gap do not catch up
    before = [bt for bt, b in beams if b.turn == 9]
    assert before == [t[9] + j * P_NS // 8 for j in range(8)] and before[-1] < t[9] + P_NS < t[10]
    block = import_block(capsys.readouterr().out)
    # 1.6 s = 6.4 turns: 5 turns missing (round(6.4) - 1)
    assert block["radar gaps"] == (f"1 gap(s), 5 turns missing; longest 1.600 s before frame 000011 "
                                   f"(t = {t[10] // 10**9}.{t[10] % 10**9:09d} s)")
    assert block["late frames"].startswith("none")


def test_a_late_stamped_backlog_is_put_back_on_the_turn_clock(tmp_path, capsys):
    """Frame 21 stamped 0.8 s late and the next frames catching up by 20 ms each, as the real
    head's frames 131-176: the turns are not missing, the stamps are late."""
    true = np.array([T0_NS + k * P_NS for k in range(160)], dtype=np.int64)
    late_ns = np.array([0] * 20 + [max(0, 800_000_000 - 20_000_000 * j) for j in range(140)], dtype=np.int64)
    radiate_folder(tmp_path, (true + late_ns).tolist(), rows=4, cols=8)
    beams, _, _ = import_radiate(tmp_path, tmp_path / "r.mcap")
    n_late = int(np.sum(late_ns > P_NS // 10))  # late by more than 0.1 turn: on the clock; the others as stamped
    assert _first_beam_times(beams) == np.where(late_ns > P_NS // 10, true, true + late_ns).tolist()
    block = import_block(capsys.readouterr().out)
    assert block["late frames"].startswith(f"{n_late} frame(s) stamped late by > 25 ms (up to 0.800 s, frame 000021")
    assert block["radar gaps"].startswith("none")
    beams, _, _ = import_radiate(tmp_path, tmp_path / "k.mcap", "--keep-frame-stamps")
    assert _first_beam_times(beams) == (true + late_ns).tolist()
    assert block["late frames"] != import_block(capsys.readouterr().out)["late frames"]


def _drive(t_s):
    """A known drive (ENU): 6 s at rest, 2 m/s^2 to 10 m/s heading 30 deg, a 5 deg/s turn for
    6 s, straight, 2 m/s^2 down to rest. Returns east, north, heading (ENU), speed at t_s."""
    dt = 0.001
    tt = np.arange(0.0, t_s.max() + dt, dt)
    v = np.clip(2.0 * (tt - 6.0), 0.0, 10.0)
    v = np.minimum(v, np.clip(2.0 * (22.0 - tt), 0.0, 10.0))
    psi = np.radians(30.0) + np.radians(5.0) * np.clip(tt - 12.0, 0.0, 6.0)
    e = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] * np.cos(psi[1:]) + v[:-1] * np.cos(psi[:-1])) * dt)])
    n = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] * np.sin(psi[1:]) + v[:-1] * np.sin(psi[:-1])) * dt)])
    return (np.interp(t_s, tt, e), np.interp(t_s, tt, n), np.interp(t_s, tt, psi), np.interp(t_s, tt, v))


def test_truth_heading_from_the_course_over_ground_known_only_while_moving(tmp_path, capsys):
    radiate_folder(tmp_path, [T0_NS + k * P_NS for k in range(112)], rows=4, cols=8)  # 28 s of scans
    t_fix = T0_NS - 1_000_000_000 + np.arange(600) * 50_000_000  # 20 Hz from 1 s before
    ts = (t_fix - T0_NS) / 1e9
    east, north, psi, speed = _drive(ts)
    east = east + 0.002 * np.sin(ts * 1.7) * (speed == 0)  # a real receiver's fix moves a little at rest
    radiate_gps(tmp_path, t_fix.tolist(), east, north, psi - np.radians(7.0))  # the IMU off by -7 deg
    _, truth, _ = import_radiate(tmp_path, tmp_path / "r.mcap")
    block = import_block(capsys.readouterr().out)
    t = np.array([ti for ti, _ in truth])
    inside = (t_fix >= T0_NS) & (t_fix <= T0_NS + 112 * P_NS)
    assert t.tolist() == t_fix[inside].tolist()
    e, n, h, v = east[inside], north[inside], psi[inside], speed[inside]
    xyt = np.array([p.as_array() for _, p in truth])
    cov = np.array([p.cov_xyt for _, p in truth])
    known = np.array([p.heading_known for _, p in truth])
    assert known[v >= 2.1].all() and not known[v <= 1.9].any()
    psi0 = h[np.argmax(known)]  # x along the first known course
    c, s = math.cos(psi0), math.sin(psi0)
    assert np.allclose(xyt[:, 0], c * (e - e[0]) + s * (n - n[0]), atol=0.005)
    assert np.allclose(xyt[:, 1], -s * (e - e[0]) + c * (n - n[0]), atol=0.005)
    err = np.degrees(np.abs(wrap_angle(xyt[:, 2] - (h - psi0))))
    smooth = (np.abs(ts[inside] - 12.0) > 0.5) & (np.abs(ts[inside] - 18.0) > 0.5)  # away from the yaw-rate steps
    assert err[known & smooth].max() < 0.2
    assert err[known].max() < 1.25  # a 1 s chord at a 5 deg/s step of the yaw rate: <= 5 x 1 / 4 deg
    rest0 = ts[inside] < 6.0
    assert (xyt[rest0, 2] == 0.0).all() and (cov[rest0, 2, 2] == HEADING_UNKNOWN_VAR_RAD2).all()
    rest1 = ts[inside] > 23.0  # stopped again: theta held at the last known heading
    assert np.allclose(xyt[rest1, 2], h[known][-1] - psi0, atol=1e-3) and not known[rest1].any()
    assert np.allclose(cov[known, 2, 2], (0.06 / v[known]) ** 2 + math.radians(1.0) ** 2, rtol=0.05)
    rot = np.array([[c, s], [-s, c]])
    assert np.allclose(cov[:, :2, :2], rot @ np.diag([0.09, 0.16]) @ rot.T, atol=1e-12)
    assert block["IMU yaw"].startswith("-7.0 deg from the course while moving")
    assert block["heading"].startswith("from the GPS course over ground (>= 2 m/s over 1 s;")
    assert f"on {int(known.sum())} of {len(t)} poses; unknown on the rest" in block["heading"]
    assert "origin the first fix, x along the first course over ground" in block["truth"]


def test_gps_log_quirks_repeats_clock_step_back_stale_fix_missing_file(tmp_path, capsys):
    """A 20 Hz GPS at 10 m/s whose log's clock steps back 0.36 s at fix 100 (the receiver keeps
    its rate: the fixes stay 0.5 m apart), a stray stamp 1 s back at fix 60, a stale fix and a
    missing file: the step is re-joined (every later fix back at its true time, none lost), the
    stray stamp dropped, all of it reported in the block and the metadata."""
    radiate_folder(tmp_path, [T0_NS + k * P_NS for k in range(40)], rows=4, cols=8)
    true = T0_NS + np.arange(200) * 50_000_000
    stamped = true.copy()
    stamped[100:] -= 360_000_000  # the log's clock steps back 0.36 s at fix 100
    stamped[60] -= 1_000_000_000  # one stray stamp
    east = np.arange(200) * 0.5  # 10 m/s east
    east[150] = east[149]  # fix 150: a stale fix (the previous position at a new time)
    radiate_gps(tmp_path, stamped.tolist(), east, np.zeros(200), np.zeros(200), index_only=(170,))
    _, truth, meta = import_radiate(tmp_path, tmp_path / "r.mcap")
    block = import_block(capsys.readouterr().out)
    for key in ("padded times", "repeats", "times back", "clock steps", "late frames", "radar gaps", "GPS gaps",
                "GPS files", "truth", "heading", "IMU yaw"):  # the same facts in the mission file's metadata
        assert meta[key.replace(" ", "_")] == block[key]
    kept = np.ones(200, bool)
    kept[[60, 150, 170]] = False
    inside = (true >= T0_NS) & (true <= T0_NS + 40 * P_NS)
    t = [ti for ti, _ in truth]
    assert t == true[kept & inside].tolist()  # every fix after the step at its true time
    x = np.array([p.x_m for _, p in truth])
    assert np.allclose(np.diff(x) / (np.diff(t) * 1e-9), 10.0, atol=1e-6)  # no jump at the step: 10 m/s
    assert block["clock steps"] == ("GPS: 1 step(s) back of the log's clock re-joined (line 201, fix 000201: stamps "
                                    "from there on moved +0.360 s, one period after the last stamp before the step: "
                                    "the receiver kept its rate)")
    assert block["times back"].startswith("radar: none; GPS: 2 line(s) dropped (time going back or repeated): "
                                          "line 121 (fix 000121, -0.950 s)")
    assert block["repeats"] == ("GPS: 198 fix(es) written twice merged; 1 stale (a new time with "
                                "the previous position) merged; 0 same time with another fix (first kept)")
    assert block["GPS files"] == ("2 of 398 listed in GPS_IMU_Twist.txt missing (first frame 000341, "
                                  "line 341): those fixes not read")


def test_frames_from_401_import(tmp_path, capsys):
    """The held-out drive may be frames 401-707 of a sequence: nothing assumes frame 1."""
    times = [T0_NS + k * P_NS for k in range(12)]
    radiate_folder(tmp_path, times, rows=4, cols=8, first=401)
    t_fix = T0_NS + np.arange(60) * 50_000_000
    radiate_gps(tmp_path, t_fix.tolist(), np.arange(60) * 0.5, np.zeros(60), np.zeros(60), first=8021)
    beams, truth, _ = import_radiate(tmp_path, tmp_path / "r.mcap")
    assert _first_beam_times(beams) == times and len(truth) == 60
    assert sorted(p.name for p in (tmp_path / "Navtech_Polar").glob("*.png"))[0] == "000401.png"
    assert "turns:        12" in capsys.readouterr().out


def test_a_listed_frame_without_png_is_a_gap_not_an_error(tmp_path, capsys):
    paths = radiate_folder(tmp_path, [T0_NS + k * P_NS for k in range(8)], rows=4, cols=8)
    paths[4].unlink()
    beams, _, _ = import_radiate(tmp_path, tmp_path / "r.mcap")
    before = [bt for bt, b in beams if b.turn == 3]
    assert len(_first_beam_times(beams)) == 7 and before[-1] < T0_NS + 4 * P_NS
    block = import_block(capsys.readouterr().out)
    assert block["radar gaps"].endswith("1 frame(s) listed without a PNG (first 000005), not read")


# --- the real Edinburgh head (skips when absent) ---

def _head():
    folder = _find("radiate-edinburgh-head", "Navtech_Polar")
    if folder is None:
        pytest.skip("RADIATE Edinburgh head not found (set IMPALA_FLOW_TEST_DATA)")
    return folder


def _times(path):
    """(frames, t_ns) of an index, parsed here: Decimal with RADIATE's rule."""
    rows = [re.match(r"Frame: (\d+) Time: (\S+)", ln).groups() for ln in path.read_text().splitlines() if ln.strip()]
    return np.array([int(f) for f, _ in rows]), np.array([_radiate_ns(t) for _, t in rows], dtype=np.int64)


def test_real_head_reads_unpatched_with_its_counts():
    folder = _head()
    report = ImportReport()
    ds = open_dataset("radiate", str(folder), report=report)
    t, xyt, cov = ds.truth(report)
    radar_text = (folder / "Navtech_Polar.txt").read_text().split()
    gps_text = (folder / "GPS_IMU_Twist.txt").read_text().split()
    n_radar_padded = sum(len(w.split(".")[1]) < 9 for w in radar_text[3::4])
    n_gps_padded = sum(len(w.split(".")[1]) < 9 for w in gps_text[3::4])
    assert (n_radar_padded, n_gps_padded) == (37, 404)  # the folder's README
    assert report.facts["padded times"].startswith("radar 37 of 400 lines of Navtech_Polar.txt, GPS 404 of 4007 ")
    _, tg = _times(folder / "GPS_IMU_Twist.txt")
    repeats = int(np.sum(np.diff(tg) == 0))
    assert repeats == 2003 and f"GPS: {repeats} fix(es) written twice merged; 0 stale" in report.facts["repeats"]
    assert report.facts["times back"] == "radar: none; GPS: none"
    # the frames are late, not turns missing: 400 frames over 399 turns of the clock
    _, tr = _times(folder / "Navtech_Polar.txt")
    assert abs((tr[-1] - tr[0]) / 399 / ds.period_ns - 1.0) < 1e-3
    assert report.facts["radar gaps"].startswith("none")
    assert "frame 000131" in report.facts["late frames"]
    assert np.all(np.diff(ds.turn_t_ns) > 0.9 * ds.period_ns)
    # truth: every unique fix within the scans, in time order
    ug = np.unique(tg) - ds.gps_offset_ns  # the fixes on the radar's clock (RADIATE_GPS_OFFSET_S)
    assert ds.gps_offset_ns == 1_550_000_000 and report.facts["GPS clock"].startswith("fixes taken +1.550 s before")
    assert t.tolist() == ug[(ug >= ds.turn_t_ns[0]) & (ug <= ds.turn_t_ns[-1] + ds.period_ns)].tolist()
    known = cov[:, 2, 2] < HEADING_UNKNOWN_VAR_RAD2
    ts = (t - t[0]) / 1e9
    # the first minute the car waits (about 11 m of GPS wander and creeping): no heading, theta held at 0
    assert not known[ts < 60].any() and (xyt[ts < 60, 2] == 0.0).all()
    assert np.hypot(xyt[ts < 60, 0], xyt[ts < 60, 1]).max() < 12.0
    assert known[(ts > 72) & (ts < 98)].all()  # driving at ~10 m/s (across the GPS's 0.8 s gap too)
    imu = float(report.facts["IMU yaw"].split(" deg")[0])
    assert -9.0 < imu < -5.0  # -5.7 deg on the full drive per the issue


def _cartesian(scan, cell_m=0.25, half_m=60.0):
    """A turn's pixels (floor removed, first 6 m blanked) on a vehicle-frame grid, row 0 forward."""
    import cv2

    img = scan.power.T.astype(np.float32) * 255.0  # range bins x azimuths
    img = np.maximum(img - np.median(img, axis=1, keepdims=True), 0.0)
    img[:35] = 0.0
    n = int(half_m / cell_m)
    xs = (np.arange(2 * n) - n + 0.5)[::-1] * cell_m
    x, y = np.meshgrid(xs, xs, indexing="ij")
    col = np.mod(-np.arctan2(y, x), 2 * np.pi) / (2 * np.pi) * img.shape[1]  # clockwise columns
    rng = np.hypot(x, y) / 0.17361 - 0.5
    return cv2.remap(img, col.astype(np.float32), rng.astype(np.float32), cv2.INTER_LINEAR, borderValue=0.0)


def test_real_head_late_frame_is_one_turn_not_two():
    """Frames 335 and 336 are stamped 0.516 s apart while the car drives at ~10 m/s. The radar
    (phase correlation of the two images, independent of any time) moved one turn's distance;
    the GPS over the turn-clock times agrees, over the stamps it says twice as far."""
    import cv2

    folder = _head()
    report = ImportReport()
    ds = open_dataset("radiate", str(folder), report=report)
    t, xyt, _ = ds.truth(report)
    k = int(np.flatnonzero(ds.frames == 335)[0])
    a, b = _cartesian(ds.read_scan(k)), _cartesian(ds.read_scan(k + 1))
    (dc, dr), response = cv2.phaseCorrelate(a, b, cv2.createHanningWindow(a.shape[::-1], cv2.CV_32F))
    radar_m = 0.25 * math.hypot(dc, dr)
    assert response > 0.3 and 2.2 < radar_m < 2.8

    def gps_m(t0, t1):
        return math.hypot(*(np.interp(t1, t, xyt[:, i]) - np.interp(t0, t, xyt[:, i]) for i in (0, 1)))

    stamped = gps_m(ds.frame_t_ns[k], ds.frame_t_ns[k + 1])
    clock = gps_m(ds.turn_t_ns[k], ds.turn_t_ns[k + 1])
    assert (ds.frame_t_ns[k + 1] - ds.frame_t_ns[k]) / 1e9 == pytest.approx(0.516, abs=1e-3)
    assert stamped > 4.0 and abs(clock - radar_m) < 0.4
