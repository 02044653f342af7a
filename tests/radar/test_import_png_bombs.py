"""Scan files that are not what their name says: decompression bombs (a PNG header declaring far more
pixels than any radar scan), files that are no PNG (JPEG, text, empty, a folder, a pipe) and PNGs whose
image data is corrupt. Each is refused from its header, before anything is decoded, with one line naming
the file; --skip-bad-scans skips it, counted and reported. Synthetic files made here: the PNG chunks are
written by hand (struct + zlib, the PNG specification's layout) so that the header can lie."""

from __future__ import annotations

import io
import os
import struct
import subprocess
import sys
import zlib

import numpy as np
import pytest
from PIL import Image

from impala_flow.cli import main

from ._dataset_files import navtech_folder, radiate_folder

SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def _png(rows: int, cols: int, idat: bytes) -> bytes:
    """An 8-bit grey PNG declaring rows x cols, with ``idat`` as its (zlib) image data."""
    return (SIGNATURE + _chunk(b"IHDR", struct.pack(">IIBBBBB", cols, rows, 8, 0, 0, 0, 0))
            + _chunk(b"IDAT", idat) + _chunk(b"IEND", b""))


def _bomb(rows: int, cols: int) -> bytes:
    """A small file declaring rows x cols grey pixels (its data a few zero rows: a decoder would allocate the
    declared size before finding out)."""
    return _png(rows, cols, zlib.compress(b"\0" * (cols + 1) * 4, 9))


def _import(fmt, folder, *extra):
    out = folder.parent / f"{folder.name}-out.mcap"
    code = main(["import", fmt, str(folder), "-o", str(out), "--no-progress", *extra])
    return code, out


def _one_error_line(capfd) -> str:
    """The one line the command wrote on stderr; fd-level capture: a C library's own messages count too."""
    err = capfd.readouterr().err.strip().splitlines()
    assert len(err) == 1, err
    return err[0]


def test_a_header_of_50000_x_50000_is_refused_naming_the_file_and_skipped(folder, capfd):
    paths = navtech_folder(folder, n_scans=3)
    paths[1].write_bytes(_bomb(50_000, 50_000))
    code, out = _import("oxford", folder)
    line = _one_error_line(capfd)
    assert code == 1 and not out.exists()
    # 50000 x 50000 bytes = 2384 MiB, against a 64 MiB bound
    assert line.endswith(f"{paths[1]}: PNG of 50000 rows x 50000 columns (2384 MiB decoded), more than any "
                         "radar scan (64 MiB at most): not decoded")
    code, out = _import("oxford", folder, "--skip-bad-scans")
    text = capfd.readouterr().out
    assert code == 0 and out.exists()
    assert "turns:        2" in text and "beams:        800" in text  # the two good scans, every row
    assert f"scans skipped: 1 ({paths[1]}: PNG of 50000 rows x 50000 columns" in text


def test_a_first_scan_of_40000_rows_is_refused_before_decoding(folder, capfd):
    """The 147 kB file of the issue, 3779 x 40000, as the first scan (which gives the shape of the others):
    144 MiB declared. Under the byte bound, a Navtech turn still has at most one row per encoder count."""
    paths = navtech_folder(folder, n_scans=2)
    paths[0].write_bytes(_bomb(40_000, 3779))
    code, _ = _import("boreas", folder)
    assert code == 1
    assert _one_error_line(capfd).endswith(f"{paths[0]}: PNG of 40000 rows x 3779 columns (144 MiB decoded), more "
                                           "than any radar scan (64 MiB at most): not decoded")
    paths[0].write_bytes(_bomb(6000, 3779))  # 21.6 MiB
    code, _ = _import("oxford", folder)
    assert code == 1
    assert _one_error_line(capfd).endswith(
        f"{paths[0]}: 6000 rows, more than the 5600 encoder counts of a turn (one row per azimuth): not decoded")


@pytest.mark.parametrize("fmt", ["oxford", "radiate"])
def test_a_bad_first_scan_is_skipped_and_the_others_keep_their_shape(folder, capfd, fmt):
    """The first scan no longer sets the shape alone: with --skip-bad-scans a bomb in first place is skipped
    like any other, and the remaining scans import whole (their own shape, every row)."""
    if fmt == "oxford":
        paths = navtech_folder(folder, n_scans=3)
        rows = 400
    else:
        paths = radiate_folder(folder, ["100.0", "100.25", "100.5"], rows=30)
        rows = 400  # azimuths: the PNG's columns
    paths[0].write_bytes(_bomb(50_000, 50_000))
    code, out = _import(fmt, folder)
    assert code == 1 and not out.exists()
    assert _one_error_line(capfd).endswith(f"{paths[0]}: PNG of 50000 rows x 50000 columns (2384 MiB decoded), "
                                           "more than any radar scan (64 MiB at most): not decoded")
    code, out = _import(fmt, folder, "--skip-bad-scans")
    text = capfd.readouterr().out
    assert code == 0 and out.exists(), text
    assert "turns:        2" in text and f"beams:        {2 * rows}" in text
    assert f"scans skipped: 1 ({paths[0]}: PNG of 50000 rows" in text


