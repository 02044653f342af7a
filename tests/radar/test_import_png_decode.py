"""The scan reader's PNG path: the image data is inflated once (by the check of its size) and Pillow only
unfilters it; the 8-bit counts go to linear power by table. Each is checked against an independent
reference: Pillow reading the file itself (every PNG filter type, Adam7 interlacing, the real RADIATE
scans), and the float formula of ``counts_to_power``."""

from __future__ import annotations

import os
import struct
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from impala_radar.datasets.common import DatasetError, _power_table, counts_to_power, power_of_counts
from impala_radar.datasets.navtech_png import _ADAM7, decode_grey8, read_navtech_png

SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _png(rows: int, cols: int, raw: bytes, interlace: int = 0, idat_parts: int = 3) -> bytes:
    """An 8-bit grey PNG of ``raw`` (the filtered rows, filter byte first) written by hand, its zlib
    stream split over ``idat_parts`` IDAT chunks."""
    z = zlib.compress(raw, 6)
    cut = [len(z) * i // idat_parts for i in range(idat_parts + 1)]
    return (SIGNATURE + _chunk(b"IHDR", struct.pack(">IIBBBBB", cols, rows, 8, 0, 0, 0, interlace))
            + b"".join(_chunk(b"IDAT", z[a:b]) for a, b in zip(cut[:-1], cut[1:], strict=True))
            + _chunk(b"IEND", b""))


def _filtered(rng: np.random.Generator, rows: int, cols: int) -> bytes:
    """Random filtered rows: any bytes after a filter byte in 0..4 (None, Sub, Up, Average, Paeth) are a
    valid PNG row, so every filter type is exercised, in every order."""
    data = rng.integers(0, 256, size=(rows, cols + 1), dtype=np.uint8)
    data[:, 0] = rng.integers(0, 5, size=rows)
    return data.tobytes()


@pytest.mark.parametrize("rows,cols", [(1, 1), (7, 13), (64, 400), (576, 400), (300, 70_000 // 300)])
def test_every_filter_type_decodes_as_pillow_reads_the_file(tmp_path, rows, cols):
    rng = np.random.default_rng(rows * 1000 + cols)
    path = tmp_path / "scan.png"
    path.write_bytes(_png(rows, cols, _filtered(rng, rows, cols)))
    assert np.array_equal(decode_grey8(path), np.asarray(Image.open(path)))


def test_interlaced_scans_decode_as_pillow_reads_the_file(tmp_path):
    rows, cols = 37, 29
    size = sum(h * (w + 1) for x0, y0, dx, dy in _ADAM7
               if (w := -(-(cols - x0) // dx)) > 0 and (h := -(-(rows - y0) // dy)) > 0)
    rng = np.random.default_rng(5)
    raw = bytearray(rng.integers(0, 256, size=size, dtype=np.uint8).tobytes())
    pos = 0  # a filter byte in 0..4 at the start of every row of every pass
    for x0, y0, dx, dy in _ADAM7:
        w, h = -(-(cols - x0) // dx), -(-(rows - y0) // dy)
        if w <= 0 or h <= 0:
            continue
        for _ in range(h):
            raw[pos] = int(rng.integers(0, 5))
            pos += w + 1
    path = tmp_path / "interlaced.png"
    path.write_bytes(_png(rows, cols, bytes(raw), interlace=1))
    assert np.array_equal(decode_grey8(path), np.asarray(Image.open(path)))


def test_a_bad_filter_byte_is_one_line_naming_the_file(tmp_path):
    rows, cols = 6, 9
    raw = bytearray(_filtered(np.random.default_rng(1), rows, cols))
    raw[3 * (cols + 1)] = 7  # no such filter type
    path = tmp_path / "bad-filter.png"
    path.write_bytes(_png(rows, cols, bytes(raw)))
    with pytest.raises(DatasetError) as e:
        decode_grey8(path)
    assert str(e.value).startswith(f"{path}: cannot decode the PNG") and "\n" not in str(e.value)


def test_a_scan_cut_short_or_too_long_is_still_refused(tmp_path):
    rows, cols = 8, 20
    raw = _filtered(np.random.default_rng(2), rows, cols)
    short, long = tmp_path / "short.png", tmp_path / "long.png"
    short.write_bytes(_png(rows, cols, raw[:-(cols + 1) * 3]))
    long.write_bytes(_png(rows, cols, raw + bytes(cols + 1)))
    with pytest.raises(DatasetError, match=r"image data for 5 of the 8 rows"):
        decode_grey8(short)
    with pytest.raises(DatasetError, match=r"more image data than the 8 x 20 pixels"):
        decode_grey8(long)


def test_power_of_counts_is_counts_to_power_bit_for_bit():
    counts = np.arange(256, dtype=np.uint8)
    # the identity the table rests on: every count comes back from its float32 / 255
    assert all(int(np.rint(np.float64(np.float32(c) / np.float32(255.0)) * 255.0)) == c for c in range(256))
    rng = np.random.default_rng(3)
    for shape in [(16,), (16, 16), (3, 100), (40, 576)]:
        c = rng.integers(0, 256, size=shape, dtype=np.uint8)
        c.flat[: min(256, c.size)] = counts[: min(256, c.size)]
        for db in (0.5, 0.25, 1.0, 0.0371):
            got = power_of_counts(c, db)
            want = counts_to_power(c.astype(np.float32) / np.float32(255.0), db)
            assert got.dtype == np.float32 and got.shape == c.shape
            assert np.array_equal(got.view(np.uint32), want.view(np.uint32))
    # and the table against the dB formula computed on its own
    assert np.array_equal(_power_table(0.5), (10.0 ** (np.arange(256) * 0.5 / 10.0)).astype(np.float32))
    # the other look-ups: a view whose pixels are not contiguous in a row, and more than two dimensions
    c = rng.integers(0, 256, size=(30, 40), dtype=np.uint8)
    for view in (c[:, ::2], c.reshape(2, 15, 40), c.T):
        got = power_of_counts(view, 0.5)
        want = counts_to_power(view.astype(np.float32) / np.float32(255.0), 0.5)
        assert got.shape == view.shape and np.array_equal(got.view(np.uint32), want.view(np.uint32))
    with pytest.raises(TypeError, match="uint8"):
        power_of_counts(np.zeros((20, 20), np.float32), 0.5)


def test_real_radiate_and_oxford_scans_decode_as_pillow_reads_them():
    root = os.environ.get("IMPALA_FLOW_TEST_DATA")
    if not root:
        pytest.skip("IMPALA_FLOW_TEST_DATA not set")
    radiate = sorted((Path(root) / "radiate-edinburgh-head" / "Navtech_Polar").glob("*.png"))[::40]
    oxford = sorted((Path(root) / "oxford-radar-robotcar-sample" / "radar").glob("*.png"))[:3]
    if not radiate or not oxford:
        pytest.skip("RADIATE or Oxford sample missing")
    for path in radiate:  # Sub, Up, Average and Paeth rows
        assert np.array_equal(decode_grey8(path), np.asarray(Image.open(path)))
    for path in oxford:
        pixels = np.asarray(Image.open(path))
        scan = read_navtech_png(path)
        assert np.array_equal(scan.counts, pixels[:, 11:])
        assert np.array_equal(scan.power, pixels[:, 11:].astype(np.float32) / np.float32(255.0))
