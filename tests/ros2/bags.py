"""Bags as a Navtech ROS 2 driver and rosbag2 record them, built with mcap-ros2-support's writer from the dataset
files on disk (never from impala-flow's readers).

Oxford Radar RobotCar ``radar/<us>.png``: per row, bytes 0-7 the azimuth's time (int64 us, little-endian), 8-9 its
encoder count (uint16, 5600 per turn), 10 the valid flag, 11... the 8-bit power of each range bin. Navtech's B-scan
publisher puts each azimuth on row ``encoder // (encoder_size / azimuth_samples)`` of one ``sensor_msgs/Image``
8UC1 per turn (height = azimuths, width = bins); here the image is stamped at the turn's first azimuth (row 0's
time) and logged when the turn is complete (its last row's time), as rosbag2 logs on receipt. The per-azimuth times
are lost. The driver's configuration message travels on ``/radar_data/configuration_data`` (integers big-endian,
the bin size an 8-byte little-endian double in metres). The truth: ``gt/radar_odometry.csv`` chained here into
``nav_msgs/Odometry`` poses (Oxford's y right and clockwise yaw turned into ROS's y left, counter-clockwise),
stamped at each row's source_timestamp, the first (identity) at the first row's destination_timestamp.
"""

from __future__ import annotations

import csv
import math
import struct
from pathlib import Path

import cv2
import numpy as np
from mcap.writer import CompressionType
from mcap_ros2.writer import Writer

from impala_ros2 import msgdefs

ENCODER_SIZE = 5600
BSCAN_TOPIC = "/radar_data/b_scan_image"
CONFIG_TOPIC = "/radar_data/configuration_data"
FFT_TOPIC = "/radar_data/fft_data"
TRUTH_TOPIC = "/ground_truth/odom"