def test_a_radiate_bomb_is_refused_and_skipped(folder, capfd):
    paths = radiate_folder(folder, ["100.0", "100.25", "100.5"], rows=30)
    paths[1].write_bytes(_bomb(576, 200_000))  # 110 MiB declared
    code, _ = _import("radiate", folder)
    assert code == 1
    assert _one_error_line(capfd).endswith(f"{paths[1]}: PNG of 576 rows x 200000 columns (110 MiB decoded), more "
                                           "than any radar scan (64 MiB at most): not decoded")
    code, _ = _import("radiate", folder, "--skip-bad-scans")
    assert code == 0
    assert f"scans skipped: 1 ({paths[1]}: PNG of 576 rows" in capfd.readouterr().out


def _jpeg(path):
    buf = io.BytesIO()
    Image.fromarray(np.zeros((400, 31), np.uint8)).save(buf, format="JPEG")
    path.write_bytes(buf.getvalue())


def _corrupt_data(path):
    """A valid header of the right shape, its image data a broken zlib stream (chunk CRCs right)."""
    raw = np.random.default_rng(1).integers(0, 256, 400 * 32, dtype=np.uint8).tobytes()
    z = bytearray(zlib.compress(raw))
    z[40:80] = b"\x55" * 40
    path.write_bytes(_png(400, 31, bytes(z)))


def _short_data(path):
    """A valid header, image data for 10 of the 400 rows declared."""
    path.write_bytes(_png(400, 31, zlib.compress(b"\0" * 32 * 10)))


def _flipped_bit(path):
    """A scan as written, one bit of its image data flipped (the chunk's CRC now wrong)."""
    data = bytearray(path.read_bytes())
    data[33 + 8 + 100] ^= 0x10  # inside the first IDAT chunk, after the IHDR chunk
    path.write_bytes(bytes(data))


def _folder(path):
    path.unlink()
    path.mkdir()


@pytest.mark.parametrize(("make", "reason"), [
    (_jpeg, "not a PNG (JPEG image)"),
    (lambda p: p.write_text("timestamp,range\n1,2\n"), "not a PNG (text)"),
    (lambda p: p.write_bytes(b""), "empty file (0 bytes), not a PNG"),
    (lambda p: p.write_bytes(b"\0" * 4096), "not a PNG (unknown binary data)"),
    (_folder, "a folder, not a PNG file"),
    (_corrupt_data, "cannot decode the PNG ("),
    (_short_data, "cannot decode the PNG (image data for 10 of the 400 rows its header declares)"),
    (_flipped_bit, "corrupt PNG (chunk 'IDAT' at byte 33: length or CRC wrong)"),
    (lambda p: p.write_bytes(SIGNATURE + b"\0\0\0\x0dIHDR"), "truncated PNG (16 bytes, no complete header)"),
])
def test_scan_files_that_are_no_png_are_one_located_line_and_skipped(folder, capfd, make, reason):
    paths = navtech_folder(folder, n_scans=3)
    make(paths[1])
    code, out = _import("oxford", folder)
    line = _one_error_line(capfd)
    assert code == 1 and not out.exists()
    assert line.startswith(f"impala-flow import: error: {paths[1]}: {reason}"), line
    code, out = _import("oxford", folder, "--skip-bad-scans")
    text = capfd.readouterr().out
    assert code == 0 and "turns:        2" in text and f"scans skipped: 1 ({paths[1]}: {reason}" in text


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_a_pipe_named_like_a_scan_is_refused_without_blocking(folder, tmp_path):
    """Opening a pipe blocks until a writer comes: the file's kind is checked first."""
    paths = navtech_folder(folder, n_scans=3)
    paths[2].unlink()
    os.mkfifo(paths[2])
    cli = "import sys; from impala_flow.cli import main; sys.exit(main(sys.argv[1:]))"
    cmd = [sys.executable, "-c", cli, "import", "oxford", str(folder), "-o", str(tmp_path / "o.mcap"),
           "--no-progress", "--skip-bad-scans"]
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert f"scans skipped: 1 ({paths[2]}: not a regular file (device, pipe or socket), not read)" in run.stdout
