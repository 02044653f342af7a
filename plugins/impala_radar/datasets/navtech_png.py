"""Navtech polar PNGs with an 11-byte row header (Oxford Radar RobotCar, Boreas).

One PNG per antenna turn, 8-bit grey, one row per azimuth in acquisition order:
columns 0-7 little-endian int64 timestamp (us), columns 8-9 little-endian uint16 encoder
count (5600 counts per turn), column 10 a flag byte (Oxford: 255 = valid row; Boreas'
newer firmware: the chirp direction, 0 / 255, not a validity flag), columns 11... power per
range bin (value / 255; Navtech stores it log-compressed).

Geometry (each a reader parameter):

* **Azimuth.** The encoder angle ``a = 2 pi count / 5600`` turns **clockwise** seen from
  above, 0 = vehicle forward (the datasets' SDKs). The beam's azimuth in the project
  convention (counter-clockwise, 0 = forward) is
  ``RadarBeam.azimuth_rad = wrap(-a + radians(azimuth_offset_deg))``: the offset is added in
  the project's CCW sense, so a positive offset turns the whole scan to the left.
* **Range.** The datasets' SDKs put bin k at its centre, ``(k + 0.5) resolution``:
  ``RadarConfig.range_offset_m = range_offset_bins * resolution`` with
  ``range_offset_bins = 0.5`` by default.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from PIL import Image, UnidentifiedImageError

from impala_flow import msgs

from .common import DatasetError

__all__ = ["ENCODER_SIZE", "HEADER_BYTES", "NavtechScan", "png_header", "read_navtech_png", "ccw_azimuth"]

ENCODER_SIZE = 5600
HEADER_BYTES = 11
_PNG_END = b"IEND\xaeB`\x82"


@dataclass(eq=False)
class NavtechScan:
    """One decoded turn: per-row ``timestamps_ns`` (int64), ``encoder`` counts,
    ``azimuth_rad`` (the dataset's clockwise angle, see the module doc), ``valid`` (flag byte
    == 255), ``flag`` (the raw byte) and ``power`` (float32, rows x bins, in [0, 1])."""

    timestamps_ns: np.ndarray
    encoder: np.ndarray
    azimuth_rad: np.ndarray
    valid: np.ndarray
    power: np.ndarray
    flag: np.ndarray | None = None


def png_header(path: str | Path) -> tuple[int, int, str]:
    """``(rows, columns, PIL mode)`` of a PNG, from its header only; an unreadable or truncated
    file (no IEND chunk at its end) is a :class:`DatasetError`."""
    path = Path(path)
    try:
        with Image.open(path) as im:
            if im.format != "PNG":
                raise DatasetError(f"{path}: not a PNG ({im.format} image)")
            width, height, mode = im.size[0], im.size[1], im.mode
        with open(path, "rb") as f:
            f.seek(max(0, path.stat().st_size - 12))
            if not f.read().endswith(_PNG_END):
                raise DatasetError(f"{path}: truncated PNG (no IEND chunk at the end of the file)")
    except (UnidentifiedImageError, OSError) as e:
        raise DatasetError(f"{path}: cannot read the PNG ({e})") from None
    return height, width, mode


def check_grey8(path: Path, mode: str) -> None:
    if mode != "L":
        kind = {"I;16": "16-bit grey", "I;16B": "16-bit grey", "I": "32-bit grey", "RGB": "colour (RGB)",
                "RGBA": "colour (RGBA)", "P": "palette (colour)", "LA": "grey with alpha"}.get(mode, mode)
        raise DatasetError(f"{path}: {kind} PNG, expected 8-bit grey")


def decode_grey8(path: Path) -> np.ndarray:
    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    if img is None or img.ndim != 2 or img.dtype != np.uint8:
        raise DatasetError(f"{path}: cannot decode the PNG as 8-bit grey")
    return img


def read_navtech_png(path: str | Path, encoder_size: int = ENCODER_SIZE, timestamp_unit_ns: int = 1000,
                     shape: tuple[int, int] | None = None) -> NavtechScan:
    """Decode one Navtech polar PNG (layout in the module doc). ``shape`` (rows, columns), when
    given, is the shape every scan of the sequence must have. Bad files raise
    :class:`DatasetError` naming the file (and the row for a bad encoder count)."""
    path = Path(path)
    rows, cols, mode = png_header(path)
    check_grey8(path, mode)
    if cols <= HEADER_BYTES:
        raise DatasetError(f"{path}: {rows} x {cols} pixels: no range bins after the {HEADER_BYTES}-byte "
                           f"row header")
    if shape is not None and (rows, cols) != tuple(shape):
        raise DatasetError(f"{path}: {rows} rows x {cols} columns, expected {shape[0]} x {shape[1]} "
                           f"like the first scan")
    img = decode_grey8(path)
    stamps = np.ascontiguousarray(img[:, :8]).view("<i8")[:, 0].astype(np.int64)
    encoder = np.ascontiguousarray(img[:, 8:10]).view("<u2")[:, 0]
    bad = np.flatnonzero(encoder >= encoder_size)
    if bad.size:
        raise DatasetError(f"{path}: row {int(bad[0])}: encoder count {int(encoder[bad[0]])} "
                           f">= {encoder_size} counts per turn")
    return NavtechScan(
        timestamps_ns=stamps * timestamp_unit_ns,
        encoder=encoder,
        azimuth_rad=encoder.astype(np.float64) * (2.0 * np.pi / encoder_size),
        valid=img[:, 10] == 255,
        power=img[:, HEADER_BYTES:].astype(np.float32) / np.float32(255.0),
        flag=img[:, 10].copy(),
    )


def ccw_azimuth(clockwise_rad: np.ndarray, azimuth_offset_deg: float = 0.0) -> np.ndarray:
    """The project's azimuth of a clockwise dataset angle: ``wrap(-a + radians(offset))``."""
    return msgs.wrap_angle(np.radians(azimuth_offset_deg) - np.asarray(clockwise_rad, dtype=np.float64))


def rotation_hz_of(scan_start_ns: list[int], timestamps_ns: np.ndarray, beams_per_turn: int) -> float:
    """Rotation rate measured on the data, rounded to 1 mHz: the median interval between the
    first rows of consecutive scans, or, with a single scan, its row span x rows / (rows - 1)
    (row times come in bursts, so the row interval itself is no measure)."""
    starts = np.diff(np.asarray(scan_start_ns, dtype=np.int64))
    starts = starts[starts > 0]
    if starts.size:
        period_ns = float(np.median(starts))
    else:
        span = int(timestamps_ns[-1] - timestamps_ns[0]) if len(timestamps_ns) > 1 else 0
        if span <= 0:
            raise DatasetError("cannot measure the rotation rate: one scan whose rows share one time")
        period_ns = span * beams_per_turn / (beams_per_turn - 1)
    return round(1e9 / period_ns, 3)
