"""Impossible values, through `impala-flow import` (and the readers' constructors for API users):
every numeric option finite and physically possible, every value read from a dataset checked
where it enters (file and row named, one line, exit code 1 or 2 for an option, no output file), or,
where the reader has a drop-and-count policy, dropped and counted. Synthetic folders made here."""

from __future__ import annotations

import math
import os

import numpy as np
import pytest
from PIL import Image

from impala_flow._component import ParamError
from impala_flow.cli import main
from impala_flow.io import MissionReader
from impala_radar.datasets.boreas import BOREAS_POSE_COLUMNS
from impala_radar.datasets.common import DatasetError, ImportReport, iter_mission
from impala_radar.datasets.component import OxfordScans
from impala_radar.datasets.oxford import OxfordDataset
from impala_radar.datasets.radiate import RadiateDataset

from ._dataset_files import ROW_US, navtech_folder, navtech_png, radiate_folder, radiate_gps
from ._import_cli import import_block, refused

TURN_US = 400 * ROW_US  # 0.25 s
P_NS = 250_000_000
T0_NS = 1_549_986_548_010_563_645
GT_HEADER = ("source_timestamp,destination_timestamp,x,y,z,roll,pitch,yaw,source_radar_timestamp,"
             "destination_radar_timestamp")


def _imports(fmt, folder, capsys, *extra):
    out = folder.parent / f"{folder.name}-ok.mcap"
    assert main(["import", fmt, str(folder), "-o", str(out), "--no-progress", *extra]) == 0
    text = capsys.readouterr().out
    with MissionReader(out) as r:
        beams = [(m.t_ns, m.data) for m in r.messages(["radar/beams"])]
    return beams, import_block(text)


# ---------------------------------------------------------------- numeric options

@pytest.mark.parametrize(("fmt", "option", "value", "says"), [
    ("oxford", "--db-per-count", "inf", "inf must be <= 1.0"),
    ("oxford", "--db-per-count", "nan", "NaN is not allowed"),
    ("boreas", "--db-per-count", "-0.5", "-0.5 must be > 0.0"),
    ("oxford", "--azimuth-offset-deg", "inf", "inf must be <= 360.0"),
    ("radiate", "--azimuth-offset-deg", "-inf", "-inf must be >= -360.0"),
    ("oxford", "--range-resolution-m", "inf", "inf must be <= 10.0"),
    ("boreas", "--range-resolution-m", "1e9", "1000000000.0 must be <= 10.0"),
    ("radiate", "--range-resolution-m", "0", "0.0 must be > 0.0"),
    ("oxford", "--range-offset-bins", "1e308", "1e+308 must be <= 1000.0"),
    ("radiate", "--gps-offset-s", "inf", "inf must be <= 60.0"),
    ("radiate", "--gps-offset-s", "nan", "NaN is not allowed"),
])
def test_a_numeric_option_out_of_bounds_is_one_usage_line_naming_it(folder, capsys, fmt, option, value, says):
    if fmt == "radiate":
        radiate_folder(folder, ["100.0", "100.25"])
    else:
        navtech_folder(folder, n_scans=2)
    assert refused(fmt, folder, capsys, f"{option}={value}", code=2).endswith(f"error: {option}: {says}")


def test_api_users_get_the_same_checks(folder):
    navtech_folder(folder, n_scans=2)
    with pytest.raises(DatasetError, match=r"^option range_resolution_m: inf m: expected a finite value in \(0, 10\]"):
        OxfordDataset(folder, range_resolution_m=math.inf)
    with pytest.raises(DatasetError, match=r"^option azimuth_offset_deg: nan deg"):
        OxfordDataset(folder, azimuth_offset_deg=math.nan)
    with pytest.raises(ParamError, match="parameter 'db_per_count': inf must be <= 1.0"):
        OxfordScans("ox", folder=str(folder), db_per_count=math.inf)
    with pytest.raises(DatasetError, match="^option db_per_count: inf dB"):
        next(iter_mission(OxfordDataset(folder), ImportReport(), db_per_count=math.inf))
    radiate = folder.parent / "radiate"
    radiate_folder(radiate, ["100.0", "100.25"])
    with pytest.raises(DatasetError, match=r"^option gps_offset_s: inf s: expected a finite value in \[-60, 60\] s"):
        RadiateDataset(radiate, gps_offset_s=math.inf)


