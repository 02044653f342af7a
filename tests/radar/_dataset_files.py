"""Synthetic dataset files for the reader tests: Navtech PNGs with the 11-byte row header
(Oxford/Boreas layout), RADIATE polar PNGs and frame-time indexes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

ROW_US = 625  # 400 rows x 625 us = one 4 Hz turn


def navtech_png(path: Path, t0_us: int, n_bins: int = 20, rows: int = 400, flag: int | np.ndarray = 255,
                seed: int = 0, times_us: np.ndarray | None = None) -> np.ndarray:
    """Write an 8-bit grey Navtech PNG (timestamps, encoder 7 + 14 k, flag, random power)."""
    img = np.zeros((rows, 11 + n_bins), dtype=np.uint8)
    t = t0_us + ROW_US * np.arange(rows, dtype=np.int64) if times_us is None else np.asarray(times_us, np.int64)
    img[:, :8] = t.astype("<i8").view(np.uint8).reshape(rows, 8)
    enc = (7 + 14 * np.arange(rows)).astype("<u2")
    img[:, 8:10] = enc.view(np.uint8).reshape(rows, 2)
    img[:, 10] = flag
    img[:, 11:] = np.random.default_rng(seed).integers(0, 256, (rows, n_bins), dtype=np.uint8)
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(img).save(path)
    return img


def navtech_folder(folder: Path, n_scans: int = 3, t0_us: int = 1_700_000_000_000_000, **kw) -> list[Path]:
    paths = []
    for k in range(n_scans):
        t = t0_us + k * 400 * ROW_US
        paths.append(folder / "radar" / f"{t}.png")
        navtech_png(paths[-1], t, seed=k, **kw)
    return paths


def radiate_time(seconds: str) -> str:
    """Decimal seconds (``"100.25"``) written as RADIATE writes them: ``<s>.<ns>`` with the
    nanoseconds' leading zeros dropped (``"100.250000000"``; 100.01 s is ``"100.10000000"``)."""
    s, _, frac = seconds.partition(".")
    return f"{s}.{int(frac.ljust(9, '0')[:9])}"


def radiate_folder(folder: Path, times: list[str], rows: int = 30, cols: int = 400) -> list[Path]:
    """``Navtech_Polar/00000k.png`` (rows range bins x cols azimuths) and ``Navtech_Polar.txt``."""
    (folder / "Navtech_Polar").mkdir(parents=True, exist_ok=True)
    lines, paths = [], []
    for k, t in enumerate(times, start=1):
        img = np.random.default_rng(k).integers(0, 256, (rows, cols), dtype=np.uint8)
        paths.append(folder / "Navtech_Polar" / f"{k:06d}.png")
        Image.fromarray(img).save(paths[-1])
        lines.append(f"Frame: {k:06d} Time: {radiate_time(t)}")
    (folder / "Navtech_Polar.txt").write_text("\n".join(lines) + "\n")
    return paths
