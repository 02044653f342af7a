"""Bad input, every format: one line naming the file and the row or scan, exit code 1, and
no output file (not even a partial one). Synthetic files made here."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from impala_flow.cli import main

from ._dataset_files import navtech_folder, navtech_png, radiate_folder
from ._import_cli import refused


@pytest.mark.parametrize("fmt", ["oxford", "boreas"])
def test_empty_folder_and_no_radar_folder(folder, capsys, fmt):
    assert refused(fmt, folder, capsys).endswith(f"{folder}: no radar/ folder of Navtech PNG scans")
    (folder / "radar").mkdir()
    assert refused(fmt, folder, capsys).endswith(f"{folder / 'radar'}: no <timestamp>.png scans")


def test_radiate_without_navtech_polar(folder, capsys):
    assert refused("radiate", folder, capsys).endswith(f"{folder}: no Navtech_Polar/ folder of RADIATE polar scans")


@pytest.mark.parametrize("fmt", ["oxford", "boreas"])
def test_wrong_width(folder, capsys, fmt):
    paths = navtech_folder(folder, n_scans=3)
    navtech_png(paths[1], int(paths[1].stem), n_bins=25)
    line = refused(fmt, folder, capsys)
    assert f"{paths[1]}: 400 rows x 36 columns, expected 400 x 31 like the first scan" in line


def test_header_only_png(folder, capsys):
    p = folder / "radar" / "1700000000000000.png"
    p.parent.mkdir()
    Image.fromarray(np.zeros((400, 11), np.uint8)).save(p)
    assert "no range bins after the 11-byte row header" in refused("oxford", folder, capsys)


@pytest.mark.parametrize(("array", "kind"), [(np.zeros((400, 31, 3), np.uint8), "colour (RGB) PNG"),
                                             (np.zeros((400, 31), np.uint16), "16-bit grey PNG")])
def test_colour_and_16_bit(folder, capsys, array, kind):
    paths = navtech_folder(folder, n_scans=2)
    Image.fromarray(array).save(paths[1])
    assert refused("oxford", folder, capsys).endswith(f"{paths[1]}: {kind}, expected 8-bit grey")


def test_truncated_png(folder, capsys):
    paths = navtech_folder(folder, n_scans=3)
    data = paths[2].read_bytes()
    paths[2].write_bytes(data[: len(data) // 2])
    line = refused("boreas", folder, capsys)
    assert line.endswith(f"{paths[2]}: truncated PNG (no IEND chunk at the end of the file)")


def test_skip_bad_scans_keeps_and_counts_the_others(folder, capsys):
    paths = navtech_folder(folder, n_scans=3)
    paths[1].write_bytes(paths[1].read_bytes()[:100])
    out = folder.parent / "skip.mcap"
    assert main(["import", "oxford", str(folder), "-o", str(out), "--no-progress", "--skip-bad-scans"]) == 0
    text = capsys.readouterr().out
    assert "turns:        2" in text and "beams:        800" in text
    assert f"scans skipped: 1 ({paths[1]}: truncated PNG" in text


def test_invalid_rows_are_counted_with_their_reason(folder, capsys):
    flag = np.full(400, 255, np.uint8)
    flag[[3, 50, 51]] = 0
    navtech_folder(folder, n_scans=2, flag=flag)
    out = folder.parent / "ok.mcap"
    assert main(["import", "oxford", str(folder), "-o", str(out), "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "beams:        794" in text and "rows dropped: 6 (6 Oxford valid flag (column 10) != 255)" in text


def test_ground_truth_with_missing_columns(folder, capsys):
    navtech_folder(folder, n_scans=2)
    (folder / "gt").mkdir()
    (folder / "gt" / "radar_odometry.csv").write_text("source_timestamp,destination_timestamp,x,y\n1,2,3,4\n")
    line = refused("oxford", folder, capsys)
    assert line.endswith(f"{folder / 'gt' / 'radar_odometry.csv'}: row 1 (header): missing column(s) "
                         "source_radar_timestamp, destination_radar_timestamp, yaw")


def test_boreas_poses_bad_row(folder, capsys):
    navtech_folder(folder, n_scans=2)
    (folder / "applanix").mkdir()
    header = "GPSTime,easting,northing,altitude,vel_east,vel_north,vel_up,roll,pitch,heading,angvel_z,angvel_y,angvel_x"
    (folder / "applanix" / "radar_poses.csv").write_text(f"{header}\n1,0,0,0,0,0,0,3.1,0,0,0,0,0\n2,0,0\n")
    assert refused("boreas", folder, capsys).endswith("radar_poses.csv: row 3: 3 fields, expected 13 with "
                                                     "GPSTime, easting, northing, roll, pitch, heading filled")


def test_radiate_wrong_shape(folder, capsys):
    paths = radiate_folder(folder, ["100.0", "100.25", "100.5"])
    Image.fromarray(np.zeros((30, 399), np.uint8)).save(paths[2])
    assert f"{paths[2]}: 30 rows x 399 columns, expected 30 x 400" in refused("radiate", folder, capsys)