def test_options_at_their_bounds_give_finite_beams(folder, capsys):
    """At the bounds every value leaving the reader is finite: a pixel of count c carries
    10^(c x 1.0 / 10) (count 255: 10^25.5, within float32), azimuths wrapped to [-pi, pi]."""
    img = navtech_folder(folder, n_scans=2)
    beams, _ = _imports("oxford", folder, capsys, "--db-per-count", "1", "--azimuth-offset-deg", "360",
                        "--range-resolution-m", "10", "--range-offset-bins", "-1000")
    power = np.stack([b.up for _, b in beams])
    assert np.isfinite(power).all() and np.all(np.abs([b.azimuth_rad for _, b in beams]) <= math.pi)
    counts = np.array(Image.open(img[0]))[:, 11:]
    assert np.allclose(power[:400], 10.0 ** (counts / 10.0), rtol=1e-6)
    c = beams[0][1].config
    assert math.isfinite(c.range_offset_m) and c.range_offset_m == pytest.approx(-10_000.0)


# ---------------------------------------------------------------- Oxford / Boreas values

def _gt(folder, rows):
    (folder / "gt").mkdir(exist_ok=True)
    (folder / "gt" / "radar_odometry.csv").write_text("\n".join([GT_HEADER, *rows]) + "\n")
    return folder / "gt" / "radar_odometry.csv"


def _gt_rows(stamps_us, x="2.0"):
    rows, prev = [], stamps_us[0] - TURN_US
    for s in stamps_us:
        rows.append(f"{s + TURN_US // 2},{prev + TURN_US // 2},{x},0.0,0.0,0.0,0.0,0.0,{s},{prev}")
        prev = s
    return rows


def test_oxford_truth_step_no_vehicle_makes(folder, capsys):
    """x = 1e308 is finite but its chained poses are not: refused with its row and value."""
    stamps = [int(p.stem) for p in navtech_folder(folder, n_scans=3)]
    rows = _gt_rows(stamps)
    rows[1] = rows[1].replace(",2.0,", ",1e308,")
    path = _gt(folder, rows)
    line = refused("oxford", folder, capsys)
    assert line.endswith(f"{path}: row 3: x 1e308 m, y 0.0 m, yaw 0.0 rad over 0.250 s: more than 100 m/s (+1 m) "
                         "or half a turn between two scans")
    rows = _gt_rows(stamps)
    rows[2] = rows[2].replace(",0.0,0.0,0.0,0.0,0.0,", ",0.0,0.0,0.0,0.0,7.0,")  # yaw 7 rad in a quarter second
    _gt(folder, rows)
    assert "row 4: x 2.0 m, y 0.0 m, yaw 7.0 rad" in refused("oxford", folder, capsys)


def test_oxford_truth_time_against_its_scan_time(folder, capsys):
    stamps = [int(p.stem) for p in navtech_folder(folder, n_scans=3)]
    rows = _gt_rows(stamps)
    rows[0] = "0," + rows[0].split(",", 1)[1]  # source_timestamp zeroed, the radar's time kept
    path = _gt(folder, rows)
    line = refused("oxford", folder, capsys)
    assert line.startswith(f"impala-flow import: error: {path}: row 2: source_timestamp 0 is -1.7e+09 s from "
                           f"source_radar_timestamp {stamps[0]}")


def test_oxford_row_times_zeroed_while_the_names_say_2019(folder, capsys):
    """The scan's rows and its file name are two clocks: a mismatch is refused with the file and row
    (else a 49-year mission)."""
    t0 = 1_547_131_046_353_776  # 2019-01-10, the sample's first scan
    paths = navtech_folder(folder, n_scans=3, t0_us=t0)
    navtech_png(paths[1], int(paths[1].stem), times_us=np.zeros(400, np.int64))
    line = refused("oxford", folder, capsys)
    assert line.endswith(f"{paths[1]}: row 0: time 0 ns is -1.54713e+09 s from the file name's "
                         f"{int(paths[1].stem) // 10**6}.{int(paths[1].stem) % 10**6:06d}000 s (rows within 1 s of "
                         "it): the row times and the scan's name disagree")
    navtech_png(paths[0], t0, times_us=t0 + 86_400_000_000 + ROW_US * np.arange(400))  # the first: a day later
    assert f"{paths[0]}: row 0: time {(t0 + 86_400_000_000) * 1000} ns is +86400 s from" in refused("boreas", folder,
                                                                                                   capsys)