def _stamp(t_ns: int) -> dict:
    return {"sec": t_ns // 1_000_000_000, "nanosec": t_ns % 1_000_000_000}


def oxford_scans(folder: Path) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """(row times ns, encoder counts, 8-bit power rows) of every scan, in time order."""
    out = []
    for png in sorted((folder / "radar").glob("*.png")):
        img = cv2.imread(str(png), cv2.IMREAD_GRAYSCALE)
        t_ns = img[:, :8].copy().view("<i8")[:, 0] * 1000
        encoder = img[:, 8:10].copy().view("<u2")[:, 0]
        out.append((t_ns, encoder, img[:, 11:]))
    return out


def oxford_truth(folder: Path) -> list[tuple[int, float, float, float]]:
    """(t_ns, x, y, yaw) in ROS's frame (y left, yaw counter-clockwise), chained from the CSV's relative poses of
    the sample's scans (the rows whose source_radar_timestamp is one of radar/<us>.png's names: the CSV covers the
    whole drive)."""
    scans = {int(p.stem) for p in (folder / "radar").glob("*.png")}
    with open(folder / "gt" / "radar_odometry.csv", newline="") as f:
        rows = [r for r in csv.DictReader(f) if min(scans) <= int(r["source_radar_timestamp"]) <= max(scans)]
    rows.sort(key=lambda r: int(r["source_timestamp"]))
    assert all(a["source_timestamp"] == b["destination_timestamp"] for a, b in zip(rows, rows[1:], strict=False))
    x = y = th = 0.0
    out = [(int(rows[0]["destination_timestamp"]) * 1000, x, y, th)]
    for r in rows:
        dx, dy, dth = float(r["x"]), -float(r["y"]), -float(r["yaw"])
        x, y = x + math.cos(th) * dx - math.sin(th) * dy, y + math.sin(th) * dx + math.cos(th) * dy
        th = math.remainder(th + dth, 2 * math.pi)
        out.append((int(r["source_timestamp"]) * 1000, x, y, th))
    return out


def _schema(writer: Writer, name: str):
    return writer.register_msgdef(msgdefs.schema_name(name), msgdefs.schema_text(name))


def write_oxford_bag(folder: Path, path: Path, *, configuration: bool = True, truth: bool = True,
                     fft: bool = False, chunk_size: int = 1024 * 1024, range_resolution_m: float = 0.0438,
                     turns: range | None = None) -> dict:
    """Write ``path``: every scan, or the ``turns`` (scan indices) of one part of a split bag (the truth of those
    turns' time span); returns what was written (counts)."""
    scans = oxford_scans(folder)
    span = None
    if turns is not None:
        chosen = [scans[k] for k in turns]
        span = (int(chosen[0][0][0]), int(scans[turns.stop][0][0]) if turns.stop < len(scans) else None)
        scans = chosen
    writer = Writer(str(path), chunk_size=chunk_size, compression=CompressionType.ZSTD)
    image = _schema(writer, "sensor_msgs/Image")
    counts = {"images": 0, "fft": 0, "truth": 0, "configuration": 0}
    n_az, n_bins = scans[0][2].shape
    if configuration:
        conf = _schema(writer, "messages/RadarConfigurationMessage")
        t0 = int(scans[0][0][0]) - 1_000_000
        writer.write_message(CONFIG_TOPIC, conf, {
            "header": {"stamp": _stamp(t0), "frame_id": "radar"},
            "azimuth_samples": list(struct.pack(">H", n_az)), "encoder_size": list(struct.pack(">H", ENCODER_SIZE)),
            "bin_size": list(struct.pack("<d", range_resolution_m)), "range_in_bins": list(struct.pack(">H", n_bins)),
            "expected_rotation_rate": list(struct.pack(">H", 4000))}, log_time=t0, publish_time=t0)
        counts["configuration"] += 1
    events = []
    for t_ns, encoder, power in scans:
        rows = encoder // (ENCODER_SIZE // n_az)
        data = np.zeros((n_az, n_bins), dtype=np.uint8)
        data[rows] = power
        events.append((int(t_ns[-1]), 0, "image", (int(t_ns[0]), data)))
        if fft:
            for i in range(n_az):
                events.append((int(t_ns[i]), 1, "fft", (int(t_ns[i]), int(encoder[i]), power[i])))
    if truth:
        for t, x, y, th in oxford_truth(folder):
            if span is not None and (t < span[0] or (span[1] is not None and t >= span[1])):
                continue
            events.append((t, 2, "truth", (t, x, y, th)))
    events.sort(key=lambda e: (e[0], e[1]))
    fft_schema = _schema(writer, "messages/RadarFftDataMessage") if fft else None
    odom = _schema(writer, "nav_msgs/Odometry") if truth else None
    for log_t, _, kind, v in events:
        if kind == "image":
            stamp, data = v
            writer.write_message(BSCAN_TOPIC, image, {
                "header": {"stamp": _stamp(stamp), "frame_id": "radar"}, "height": n_az, "width": n_bins,
                "encoding": "8UC1", "is_bigendian": 0, "step": n_bins, "data": data.tobytes()},
                log_time=log_t, publish_time=log_t)
            counts["images"] += 1
        elif kind == "fft":
            t, enc, row = v
            writer.write_message(FFT_TOPIC, fft_schema, {
                "header": {"stamp": _stamp(t), "frame_id": "radar"},
                "angle": list(struct.pack("<d", enc / ENCODER_SIZE * 360.0)), "azimuth": list(struct.pack(">H", enc)),
                "sweep_counter": list(struct.pack(">H", 0)),
                "ntp_seconds": list(struct.pack(">I", t // 1_000_000_000)),
                "ntp_split_seconds": list(struct.pack(">I", t % 1_000_000_000)),
                "data": row.tobytes(), "data_length": list(struct.pack(">H", row.size))},
                log_time=log_t, publish_time=log_t)
            counts["fft"] += 1
        else:
            t, x, y, th = v
            writer.write_message(TRUTH_TOPIC, odom, {
                "header": {"stamp": _stamp(t), "frame_id": "odom"}, "child_frame_id": "base_link",
                "pose": {"pose": {"position": {"x": x, "y": y, "z": 0.0},
                                  "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(th / 2), "w": math.cos(th / 2)}},
                         "covariance": [0.0] * 36},
                "twist": {"twist": {"linear": {"x": 0.0, "y": 0.0, "z": 0.0},
                                    "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}, "covariance": [0.0] * 36}},
                log_time=log_t, publish_time=log_t)
            counts["truth"] += 1
    writer.finish()
    return counts


def write_radiate_bag(folder: Path, path: Path) -> int:
    """RADIATE ``Navtech_Polar/<frame>.png`` (8-bit, rows = range bins, columns = the turn's azimuths, column j at
    ``j / N`` of a turn) and ``Navtech_Polar.txt`` (``Frame: 000001 Time: <s>.<ns>``, the time of column 0) as
    Navtech B-scan images (transposed: a row per azimuth), stamped at the frame's time, logged a turn later; no
    configuration message (the geometry comes from options). Returns the images written."""
    writer = Writer(str(path))
    image = _schema(writer, "sensor_msgs/Image")
    n = 0
    for line in (folder / "Navtech_Polar.txt").read_text().splitlines():
        parts = line.split()
        if len(parts) < 4:
            continue
        png = folder / "Navtech_Polar" / f"{parts[1]}.png"
        if not png.is_file():
            continue
        sec, _, frac = parts[3].partition(".")
        t = int(sec) * 1_000_000_000 + int(frac)  # RADIATE writes the nanoseconds as an integer
        data = np.ascontiguousarray(cv2.imread(str(png), cv2.IMREAD_GRAYSCALE).T)
        writer.write_message(BSCAN_TOPIC, image, {
            "header": {"stamp": _stamp(t), "frame_id": "radar"}, "height": data.shape[0], "width": data.shape[1],
            "encoding": "mono8", "is_bigendian": 0, "step": data.shape[1], "data": data.tobytes()},
            log_time=t + 250_000_000, publish_time=t + 250_000_000)
        n += 1
    writer.finish()
    return n
