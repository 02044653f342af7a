"""Our dataset readers against the datasets' official kits, on the same files (issue 23 item 6).

    python bench/readers_kits.py                          # data from $IMPALA_FLOW_TEST_DATA
    python bench/readers_kits.py --kits DIR --quick       # DIR: checkouts of the kits; skip the slow measurements

For each format, our reader (``impala_radar.datasets``, the defaults ``impala-flow import`` uses)
and the official kit's decode of the same PNGs: per-row times, azimuths, power values, flag or
chirp column, and the range of each bin, with the largest differences. The kits are never part
of this project: pyboreas is imported if installed (``pip install asrl-pyboreas``, it needs
``asrl-pylgmath`` and ``asrl-pysteam`` to import); the Oxford SDK (``robotcar-dataset-sdk``) and
``radiate_sdk`` are not on PyPI and are read from ``--kits DIR`` (or ``$IMPALA_FLOW_KITS``),
a folder holding their checkouts. A kit that is missing is skipped with one line saying so.

Measurements (the evidence for the readers' defaults; ``--quick`` skips the slow ones):

* Boreas: the notch of zero beat frequency (the IF high-pass) in the mean near-range power of
  the frame's down-chirp azimuths; its parabola vertex, as a range through the reader's bin
  geometry, should be 0 m.
* RADIATE and Oxford: the direction of the car's motion in the radar frame. Consecutive scans
  drawn as Cartesian images (0.2 m cells, 4-70 m) are phase-correlated over a set of trial
  rotations; the translation's angle, regressed on the turn per metre (the lever arm of a
  radar ahead of the rear axle), has as intercept the radar's yaw against the vehicle's axis:
  0 when the azimuth offset is right.
* RADIATE's own Cartesian images (radiate_sdk's tiny_foggy sample, when in ``--kits``): the
  clockwise angle at which polar column 0 is drawn, and the rotation sense, fitted.

The last line is one JSON object with every figure.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import math
import os
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "plugins")]

from impala_flow.msgs import wrap_angle  # noqa: E402
from impala_radar.datasets.boreas import BOREAS_RANGE_OFFSET_M  # noqa: E402
from impala_radar.datasets.formats import open_dataset  # noqa: E402

OUT: dict[str, float | int | str] = {}


def say(key: str, value: float | int | str, text: str) -> None:
    OUT[key] = value
    print(f"  {text}")


def _load_file(name: str, path: Path, extra_path: Path | None = None):  # noqa: ANN202
    if extra_path is not None and str(extra_path) not in sys.path:
        sys.path.insert(0, str(extra_path))
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)  # type: ignore[union-attr]
    return mod


def _find(kits: Path | None, *names: str) -> Path | None:
    if kits is None:
        return None
    for n in names:
        for cand in [kits / n, *kits.glob(f"*{n}*")]:
            if cand.is_dir():
                return cand
    return None


def _deg(a: np.ndarray) -> np.ndarray:
    return np.degrees(wrap_angle(np.asarray(a, dtype=np.float64)))


# --- Oxford ------------------------------------------------------------------------------

def oxford(data: Path, kits: Path | None) -> None:
    folder = data / "oxford-radar-robotcar-sample"
    print("oxford (robotcar-dataset-sdk python/radar.py)")
    if not folder.is_dir():
        print(f"  skipped: no {folder}")
        return
    sdk = _find(kits, "robotcar-dataset-sdk")
    if sdk is None or not (sdk / "python" / "radar.py").is_file():
        print("  skipped: the Oxford SDK is not installed (not on PyPI): give --kits DIR holding a "
              "robotcar-dataset-sdk checkout")
        return
    radar = _load_file("oxford_sdk_radar", sdk / "python" / "radar.py")
    ds = open_dataset("oxford", str(folder))
    cfg = ds.config
    dt, daz, dp, dflag = 0, [], 0.0, 0
    for k, path in enumerate(ds.scan_paths):
        t, az, valid, fft, res = radar.load_radar(str(path))
        s = ds.read_scan(k)
        dt = max(dt, int(np.abs(s.t_ns - t[:, 0].astype(np.int64) * 1000).max()))
        daz.append(_deg(s.azimuth_rad - (-az[:, 0].astype(np.float64))))  # SDK: clockwise, ours CCW + offset
        dp = max(dp, float(np.abs(s.power - fft[:, :, 0]).max()))
        dflag += int(np.count_nonzero(s.keep != valid[:, 0]))
    daz = np.concatenate(daz)
    kb = np.arange(cfg.n_bins)
    sdk_range = (kb + 0.5) * float(res[0])  # radar_polar_to_cartesian: sample_u = (r - res / 2) / res
    dr = cfg.range_of_bin_m(kb) - sdk_range
    say("oxford_dt_ns_max", dt, f"row times: max |ours - SDK| = {dt} ns")
    say("oxford_daz_deg_mean", round(float(daz.mean()), 4), f"azimuth ours - SDK (float32 rad): {daz.mean():+.4f} deg "
        f"mean, spread {np.ptp(daz):.2e} deg (our default offset {ds.azimuth_offset_deg:+.2f} deg, measured)")
    say("oxford_dpower_max", dp, f"power (value / 255): max |ours - SDK| = {dp:.2e}")
    say("oxford_valid_rows_differ", dflag, f"valid rows: {dflag} differ")
    say("oxford_drange_m_bin0", round(float(dr[0]), 5), f"range of bin k: ours (k + 0.5) x {cfg.range_per_bin_m:.5f} m "
        f"vs SDK (k + 0.5) x {float(res[0]):.4f} m: {dr[0]:+.4f} m at bin 0, {dr[-1]:+.3f} m at bin {kb[-1]} "
        f"(the resolution measured on the ground truth, 0.0438, against the README's 0.0432)")
    OUT["oxford_drange_m_last"] = round(float(dr[-1]), 4)


# --- Boreas ------------------------------------------------------------------------------

def boreas(data: Path, kits: Path | None, quick: bool) -> None:
    folder = data / "boreas-frame"
    print("boreas (pyboreas.utils.radar.load_radar)")
    if not folder.is_dir():
        print(f"  skipped: no {folder}")
        return
    ds = open_dataset("boreas", str(folder))
    cfg = ds.config
    s = ds.read_scan(0)
    res = cfg.range_per_bin_m
    kb = np.arange(cfg.n_bins)
    doc = kb * res + BOREAS_RANGE_OFFSET_M  # DATA_REFERENCE.md: range_m = bin_index * resolution + radar_offset
    say("boreas_drange_doc_m", float(np.abs(cfg.range_of_bin_m(kb) - doc).max()),
        f"range of bin k: max |ours - documented k x {res} - 0.31 m| = "
        f"{np.abs(cfg.range_of_bin_m(kb) - doc).max():.1e} m;"
        f" pyboreas' Cartesian images use (k + 0.5) x res: {cfg.range_of_bin_m(0) - 0.5 * res:+.4f} m from ours")
    OUT["boreas_drange_cartesian_m"] = round(float(cfg.range_of_bin_m(0) - 0.5 * res), 5)
    # evidence: the zero-beat-frequency notch (down-chirp rows)
    png = cv2.imread(str(ds.scan_paths[0]), cv2.IMREAD_UNCHANGED)
    down = png[:, 10] == 0
    m = png[down, 11:].astype(np.float64).mean(0)
    k0 = 5 + int(np.argmin(m[5:14]))
    c = np.polyfit(np.arange(k0 - 2, k0 + 3), m[k0 - 2:k0 + 3], 2)
    notch = -c[1] / (2 * c[0])
    say("boreas_notch_bin", round(float(notch), 2), f"zero-beat-frequency notch of the {int(down.sum())} down-chirp "
        f"azimuths at bin {notch:.2f}: range {float(cfg.range_of_bin_m(notch)):+.3f} m with ours (0 expected), "
        f"{(notch + 0.5) * res:+.3f} m with bin centres")
    OUT["boreas_notch_range_m"] = round(float(cfg.range_of_bin_m(notch)), 4)
    try:
        from pyboreas.utils.radar import load_radar
    except ImportError as e:
        print(f"  skipped the pyboreas comparison: pyboreas is not installed or not importable ({e}); "
              "pip install asrl-pyboreas asrl-pylgmath asrl-pysteam")
        return
    t, az, chirp, fft, res_kit = load_radar(str(ds.scan_paths[0]))
    blank = int(round(2.5 / res_kit))
    say("boreas_dt_ns_max", int(np.abs(s.t_ns - t[:, 0].astype(np.int64) * 1000).max()),
        f"row times: max |ours - pyboreas| = {int(np.abs(s.t_ns - t[:, 0].astype(np.int64) * 1000).max())} ns")
    daz = _deg(s.azimuth_rad + az[:, 0].astype(np.float64))
    say("boreas_daz_deg_max", float(np.abs(daz).max()), f"azimuth ours (CCW) + pyboreas (CW, float32): max "
        f"{np.abs(daz).max():.1e} deg")
    say("boreas_resolution_m", float(res_kit), f"resolution: ours {res} m, pyboreas {res_kit} m")
    ours_chirp = s.chirp if s.chirp is not None else np.zeros(len(s.t_ns), dtype=np.int8)
    say("boreas_chirp_rows_differ", int(np.count_nonzero(ours_chirp != np.where(chirp[:, 0], 1, -1))),
        f"chirp: rows where ours (+1/-1) differs from pyboreas (chirp_type == 1 up): "
        f"{int(np.count_nonzero(ours_chirp != np.where(chirp[:, 0], 1, -1)))} of {len(ours_chirp)}")
    dp_far = float(np.abs(s.power[:, blank:] - fft[:, blank:]).max())
    lost = int(np.count_nonzero(s.power[:, :blank]))
    say("boreas_dpower_max_beyond_blank", dp_far, f"power beyond pyboreas' blanked {blank} bins (2.5 m): max |ours - "
        f"pyboreas| = {dp_far:.1e}; before them pyboreas zeroes {lost} non-zero values that we keep")
    OUT["boreas_blanked_bins"] = blank


# --- RADIATE -----------------------------------------------------------------------------

def _cartesian(ds, k: int, cell: float, n: int, dither: float = 0.0) -> np.ndarray:  # noqa: ANN001
    """Scan k drawn with the reader's geometry: row up = forward, column left = +y; the grid moved
    by ``dither`` cells along both axes."""
    cfg = ds.config
    ii, jj = np.mgrid[0:n, 0:n].astype(np.float64)
    x, y = (n / 2 - 0.5 - ii + dither) * cell, (n / 2 - 0.5 - jj + dither) * cell
    r, a = np.hypot(x, y), np.arctan2(y, x)
    s = ds.read_scan(k)
    az = np.unwrap(s.azimuth_rad)
    order = np.argsort(az)
    az, p = az[order], s.power[order]
    u = np.interp(np.mod(a - az[0], 2 * np.pi) + az[0], np.r_[az, az[0] + 2 * np.pi], np.arange(len(az) + 1))
    v = (r - cfg.range_offset_m) / cfg.range_per_bin_m
    img = cv2.remap(np.concatenate([p, p[:1]], 0).astype(np.float32), v.astype(np.float32), u.astype(np.float32),
                    cv2.INTER_LINEAR, borderValue=0)
    img[(r < 4.0) | (r > 70.0)] = 0.0
    return img


def motion_direction(ds, first: int = 0, cell: float = 0.2, n: int = 800) -> tuple[float, float, int]:  # noqa: ANN001
    """(intercept deg, its standard error, pairs): the angle of the car's motion in the radar
    frame at zero turn, from consecutive scans moving more than 0.8 m (see the module doc).
    cv2.phaseCorrelate's sub-pixel peak is pulled toward whole cells (a 0.25-cell shift reads
    0.17): the current scan is drawn twice, its grid moved by 0.25 and 0.75 cell, and the two
    shifts, less those, averaged, which cancels that periodic bias to first order."""
    win = cv2.createHanningWindow((n, n), cv2.CV_32F)
    centre = (n / 2 - 0.5, n / 2 - 0.5)
    prev = _cartesian(ds, first, cell, n)
    rows = []
    for k in range(first + 1, len(ds.scan_paths)):
        est = []
        for dither in (0.25, 0.75):
            cur = _cartesian(ds, k, cell, n, dither)
            best = None
            for d in np.arange(-4.0, 4.01, 0.25):  # cv2 has no rotation-invariant phase correlation: trial rotations
                rc = cv2.warpAffine(cur, cv2.getRotationMatrix2D(centre, float(d), 1.0), (n, n))
                (dx, dy), resp = cv2.phaseCorrelate(prev * win, rc * win)
                if best is None or resp > best[0]:
                    best = (resp, d, (dy - dither) * cell, (dx - dither) * cell)
            est.append(best[1:])
        rows.append(np.mean(est, axis=0))
        prev = _cartesian(ds, k, cell, n)
    d, fwd, left = np.array(rows).T
    step = np.hypot(fwd, left)
    m = step > 0.8
    ang = np.arctan2(left[m], fwd[m])
    a = np.c_[np.ones(m.sum()), np.radians(d[m]) / step[m]]
    coef, *_ = np.linalg.lstsq(a, ang, rcond=None)
    resid = ang - a @ coef
    cov = np.linalg.inv(a.T @ a) * resid.var(ddof=2)
    return math.degrees(coef[0]), math.degrees(math.sqrt(cov[0, 0])), int(m.sum())


def radiate_cartesian_fit(tiny: Path) -> tuple[float, float, float]:
    """(clockwise angle of polar column 0 in RADIATE's Cartesian images, rms residual cw, rms ccw)."""
    from scipy.ndimage import map_coordinates
    from scipy.optimize import minimize_scalar

    n, cell = 1152, 0.17361
    rng = np.random.default_rng(0)
    i, j = rng.integers(0, n, 200_000), rng.integers(0, n, 200_000)
    xf, yl = 576.0 - i, 575.0 - j  # origin fitted on the 18 pairs: row 576, column 575
    r = np.hypot(xf, yl) * cell
    keep = (r > 3.0) & (r < 95.0)
    i, j, xf, yl, r = i[keep], j[keep], xf[keep], yl[keep], r[keep]
    pairs = [(cv2.imread(str(tiny / "Navtech_Polar" / f"{f:06d}.png"), 0).astype(np.float64),
              cv2.imread(str(tiny / "Navtech_Cartesian" / f"{f:06d}.png"), 0).astype(np.float64)) for f in (1, 7, 13)]

    def cost(th0: float, sense: int) -> float:
        th = np.degrees(np.arctan2(-sense * yl, xf))
        u = np.mod(th - th0, 360.0) / 0.9
        v = r / cell
        return float(np.mean([np.mean((map_coordinates(np.concatenate([p, p[:, :1]], 1), [v, u], order=1)
                                       - c[i, j]) ** 2) for p, c in pairs]))

    best = minimize_scalar(lambda t: cost(t, 1), bounds=(-2.0, 2.0), method="bounded", options={"xatol": 1e-3})
    ccw = min(cost(t, -1) for t in np.arange(-2.0, 2.01, 0.25))
    return float(best.x), math.sqrt(best.fun), math.sqrt(ccw)


def radiate(data: Path, kits: Path | None, quick: bool) -> None:
    print("radiate (radiate_sdk radiate.py)")
    folder = data / "radiate-edinburgh-head"
    if not folder.is_dir():
        folder = data / "radiate-fog-6-0-head"
    if not folder.is_dir():
        print("  skipped: no RADIATE sample")
        return
    ds = open_dataset("radiate", str(folder))
    cfg = ds.config
    # radiate_sdk README: polar index 0 = 0 m, index 575 = 100 m; config range_res 0.173611, 400 azimuth cells
    say("radiate_drange_m", round(float(cfg.range_of_bin_m(0)), 5), f"range of bin k: ours (k + 0.5) x "
        f"{cfg.range_per_bin_m} m, the SDK's README k x 0.17361 m: {cfg.range_of_bin_m(0):+.4f} m at every bin")
    s = ds.read_scan(0)
    sdk_cw = np.radians(np.arange(cfg.beams_per_turn) * 360.0 / 400)
    daz = _deg(s.azimuth_rad + sdk_cw)
    say("radiate_daz_deg", round(float(daz.mean()), 4), f"azimuth ours - SDK's (column j at j x 0.9 deg clockwise): "
        f"{daz.mean():+.3f} deg (spread {np.ptp(daz):.1e}), our measured offset")
    sdk = _find(kits, "radiate_sdk")
    if sdk is None or not (sdk / "radiate.py").is_file():
        print("  skipped the radiate_sdk comparison: radiate_sdk is not installed (not on PyPI): give --kits DIR "
              "holding a radiate_sdk checkout")
    else:
        rad = _load_file("radiate_sdk_radiate", sdk / "radiate.py", extra_path=sdk)
        seq = object.__new__(rad.Sequence)  # only its time parser: no config or sensors needed
        kit_t = np.array(seq.load_timestamp(str(folder / "Navtech_Polar.txt"))["time"])
        dt = np.abs(ds.frame_t_ns / 1e9 - kit_t)
        say("radiate_dt_s_max", float(dt.max()), f"frame times: max |ours - SDK (float s)| = {dt.max():.1e} s "
            f"(float64 of ~1.5e9 s: {np.spacing(kit_t.max()):.1e} s)")
        dp = 0.0
        for k in range(min(10, len(ds.scan_paths))):
            img = cv2.imread(str(ds.scan_paths[k]))  # the SDK reads every image so (3 equal channels)
            dp = max(dp, float(np.abs(ds.read_scan(k).power - img[:, :, 0].T / 255.0).max()))
        say("radiate_dpower_max", dp, f"power of the first 10 scans: max |ours - SDK's image / 255| = {dp:.1e}")
        tiny = sdk / "data" / "radiate" / "tiny_foggy"
        if (tiny / "Navtech_Cartesian").is_dir() and not quick:
            th0, rms_cw, rms_ccw = radiate_cartesian_fit(tiny)
            say("radiate_cartesian_col0_cw_deg", round(th0, 3), f"RADIATE's Cartesian images draw column j at "
                f"j x 0.9 {th0:+.3f} deg clockwise of up (rms {rms_cw:.1f} counts; counter-clockwise at best "
                f"{rms_ccw:.1f}): a drawing convention, not the mounting")
            OUT["radiate_cartesian_rms_cw"], OUT["radiate_cartesian_rms_ccw"] = round(rms_cw, 2), round(rms_ccw, 2)
        if (tiny / "Navtech_Polar").is_dir() and not quick:
            tds = open_dataset("radiate", str(tiny))
            a, e, n = motion_direction(tds)
            say("radiate_fog_motion_deg", round(a, 3), f"fog_6_0 (radiate_sdk, 18 scans): motion {a:+.2f} +- {e:.2f} "
                f"deg from the radar's forward with our offset ({n} pairs; 0 when right)")
    if not quick and (data / "radiate-edinburgh-head").is_dir():
        first = 240  # the car waits about a minute, then drives
        for off, key in ((ds.azimuth_offset_deg, "radiate_edinburgh_motion_deg"),
                         (0.0, "radiate_edinburgh_motion_deg_off0")):
            d0 = open_dataset("radiate", str(data / "radiate-edinburgh-head"), azimuth_offset_deg=off)
            a, e, n = motion_direction(d0, first)
            say(key, round(a, 3), f"Edinburgh scans {first + 1}-400: motion {a:+.2f} +- {e:.2f} deg from the radar's "
                f"forward with offset {off:+.2f} deg ({n} pairs)")
    if not quick and (data / "oxford-radar-robotcar-sample").is_dir():
        d0 = open_dataset("oxford", str(data / "oxford-radar-robotcar-sample"), azimuth_offset_deg=0.0)
        a, e, n = motion_direction(d0)
        say("oxford_motion_deg_off0", round(a, 3), f"method check, Oxford with offset 0: motion {a:+.2f} +- {e:.2f} "
            f"deg "
            f"({n} pairs; its ground truth gave -0.95 deg)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=os.environ.get("IMPALA_FLOW_TEST_DATA", str(ROOT.parent / "shared" / "data")))
    ap.add_argument("--kits", default=os.environ.get("IMPALA_FLOW_KITS"),
                    help="folder holding checkouts of robotcar-dataset-sdk and radiate_sdk")
    ap.add_argument("--quick", action="store_true", help="skip the slow measurements (motion, Cartesian fit)")
    args = ap.parse_args()
    data, kits = Path(args.data), Path(args.kits) if args.kits else None
    oxford(data, kits)
    boreas(data, kits, args.quick)
    radiate(data, kits, args.quick)
    print(json.dumps(OUT, sort_keys=True))


if __name__ == "__main__":
    main()