def test_navtech_scans_faster_than_the_sensor_turns(folder, capsys):
    """6 scans named 50 ms apart: 20 turns a second, five times the Navtech's 4 Hz."""
    for k in range(6):
        t = 1_700_000_000_000_000 + k * 50_000
        navtech_png(folder / "radar" / f"{t}.png", t, times_us=t + 125 * np.arange(400))
    line = refused("oxford", folder, capsys)
    assert line.endswith(f"{folder / 'radar'}: 6 scan(s) 1700000000000000.png-1700000000250000.png: one turn "
                         "every 0.0500 s (20.0 Hz): faster than the Navtech turns (0.25 s, 4 Hz; at least 0.2 s)")


def test_navtech_mission_spanning_days_is_refused(folder, capsys):
    paths = navtech_folder(folder, n_scans=3)
    late = int(paths[-1].stem) + 10 * 86_400_000_000
    navtech_png(folder / "radar" / f"{late}.png", late)
    line = refused("oxford", folder, capsys)
    assert line.endswith(f"{folder / 'radar'} (scan names): times span {(late - 1_700_000_000_000_000) / 1e6:.0f} s "
                         "(10.0 days, from "
                         f"1700000000.000000000 to {late // 10**6}.{late % 10**6:06d}000 s): more than one recording "
                         "(86400 s)")


def _boreas(folder, rows):
    (folder / "applanix").mkdir(exist_ok=True)
    path = folder / "applanix" / "radar_poses.csv"
    path.write_text("\n".join([",".join(BOREAS_POSE_COLUMNS), *rows]) + "\n")
    return path


@pytest.mark.parametrize(("k", "field", "value", "says"), [
    (1, 1, "1e308", "row 3: easting 1e308: out of range (|m| <= 1e7 m (UTM))"),
    (2, 9, "100.0", "row 4: heading 100.0: out of range (|rad| <= 2 pi)"),
    (1, 2, "5050.0", "row 3: easting 102.5, northing 5050.0: 2e+04 m/s since the sample before (0.250 s earlier): "
                     "faster than 100 m/s"),
])
def test_boreas_poses_out_of_range(folder, capsys, k, field, value, says):
    stamps = [int(p.stem) for p in navtech_folder(folder, n_scans=3)]
    rows = [f"{s},{100.0 + 2.5 * i},50.0,0.5,0,0,0,3.141592653589793,0.0,0.0,0,0,0".split(",")
            for i, s in enumerate(stamps)]
    rows[k][field] = value
    path = _boreas(folder, [",".join(r) for r in rows])
    assert refused("boreas", folder, capsys).endswith(f"{path}: {says}")


# ---------------------------------------------------------------- RADIATE values

def test_radiate_frames_faster_than_the_sensor_turns(folder, capsys):
    """6 turns in 0.25 s (frames 50 ms apart): refused, naming the index and the rate."""
    radiate_folder(folder, [T0_NS + k * 50_000_000 for k in range(6)], rows=4, cols=8)
    assert refused("radiate", folder, capsys).endswith(
        f"{folder / 'Navtech_Polar.txt'}: lines 1-6, 6 frames in 0.250 s: one turn every 0.0500 s (20.0 Hz): faster "
        "than the Navtech turns (0.25 s, 4 Hz; at least 0.2 s)")


def test_radiate_one_frame_too_soon_is_dropped_and_counted(folder, capsys):
    t = [T0_NS + k * P_NS for k in range(20)]
    t.insert(8, t[7] + 40_000_000)  # frame 9: 40 ms after frame 8, no turn
    radiate_folder(folder, t, rows=4, cols=8)
    beams, block = _imports("radiate", folder, capsys, "--gps-offset-s", "0")
    starts = sorted({b.turn: bt for bt, b in reversed(beams)}.values())
    assert starts == t[:8] + t[9:] and block["turns"] == "20"
    assert block["short turns"] == ("1 frame(s) dropped: stamped less than 0.125 s (half the sensor's turn) after "
                                    "the frame kept before (first line 9, frame 000009, +0.040 s)")


