"""Oxford and Boreas logs read as recorded, through `impala-flow import` on synthetic folders:
a row time going back, a scan out of order, a missing scan (gap) and the index file
(radar.timestamps), ground-truth rows repeated or going back: dropped and reported, gaps
reported, never an error and never silent; the import block says what the truth is."""

from __future__ import annotations

import numpy as np

from impala_flow.cli import main
from impala_flow.io import MissionReader
from impala_radar.datasets.boreas import BOREAS_POSE_COLUMNS

from ._dataset_files import ROW_US, navtech_folder, navtech_png

TURN_US = 400 * ROW_US  # 0.25 s


def _import(fmt, folder, capsys):
    out = folder.parent / f"{folder.name}-out.mcap"  # inside the dataset: refused
    assert main(["import", fmt, str(folder), "-o", str(out), "--no-progress"]) == 0
    text = capsys.readouterr().out
    with MissionReader(out) as r:
        beams = [(m.t_ns, m.data) for m in r.messages(["radar/beams"])]
        truth = [(m.t_ns, m.data) for m in r.messages(["truth/pose"])] if "truth/pose" in r.topics else []
        meta = r.metadata()[f"impala_flow.source.{fmt}"]
    block = {k.strip(): v.strip() for k, _, v in (ln.partition(":") for ln in text.splitlines()) if v}
    return beams, truth, block, meta, text


def test_a_row_time_going_back_is_dropped_and_named(tmp_path, capsys):
    paths = navtech_folder(tmp_path, n_scans=2)
    t0 = int(paths[1].stem)
    times = t0 + ROW_US * np.arange(400)
    times[137] = times[135]  # row 137 repeats row 135's time: it goes back
    navtech_png(paths[1], t0, times_us=times)
    beams, _, block, _, text = _import("oxford", tmp_path, capsys)
    assert len(beams) == 799 and np.all(np.diff([t for t, _ in beams]) > 0)
    assert (1, 137) not in {(b.turn, b.index) for _, b in beams}
    assert block["rows dropped"] == "1 (1 time going back or repeated)"
    assert f"{paths[1]}: row 137: time goes back or repeats ({times[137] * 1000} ns after {times[136] * 1000} ns)" \
        in text


def test_a_scan_out_of_order_is_dropped_and_listed(tmp_path, capsys):
    paths = navtech_folder(tmp_path, n_scans=3)
    navtech_png(paths[2], int(paths[0].stem) + 100)  # named after scan 1, stamped inside scan 0
    beams, _, block, _, _ = _import("boreas", tmp_path, capsys)
    assert len(beams) == 800 and {b.turn for _, b in beams} == {0, 1}
    assert block["scans skipped"].startswith(f"1 ({paths[2]}: every row's time at or before the previous scan's end")


def _gt_rows(stamps_us):
    """radar_odometry.csv rows: scan k 2 m ahead of scan k-1 (the first row from the scan before)."""
    rows = []
    prev = stamps_us[0] - TURN_US
    for s in stamps_us:
        rows.append(f"{s + TURN_US // 2},{prev + TURN_US // 2},2.0,0.0,0.0,0.0,0.0,0.0,{s},{prev}")
        prev = s
    return rows


def test_oxford_missing_scan_index_and_truth_quirks(tmp_path, capsys):
    paths = navtech_folder(tmp_path, n_scans=6)
    stamps = [int(p.stem) for p in paths]
    lines = [f"{s} 1" for s in stamps]
    (tmp_path / "radar.timestamps").write_text("\n".join(lines[:3] + lines[2:3] + lines[3:]) + "\n")  # one repeated
    paths[3].unlink()  # a scan lost: listed, no PNG
    gt = _gt_rows(stamps)
    (tmp_path / "gt").mkdir()
    header = ("source_timestamp,destination_timestamp,x,y,z,roll,pitch,yaw,source_radar_timestamp,"
              "destination_radar_timestamp")
    (tmp_path / "gt" / "radar_odometry.csv").write_text("\n".join([header] + gt[:4] + gt[3:4] + gt[4:]) + "\n")
    beams, truth, block, meta, _ = _import("oxford", tmp_path, capsys)
    assert {b.turn for _, b in beams} == {0, 1, 2, 3, 4}  # five files read
    # the chain goes through the missing scan: 6 rows -> 7 poses 2 m apart
    assert [t for t, _ in truth] == [stamps[0] * 1000 - TURN_US * 500] + [(s + TURN_US // 2) * 1000 for s in stamps]
    assert np.allclose([p.x_m for _, p in truth], 2.0 * np.arange(7))
    assert block["times back"] == ("scan files: none (named by time); radar.timestamps: 1 line(s) dropped (time "
                                   "going back or repeated; first line 4); radar_odometry.csv: 1 row(s) dropped "
                                   "(source time going back or repeated; first row 6)")
    assert block["radar gaps"] == (f"1 gap(s), 1 turns missing; longest 0.500 s before {stamps[4]}.png "
                                   f"(t = {stamps[4] // 10**6}.{stamps[4] % 10**6:06d}000 s); 1 scan(s) listed in "
                                   f"radar.timestamps without a PNG (first {stamps[3]}.png), not read")
    assert block["truth"].startswith("chained radar odometry")
    assert meta["radar_gaps"] == block["radar gaps"] and meta["truth"] == block["truth"]


def test_boreas_applanix_rows_repeated_or_going_back_are_dropped(tmp_path, capsys):
    paths = navtech_folder(tmp_path, n_scans=4)
    stamps = [int(p.stem) for p in paths]
    rows = [",".join(BOREAS_POSE_COLUMNS)]
    for k, s in enumerate(stamps):
        rows.append(f"{s},{100.0 + 2.5 * k},50.0,0.5,0,0,0,3.141592653589793,0.0,0.0,0,0,0")
    rows = rows[:3] + [rows[2], rows[1].replace("100.0", "90.0")] + rows[3:]  # a repeat, then a row going back
    (tmp_path / "applanix").mkdir()
    (tmp_path / "applanix" / "radar_poses.csv").write_text("\n".join(rows) + "\n")
    _, truth, block, _, _ = _import("boreas", tmp_path, capsys)
    assert [t for t, _ in truth] == [s * 1000 for s in stamps]
    assert np.allclose([p.x_m for _, p in truth], 2.5 * np.arange(4))
    assert block["times back"] == ("scan files: none (named by time); radar_poses.csv: 2 row(s) dropped (GPSTime "
                                   "going back or repeated; first row 4)")
    assert block["radar gaps"].startswith("none (no turn missing")
    assert block["truth"].startswith("Applanix post-processed GNSS/INS")
