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


def radiate_time_ns(t_ns: int) -> str:
    """Unix time in ns written as RADIATE writes it (nanoseconds without leading zeros)."""
    return f"{t_ns // 10**9}.{t_ns % 10**9}"


def radiate_folder(folder: Path, times: list[str | int], rows: int = 30, cols: int = 400, first: int = 1,
                   png: bool = True) -> list[Path]:
    """``Navtech_Polar/<frame>.png`` (rows range bins x cols azimuths, frames from ``first``) and
    ``Navtech_Polar.txt``; ``times`` as decimal seconds text or int ns."""
    (folder / "Navtech_Polar").mkdir(parents=True, exist_ok=True)
    lines, paths = [], []
    for k, t in enumerate(times, start=first):
        paths.append(folder / "Navtech_Polar" / f"{k:06d}.png")
        if png:
            img = np.random.default_rng(k).integers(0, 256, (rows, cols), dtype=np.uint8)
            Image.fromarray(img).save(paths[-1])
        lines.append(f"Frame: {k:06d} Time: {radiate_time(t) if isinstance(t, str) else radiate_time_ns(t)}")
    (folder / "Navtech_Polar.txt").write_text("\n".join(lines) + "\n")
    return paths


def en_to_latlon(east_m: np.ndarray, north_m: np.ndarray, lat0_deg: float = 55.9391,
                 lon0_deg: float = -3.2268, alt_m: float = 115.0) -> tuple[np.ndarray, np.ndarray]:
    """East/North (m) around (lat0, lon0) at ``alt_m`` to WGS-84 degrees with the ellipsoid's
    radii of curvature there (first order: about a millimetre over a few hundred metres)."""
    a, f = 6378137.0, 1.0 / 298.257223563
    e2 = f * (2 - f)
    s = np.sin(np.radians(lat0_deg))
    m = a * (1 - e2) / (1 - e2 * s * s) ** 1.5  # meridian
    n = a / np.sqrt(1 - e2 * s * s)  # prime vertical
    return (lat0_deg + np.degrees(np.asarray(north_m) / (m + alt_m)),
            lon0_deg + np.degrees(np.asarray(east_m) / ((n + alt_m) * np.cos(np.radians(lat0_deg)))))


def radiate_gps(folder: Path, t_ns: list[int], east_m, north_m, imu_yaw_enu_rad, cov_en=(0.09, 0.16),
                twice: bool = True, first: int = 1, index_only: tuple[int, ...] = ()) -> list[Path]:
    """``GPS_IMU_Twist/<frame>.txt`` and ``GPS_IMU_Twist.txt`` as RADIATE writes them: every fix
    written twice (two frames, same time) unless ``twice`` is False; line 1 lat, lon, alt;
    lines 2-4 the ENU position covariance (diagonal ``cov_en``, up 0.2); line 5 the IMU
    quaternion (yaw only); 11 more lines. Fixes at ``index_only`` positions get no file."""
    (folder / "GPS_IMU_Twist").mkdir(parents=True, exist_ok=True)
    lat, lon = en_to_latlon(np.asarray(east_m, float), np.asarray(north_m, float))
    imu_yaw_enu_rad = np.asarray(imu_yaw_enu_rad, float).tolist()
    lines, paths, frame = [], [], first
    zero = "0.0, 0.0, 0.0"
    for i, (t, la, lo, yaw) in enumerate(zip(t_ns, lat.tolist(), lon.tolist(), imu_yaw_enu_rad, strict=True)):
        body = [f"{la!r}, {lo!r}, 115.0", f"{cov_en[0]!r}, 0.0, 0.0", f"0.0, {cov_en[1]!r}, 0.0", "0.0, 0.0, 0.2",
                f"0.0, 0.0, {float(np.sin(yaw / 2))!r}, {float(np.cos(yaw / 2))!r}"] + [zero] * 11
        for _ in range(2 if twice else 1):
            path = folder / "GPS_IMU_Twist" / f"{frame:06d}.txt"
            if i not in index_only:
                path.write_text("\n".join(body) + "\n")
            paths.append(path)
            lines.append(f"Frame: {frame:06d} Time: {radiate_time_ns(int(t))}")
            frame += 1
    (folder / "GPS_IMU_Twist.txt").write_text("\n".join(lines) + "\n")
    return paths