@pytest.mark.parametrize(("shift_ns", "says"), [
    (-3_600 * 10**9, "line 6 (frame 000006): time {t} s is 3599.750 s before an earlier one: a clock step back of "
                     "more than 10 s is no logging quirk"),
    (10 * 86_400 * 10**9, "Navtech_Polar.txt: times span 864002 s (10.0 days"),
])
def test_radiate_clock_jumps_beyond_the_quirks(folder, capsys, shift_ns, says):
    t = [T0_NS + k * P_NS for k in range(10)]
    t[5:] = [x + shift_ns for x in t[5:]]
    radiate_folder(folder, t, rows=4, cols=8)
    ts = f"{t[5] // 10**9}.{t[5] % 10**9:09d}"
    assert says.format(t=ts) in refused("radiate", folder, capsys)


def _radiate_with_gps(folder):
    radiate_folder(folder, [T0_NS + k * P_NS for k in range(16)], rows=4, cols=8)
    n = 80
    paths = radiate_gps(folder, (T0_NS + np.arange(n) * 50_000_000).tolist(), np.arange(n) * 0.5, np.zeros(n),
                        np.zeros(n))
    return paths


@pytest.mark.parametrize(("line", "says"), [
    (0, "line 1: latitude 1000.0 deg: expected -90 to 90 deg"),
    (0, "line 1: longitude -500.0 deg: expected -180 to 180 deg"),
    (0, "line 1: altitude 1e+300 m: expected -500 to 9000 m"),
    (1, "line 2: position variance -1.0 m^2: expected 0 to 1e12"),
    (4, "line 5: expected 4 finite numbers, got '0.0, 0.0, nan, 1.0'"),
])
def test_radiate_gps_field_out_of_range(folder, capsys, line, says):
    paths = _radiate_with_gps(folder)
    lines = paths[21].read_text().splitlines()
    parts = lines[line].split(", ")
    if "latitude" in says:
        parts[0] = "1000.0"
    elif "longitude" in says:
        parts[1] = "-500.0"
    elif "altitude" in says:
        parts[2] = "1e300"
    elif "variance" in says:
        parts[0] = "-1.0"
    else:
        parts[2] = "nan"
    lines[line] = ", ".join(parts)
    paths[21].write_text("\n".join(lines) + "\n")
    assert refused("radiate", folder, capsys, "--gps-offset-s", "0").endswith(f"{paths[21]}: {says}")


def test_radiate_gps_position_jump_faster_than_a_vehicle(folder, capsys):
    """One fix (both copies) 5 km off: hundreds of m/s over the 1 s chord, refused with a file named."""
    paths = _radiate_with_gps(folder)
    for p in paths[40:42]:
        lines = p.read_text().splitlines()
        lat, rest = lines[0].split(", ", 1)
        lines[0] = f"{float(lat) + 0.045!r}, {rest}"
        p.write_text("\n".join(lines) + "\n")
    line = refused("radiate", folder, capsys, "--gps-offset-s", "0")
    assert "GPS_IMU_Twist/0000" in line and "m/s over the 1 s around this fix: faster than 100 m/s" in line


# ---------------------------------------------------------------- files that are no text, no CSV

@pytest.mark.parametrize(("content", "says"), [
    ("folder", "a folder, expected a CSV file with columns source_timestamp"),
    (b"source_timestamp,x\n\xff\xfe\x00binary\n", "line 2: byte 0xff is not text"),
    (b"source_timestamp,x\n1,\x002\n", "line 2: NUL byte, not text"),
    ("", "row 1: empty file, expected a header with source_timestamp"),
    (GT_HEADER + "\n", "row 1 (header) only: no data row"),
    (GT_HEADER + "\n1,2,3,4,5,6,7,8,9,10,11\n", "row 2: 11 fields, expected 10"),
    (GT_HEADER + "\n99999999999999999999999,2,3,4,5,6,7,8,9,10\n",
     "row 2: source_timestamp 99999999999999999999999 is not a Unix time of 1970-2100"),
    (GT_HEADER + "\n-5,2,3,4,5,6,7,8,9,10\n", "row 2: source_timestamp -5 is not a Unix time of 1970-2100"),
])
def test_oxford_ground_truth_file_that_is_no_csv(folder, capsys, content, says):
    navtech_folder(folder, n_scans=2)
    path = folder / "gt" / "radar_odometry.csv"
    path.parent.mkdir()
    if content == "folder":
        path.mkdir()
    elif isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content)
    assert f"error: {path}: {says}" in refused("oxford", folder, capsys)


