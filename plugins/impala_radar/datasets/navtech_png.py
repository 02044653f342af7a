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

Reading (here for RADIATE's plain polar PNGs too): a scan file is checked before anything is
decoded, from its kind (a folder, pipe or device is never opened), its size, its PNG header
(signature, IHDR and its CRC, at most :data:`MAX_SCAN_BYTES` of pixels: no decompression bomb)
and its chunks (every CRC, image data inflating to exactly the declared size); every failure
is a :class:`DatasetError` naming the file, which ``--skip-bad-scans`` skips.
"""

from __future__ import annotations

import stat
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

from impala_flow import msgs

from .common import DatasetError, pixel_power

__all__ = ["ENCODER_SIZE", "HEADER_BYTES", "MAX_SCAN_BYTES", "NavtechScan", "png_header", "read_navtech_png",
           "ccw_azimuth", "check_grey8", "decode_grey8", "reference_scan"]

ENCODER_SIZE = 5600
HEADER_BYTES = 11
#: Largest decoded scan read (bytes): the biggest real scans are 400 x 6859 (Boreas, 2.7 MB), 400 x 3779
#: (Oxford) and 576 x 400 (RADIATE); a header declaring more is refused before anything is decoded.
#: Below Pillow's own decompression-bomb limit (89 M pixels), so Pillow never warns on a scan read here.
MAX_SCAN_BYTES = 64 << 20
_MAX_FILE_BYTES = 2 * MAX_SCAN_BYTES  # a PNG compresses: a bigger file is no scan either
_PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
_PNG_END = b"IEND\xaeB`\x82"
_HEAD = 33  # signature (8) + IHDR chunk (4 length + 4 type + 13 data + 4 CRC)
# PNG colour type -> (channels, name); grey (0) is named by its bit depth
_COLOUR_TYPES = {0: (1, "grey"), 2: (3, "RGB"), 3: (1, "P"), 4: (2, "LA"), 6: (4, "RGBA")}


@dataclass(eq=False)
class NavtechScan:
    """One decoded turn: per-row ``timestamps_ns`` (int64), ``encoder`` counts,
    ``azimuth_rad`` (the dataset's clockwise angle, see the module doc), ``valid`` (flag byte
    == 255), ``flag`` (the raw byte), ``counts`` (uint8, rows x bins: the pixels) and
    :attr:`power` (float32 ``counts / 255``, in [0, 1], made at each read: :func:`.common.pixel_power`)."""

    timestamps_ns: np.ndarray
    encoder: np.ndarray
    azimuth_rad: np.ndarray
    valid: np.ndarray
    counts: np.ndarray
    flag: np.ndarray | None = None

    @property
    def power(self) -> np.ndarray:
        return pixel_power(self.counts)


def _sniff(head: bytes) -> str:
    """What a file that is not a PNG looks like, for the error line."""
    for magic, kind in ((b"\xff\xd8\xff", "JPEG image"), (b"GIF8", "GIF image"), (b"BM", "BMP image"),
                        (b"II*\x00", "TIFF image"), (b"MM\x00*", "TIFF image"), (b"RIFF", "RIFF (WebP?) file"),
                        (b"\x1f\x8b", "gzip file"), (b"PK\x03\x04", "zip file")):
        if head.startswith(magic):
            return kind
    try:
        text = head.decode("utf-8")
    except UnicodeDecodeError:  # (a character cut at the end of the head passes as binary data)
        return "unknown binary data"
    return "text" if all(c.isprintable() or c in "\t\r\n" for c in text) else "unknown binary data"


def _open_scan(path: Path, whole: bool) -> tuple[bytes, bytes]:
    """``(head, data)`` of a scan file: its first :data:`_HEAD` bytes, and either all of it
    (``whole``) or its last 12 bytes. A folder, a device or pipe, an empty or oversized file
    is a :class:`DatasetError` (nothing opened that could block or flood memory)."""
    try:
        st = path.stat()
        if stat.S_ISDIR(st.st_mode):
            raise DatasetError(f"{path}: a folder, not a PNG file")
        if not stat.S_ISREG(st.st_mode):
            raise DatasetError(f"{path}: not a regular file (device, pipe or socket), not read")
        if st.st_size == 0:
            raise DatasetError(f"{path}: empty file (0 bytes), not a PNG")
        if st.st_size > _MAX_FILE_BYTES:
            raise DatasetError(f"{path}: {st.st_size / 2**20:.0f} MiB, larger than any radar scan "
                               f"({_MAX_FILE_BYTES >> 20} MiB at most): not read")
        with open(path, "rb") as f:
            if whole:
                data = f.read(_MAX_FILE_BYTES + 1)
                return data[:_HEAD], data
            head = f.read(_HEAD)
            f.seek(max(0, st.st_size - len(_PNG_END) - 4))
            return head, f.read()
    except OSError as e:
        raise DatasetError(f"{path}: cannot read the file ({e.strerror or e})") from None


def _ihdr(path: Path, head: bytes, data: bytes) -> tuple[int, int, str, int]:
    """``(rows, columns, mode, decoded bytes)`` from a PNG's first chunk (IHDR), checked
    (signature, CRC, sizes, IEND at the end) before anything is decoded."""
    if not head.startswith(_PNG_SIGNATURE):
        raise DatasetError(f"{path}: not a PNG ({_sniff(head)})")
    if len(head) < _HEAD:
        raise DatasetError(f"{path}: truncated PNG ({len(head)} bytes, no complete header)")
    length, kind = struct.unpack(">I4s", head[8:16])
    if kind != b"IHDR" or length != 13 or zlib.crc32(head[12:29]) != struct.unpack(">I", head[29:33])[0]:
        raise DatasetError(f"{path}: corrupt PNG header (IHDR chunk missing or its CRC wrong)")
    width, height, depth, colour = struct.unpack(">IIBB", head[16:26])
    if colour not in _COLOUR_TYPES or width == 0 or height == 0:
        raise DatasetError(f"{path}: corrupt PNG header ({height} x {width} pixels, colour type {colour})")
    channels, name = _COLOUR_TYPES[colour]
    mode = {8: "L", 16: "I;16"}.get(depth, f"{depth}-bit grey") if colour == 0 else name
    decoded = height * ((width * channels * depth + 7) // 8)
    if decoded > MAX_SCAN_BYTES:
        raise DatasetError(f"{path}: PNG of {height} rows x {width} columns ({decoded / 2**20:.0f} MiB decoded), "
                           f"more than any radar scan ({MAX_SCAN_BYTES >> 20} MiB at most): not decoded")
    if not data.endswith(_PNG_END):
        raise DatasetError(f"{path}: truncated PNG (no IEND chunk at the end of the file)")
    return height, width, mode, decoded


def png_header(path: str | Path) -> tuple[int, int, str]:
    """``(rows, columns, PIL mode)`` of a PNG from its header only (nothing decoded). Not a
    PNG, truncated (no IEND chunk at its end), a folder or device, or declaring more than
    :data:`MAX_SCAN_BYTES` decoded: a :class:`DatasetError` naming the file."""
    path = Path(path)
    head, tail = _open_scan(path, whole=False)
    rows, cols, mode, _ = _ihdr(path, head, tail)
    return rows, cols, mode


#: How many scans' headers :func:`reference_scan` reads to find the dataset's scan shape.
REFERENCE_TRIES = 5


def reference_scan(paths: list[Path], grey8: bool = False) -> tuple[int, tuple[int, int, str]]:
    """``(index, (rows, columns, mode))`` of the scan whose shape the dataset's scans share: the
    shape most of the first :data:`REFERENCE_TRIES` readable headers have (ties: the earliest),
    so one bad or odd first scan neither fails the import (``--skip-bad-scans`` then skips it
    where it is read) nor sets a wrong shape for the others. No readable header among the
    first ones: the first scan's :class:`DatasetError`."""
    seen: list[tuple[int, tuple[int, int, str]]] = []
    first_error: DatasetError | None = None
    for k, path in enumerate(paths):
        if len(seen) == REFERENCE_TRIES or (k >= 4 * REFERENCE_TRIES and not seen):
            break
        try:
            rows, cols, mode = png_header(path)
            if grey8:
                check_grey8(path, mode)
        except DatasetError as e:
            first_error = first_error or e
            continue
        seen.append((k, (rows, cols, mode)))
    if not seen:
        raise first_error if first_error is not None else DatasetError("no scan to read")
    shapes = [h for _, h in seen]
    best = max(shapes, key=lambda h: (shapes.count(h), -shapes.index(h)))
    return next((k, h) for k, h in seen if h == best)


def check_grey8(path: Path, mode: str) -> None:
    if mode != "L":
        kind = {"I;16": "16-bit grey", "RGB": "colour (RGB)", "RGBA": "colour (RGBA)", "P": "palette (colour)",
                "LA": "grey with alpha"}.get(mode, mode)
        raise DatasetError(f"{path}: {kind} PNG, expected 8-bit grey")


def decode_grey8(path: Path, shape: tuple[int, int] | None = None, shape_is: str = "") -> np.ndarray:
    """The 8-bit grey pixels of a PNG (rows x columns, uint8), its header checked first
    (:func:`png_header`'s checks, 8-bit grey, ``shape`` when given; ``shape_is`` says what its
    rows and columns are, in the error line): one read of the file, and nothing bigger than
    :data:`MAX_SCAN_BYTES` is ever decoded. Any failure is a :class:`DatasetError` naming the file."""
    path = Path(path)
    head, data = _open_scan(path, whole=True)
    rows, cols, mode, _ = _ihdr(path, head, data)
    check_grey8(path, mode)
    _check_shape(path, rows, cols, shape, shape_is)
    return _decode(path, data, rows, cols)


def _check_shape(path: Path, rows: int, cols: int, shape: tuple[int, int] | None, shape_is: str = "") -> None:
    if shape is not None and (rows, cols) != tuple(shape):
        raise DatasetError(f"{path}: {rows} rows x {cols} columns, expected {shape[0]} x {shape[1]} "
                           f"{'(' + shape_is + ') ' if shape_is else ''}like the first scan")


_ADAM7 = ((0, 0, 8, 8), (4, 0, 8, 8), (0, 4, 4, 8), (2, 0, 4, 4), (0, 2, 2, 4), (1, 0, 2, 2), (0, 1, 1, 2))


def _inflate_checked(path: Path, data: bytes, rows: int, cols: int) -> bytes:
    """The image data of ``data`` inflated (the filtered rows: a filter byte per row; Adam7
    passes when interlaced), every chunk's CRC checked, and its size exactly what an 8-bit grey
    ``rows`` x ``cols`` image holds, never more: Pillow takes a zlib stream that ends early for
    the whole image and leaves the rows it lacks at 0, so a scan cut short would pass unnoticed.

    The IDAT chunks are joined and inflated in one call, and each CRC is computed over pieces of
    at most :data:`_CRC_PIECE` bytes, which CPython computes without releasing the GIL: a reader
    thread that releases it gets it back only after up to a switch interval (5 ms) while the main
    thread encodes beams, so 19 chunks' CRCs and inflations cost it up to 0.2 s a scan."""
    if data[28]:  # interlace method (IHDR byte 12)
        expected = sum(h * (w + 1) for x0, y0, dx, dy in _ADAM7
                       if (w := -(-(cols - x0) // dx)) > 0 and (h := -(-(rows - y0) // dy)) > 0)
    else:
        expected = rows * (cols + 1)
    view, pos, idat = memoryview(data), 8, []
    crc32, piece = zlib.crc32, _CRC_PIECE
    while pos + 12 <= len(data):
        length, kind = struct.unpack_from(">I4s", data, pos)
        end = pos + 8 + length
        crc = 0
        for a in range(pos + 4, end, piece):
            crc = crc32(view[a:min(a + piece, end)], crc)
        if end + 4 > len(data) or crc != struct.unpack_from(">I", data, end)[0]:
            raise DatasetError(f"{path}: corrupt PNG (chunk {kind.decode('latin-1')!r} at byte {pos}: "
                               "length or CRC wrong)")
        if kind == b"IDAT":
            idat.append(view[pos + 8:end])
        pos = end + 4
    z = zlib.decompressobj()
    try:
        raw = z.decompress(b"".join(idat), expected + 1)
        if len(raw) > expected or z.unconsumed_tail:
            raise DatasetError(f"{path}: corrupt PNG (more image data than the {rows} x {cols} pixels "
                               "its header declares)")
        raw += z.flush(expected + 1 - len(raw))
    except zlib.error as e:
        raise DatasetError(f"{path}: cannot decode the PNG (image data: {e})") from None
    if len(raw) != expected:
        raise DatasetError(f"{path}: cannot decode the PNG (image data for {len(raw) // (cols + 1)} of the {rows} "
                           "rows its header declares)")
    return raw


#: bytes of a CRC computed in one call: CPython's zlib.crc32 keeps the GIL up to 5 KiB
_CRC_PIECE = 4096


def _stored(raw: bytes) -> bytes:
    """``raw`` (not empty) as a zlib stream of stored (uncompressed) deflate blocks, as
    ``zlib.compress(raw, 0)`` writes them, without its pass over the data."""
    n = len(raw)
    parts = [b"\x78\x01"]
    for i in range(0, n, 65535):
        k = min(65535, n - i)
        parts.append(struct.pack("<BHH", i + k >= n, k, k ^ 0xFFFF))
        parts.append(raw[i:i + k])
    parts.append(struct.pack(">I", zlib.adler32(raw)))
    return b"".join(parts)


def _decode(path: Path, data: bytes, rows: int, cols: int) -> np.ndarray:
    """Decode ``data`` (a PNG whose header :func:`_ihdr` checked: rows x cols, 8-bit grey).

    The image data is inflated once, by the check (:func:`_inflate_checked`); Pillow's PNG
    decoder then only unfilters it (PNG's Sub/Up/Average/Paeth filters and Adam7), handed to it
    as stored deflate blocks, a copy: the same pixels as Pillow reading the file, about half
    the work."""
    raw = _inflate_checked(path, data, rows, cols)
    # Pillow, not OpenCV: libpng under OpenCV prints its errors on stderr and returns None without a reason
    try:
        im = Image.frombytes("L", (cols, rows), _stored(raw), "zip", "L", int(data[28]))
    except (OSError, ValueError, zlib.error) as e:  # a bad filter byte: "cannot decode image data"
        raise DatasetError(f"{path}: cannot decode the PNG ({e})") from None
    img = np.asarray(im)
    if img.shape != (rows, cols) or img.dtype != np.uint8:
        raise DatasetError(f"{path}: decoded as {img.dtype} {img.shape}, expected 8-bit grey {rows} x {cols}")
    return img


def read_navtech_png(path: str | Path, encoder_size: int = ENCODER_SIZE, timestamp_unit_ns: int = 1000,
                     shape: tuple[int, int] | None = None) -> NavtechScan:
    """Decode one Navtech polar PNG (layout in the module doc). ``shape`` (rows, columns), when
    given, is the shape every scan of the sequence must have; without it (the first scan) the
    header must describe at most one row per encoder count. Both are checked on the header,
    before decoding. Bad files raise :class:`DatasetError` naming the file (and the row for a
    bad encoder count)."""
    path = Path(path)
    head, data = _open_scan(path, whole=True)
    rows, cols, mode, _ = _ihdr(path, head, data)
    check_grey8(path, mode)
    if cols <= HEADER_BYTES:
        raise DatasetError(f"{path}: {rows} x {cols} pixels: no range bins after the {HEADER_BYTES}-byte "
                           f"row header")
    if rows > encoder_size:
        raise DatasetError(f"{path}: {rows} rows, more than the {encoder_size} encoder counts of a turn (one row "
                           f"per azimuth): not decoded")
    _check_shape(path, rows, cols, shape)
    img = _decode(path, data, rows, cols)
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
        counts=img[:, HEADER_BYTES:],
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