def test_radiate_index_files_that_are_no_text(folder, capsys):
    radiate_folder(folder, ["100.0", "100.25", "100.5"], rows=4, cols=8)
    index = folder / "Navtech_Polar.txt"
    good = index.read_text()
    index.write_bytes(good.encode() + b"Frame: 000004 Time: \x89PNG\n")
    assert refused("radiate", folder, capsys).endswith(f"{index}: line 4: byte 0x89 is not text ('Frame: <n> Time: "
                                                      "<seconds>' lines expected)")
    index.write_text(good + "Frame: 000004 Time: 99999999999999999999999.5\n")
    assert "line 4: frame 000004 at 99999999999999999999999 s: expected a frame number below 10^9 and a Unix time " \
           "of 1970-2100" in refused("radiate", folder, capsys)
    index.unlink()
    index.mkdir()
    assert refused("radiate", folder, capsys).endswith(f"{index}: a folder, expected 'Frame: <n> Time: <seconds>' "
                                                      "lines")


@pytest.mark.parametrize("kind", ["folder", "binary", "pipe"])
def test_radiate_gps_file_that_is_no_text(folder, capsys, kind):
    paths = _radiate_with_gps(folder)
    paths[10].unlink()
    if kind == "folder":
        paths[10].mkdir()
        says = "a folder, expected a GPS/IMU text file"
    elif kind == "pipe":  # once: the import blocked on it forever
        os.mkfifo(paths[10])
        says = "not a regular file (device, pipe or socket), expected a GPS/IMU text file"
    else:
        paths[10].write_bytes(b"55.9, -3.2, 115.0\n\xc3\x28\n")
        says = "line 2: byte 0xc3 is not text"
    assert refused("radiate", folder, capsys, "--gps-offset-s", "0").endswith(f"{paths[10]}: {says}" + (
        " (a GPS/IMU text file expected)" if kind == "binary" else ""))


def test_oxford_scan_index_that_is_no_text(folder, capsys):
    navtech_folder(folder, n_scans=2)
    index = folder / "radar.timestamps"
    index.write_bytes(b"1700000000000000 1\n\xff\xd8\xff\n")
    assert refused("oxford", folder, capsys).endswith(f"{index}: line 2: byte 0xff is not text ('<timestamp_us> "
                                                     "<chunk>' lines expected)")
    index.write_text("1700000000000000 1\n1700000000250000 1\n1690000000000000 1\n")
    assert refused("oxford", folder, capsys).endswith(f"{index}: line 3: time 1690000000.000000000 s is "
                                                     "10000000.250 s before an earlier one: a clock step back of "
                                                     "more than 10 s is no logging quirk")


def test_one_scan_whose_rows_share_one_time_is_named(folder, capsys):
    t = 1_700_000_000_000_000
    navtech_png(folder / "radar" / f"{t}.png", t, times_us=np.full(400, t, np.int64))
    assert refused("oxford", folder, capsys).endswith(f"{folder / 'radar' / f'{t}.png'}: cannot measure the rotation "
                                                     "rate: one scan whose rows share one time")


@pytest.mark.parametrize(("extra", "says"), [
    (["--duration", "2s", "--epoch-utc", "9999-12-31T00:00:00Z"],
     "epoch_utc '9999-12-31T00:00:00Z': expected a date from 1970 to 2100"),
    (["--duration", "2s", "--epoch-utc", "1900-01-01T00:00:00Z"],
     "epoch_utc '1900-01-01T00:00:00Z': expected a date from 1970 to 2100"),
    (["--duration", "inf"], "argument --duration: duration must be positive and at most a day: 'inf'"),
])
def test_simulate_times_beyond_int64_ns_are_refused_before_any_work(tmp_path, capsys, extra, says):
    """A year-9999 epoch once failed on the first sample (int64 overflow), 1900 on the recorder."""
    out = tmp_path / "sim.mcap"
    try:
        code = main(["simulate", "beynes", "-o", str(out), "--no-progress", *extra])
    except SystemExit as e:  # argparse's own usage error
        code = e.code
    assert code == 2 and capsys.readouterr().err.strip().splitlines()[-1].endswith(says) and not out.exists()
