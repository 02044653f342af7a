"""RADIATE's range per bin and the GPS-radar clock offset, measured on the Edinburgh head.

Usage: python bench/radiate_scale.py [FOLDER] [--first 250] [--last 399] [--no-kiss]

Reads the scans and the GPS truth through ``RadiateDataset`` (padded times, late frames on
the turn clock, GPS course-over-ground truth) and measures, independently of the project's
SLAM:

1. **Phase correlation.** Each polar PNG (ring floors removed, first 6 m blanked) is resampled
   with ``cv2.remap`` on a Cartesian grid (0.25 m cells, +-40 m) at the documented 0.17361 m per
   bin; the rotation between scans i and i+k (k = 1..4) is found by maximising OpenCV's
   phase-correlation response over trial rotations of scan i+k (parabola on the best three),
   and the translation by phase correlation refined with an upsampled DFT (matrix-multiply
   DFT, Guizar-Sicairos 2008: OpenCV's 5x5 centroid is biased towards whole pixels, 1-2 % of a
   10-pixel step). Variant ``deskew``: every beam of a turn moved to the turn's first beam
   with the constant twist measured by the first pass (the motion within a turn).
2. **kiss-icp** (the lidar odometry, its own deskew) on the 12 strongest returns per azimuth
   (``extract_peaks``), its path against the GPS path.
3. **The ratio** radar / GPS of the summed displacements over the same times (the middle of
   each turn), on the driving part (whole, first half, second half), by speed, and on the
   straightest stretch; 90 % confidence intervals by a moving-block bootstrap over turns
   (blocks of 5 s) plus the GPS's own error over the stretch (from its wander at rest over the
   same duration). The range per bin that makes the radar agree with the GPS is
   0.17361 m / ratio.
4. **Clock offset.** The GPS is read as stamped (``gps_offset_s=0``). The radar's speed over
   4 turns against the GPS's over the same interval read delta later (-1..3 s, 10 ms steps,
   parabola): the delta with the least squared residual, on the whole driving part and on each
   half, 90 % CI by the block bootstrap; pairs whose shifted window leaves the GPS log are not
   fitted (the interpolation would hold the last fix). ``gps_radar_offset_s`` > 0: a GPS fix is
   stamped that much later than a radar turn at the same time (the reader's
   ``RADIATE_GPS_OFFSET_S``). The ratios of 3. are then repeated with the GPS read at it.

Measured on the Edinburgh head (scans 250-399, ~5 min on one core): offset +1.55 s (90 % CI
1.50-1.58; halves 1.56 and 1.51), speed residual 0.16 m/s rms (0.86 as stamped); ratio with
it 0.9994 (halves 1.0002 / 0.9980; < 5, 5-8, > 8 m/s: 0.996, 1.005, 0.999; kiss-icp 0.9991)
+- 0.015 with the GPS's end-to-end error: 0.1737 +- 0.0027 m per bin. As stamped: 1.030
(halves 1.062 / 1.004), raw consecutive turns 1.047.

Ends with one JSON line.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import cv2
import numpy as np
from scipy import fft as sfft
from scipy import ndimage

from impala_radar.datasets.common import ImportReport
from impala_radar.datasets.radiate import RADIATE_RANGE_RESOLUTION_M, RadiateDataset

DOC_BIN_M = 100.0 / 576.0
SPEED_OF_LIGHT = 299_792_458.0
F0_HZ = 76.5e9  # Navtech CTS350-X: 76-77 GHz
FM_HZ = 1600.0  # one sweep per azimuth: 400 azimuths x 4 turns/s  # the dataset's documentation: 576 bins over 100 m
CELL_M, HALF_M = 0.25, 40.0
BLANK_M = 6.0
RNG = np.random.default_rng(23)


def polar_image(scan) -> np.ndarray:
    """Range bins x azimuth columns (clockwise), ring floors (median over azimuth) removed."""
    img = scan.power.T.astype(np.float32) * np.float32(255.0)
    img = np.maximum(img - np.median(img, axis=1, keepdims=True), 0.0)
    img[: int(BLANK_M / DOC_BIN_M)] = 0.0
    return img


_N = int(HALF_M / CELL_M)
_AX = (_N - np.arange(2 * _N) - 0.5) * CELL_M  # row 0 forward / column 0 left
GRID_X, GRID_Y = np.meshgrid(_AX, _AX, indexing="ij")


def cartesian(img: np.ndarray, bin_m: float, rot_rad: float = 0.0, twist=None, period_s: float = 0.25,
              gx: np.ndarray = GRID_X, gy: np.ndarray = GRID_Y) -> np.ndarray:
    """The polar image on the vehicle grid (x forward, y left) of the turn's first beam,
    turned by ``rot_rad`` (the grid point p looked up at R(rot) p). ``twist`` (vx, vy, w) in m/s,
    rad/s: each beam moved back to the first beam's pose (a point seen at the clockwise angle a
    was seen a / 2 pi turns later, the car having moved by the twist meanwhile)."""
    n_az = img.shape[1]
    c, s = math.cos(rot_rad), math.sin(rot_rad)
    x, y = c * gx - s * gy, s * gx + c * gy
    a = np.mod(-np.arctan2(y, x), 2 * np.pi)
    if twist is not None:
        vx, vy, w = twist
        for _ in range(3):  # fixed point: the angle at which the point is seen
            tau = a / (2 * np.pi) * period_s
            dx, dy, psi = x - vx * tau, y - vy * tau, w * tau
            cp, sp = np.cos(psi), np.sin(psi)
            xr, yr = cp * dx + sp * dy, -sp * dx + cp * dy
            a = np.mod(-np.arctan2(yr, xr), 2 * np.pi)
        r = np.hypot(xr, yr)
    else:
        r = np.hypot(x, y)
    col = (a / (2 * np.pi) * n_az).astype(np.float32)
    row = (r / bin_m - 0.5).astype(np.float32)
    wrap = np.concatenate([img, img[:, :1]], axis=1)  # column n_az interpolates back to column 0
    return cv2.remap(wrap, col, row, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)


_WIN = cv2.createHanningWindow((2 * _N, 2 * _N), cv2.CV_32F)
#: Shifts within this radius are never taken: resampling the polar grid leaves spokes and rings
#: fixed to the sensor in every Cartesian image (a peak at zero shift); a driving step is longer.
MIN_SHIFT_M = 0.6
_I = np.fft.fftfreq(2 * _N) * 2 * _N
_ZERO = (_I[:, None] ** 2 + _I[None, :] ** 2) < (MIN_SHIFT_M / CELL_M) ** 2


def spectrum(img: np.ndarray) -> np.ndarray:
    """The windowed, zero-mean image's spectrum."""
    return sfft.fft2(((img - img.mean()) * _WIN).astype(np.float32))


def _whitened(fa: np.ndarray, fb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    r = fb * np.conj(fa)
    r /= np.abs(r) + 1e-12
    cc = sfft.ifft2(r).real
    cc[_ZERO] = -np.inf
    return r, cc


def upsampled_shift(fa: np.ndarray, fb: np.ndarray, up: int = 20) -> tuple[float, float, float]:
    """(dx_forward_m, dy_left_m, response): where b's content sits relative to a's (b(p) = a(p - d)),
    phase correlation of the spectra ``fa``, ``fb`` with the peak refined on a 1/up-pixel grid by
    a matrix-multiply DFT (Guizar-Sicairos et al., Opt. Lett. 2008; scikit-image is not a
    dependency here)."""
    r, cc = _whitened(fa, fb)
    i0, j0 = np.unravel_index(int(np.argmax(cc)), cc.shape)
    ny, nx = cc.shape
    si = i0 - ny if i0 >= ny // 2 else i0
    sj = j0 - nx if j0 >= nx // 2 else j0
    off = np.arange(-1.5 * up, 1.5 * up + 1) / up
    ky, kx = np.fft.fftfreq(ny), np.fft.fftfreq(nx)
    ey = np.exp(2j * np.pi * np.outer(si + off, ky))
    ex = np.exp(2j * np.pi * np.outer(kx, sj + off))
    fine = (ey @ r @ ex).real / r.size
    p, q = np.unravel_index(int(np.argmax(fine)), fine.shape)
    di, dj = si + off[p], sj + off[q]
    return -di * CELL_M, -dj * CELL_M, float(fine[p, q])  # row index grows backwards, column to the right


def register(pa: np.ndarray, pb: np.ndarray, guess_rad: float, half_deg: float, step_deg: float, bin_m: float,
             twist_a=None, twist_b=None, period_s: float = 0.25) -> tuple[float, float, float, float]:
    """(dx, dy, rot, response) of scan b's content in scan a's frame: the rotation by the best
    phase-correlation peak over trial rotations of b (parabola on the best three), then the
    translation by upsampled_shift."""
    fa = spectrum(cartesian(pa, bin_m, 0.0, twist_a, period_s))
    trials = np.radians(np.arange(-half_deg, half_deg + 1e-9, step_deg)) + guess_rad
    resp = np.array([_whitened(fa, spectrum(cartesian(pb, bin_m, th, twist_b, period_s)))[1].max()
                     for th in trials])
    k = int(np.clip(np.argmax(resp), 1, trials.size - 2))
    y0, y1, y2 = resp[k - 1: k + 2]
    den = y0 - 2 * y1 + y2
    frac = 0.5 * (y0 - y2) / den if den < 0 else 0.0
    rot = float(trials[k] + np.clip(frac, -1, 1) * math.radians(step_deg))
    dx, dy, r = upsampled_shift(fa, spectrum(cartesian(pb, bin_m, rot, twist_b, period_s)))
    return dx, dy, rot, r


def block_bootstrap(n: int, block: int, reps: int = 2000) -> np.ndarray:
    """(reps, n) indices of moving-block resamples of range(n)."""
    starts = RNG.integers(0, max(1, n - block + 1), size=(reps, int(math.ceil(n / block))))
    idx = (starts[:, :, None] + np.arange(block)[None, None, :]).reshape(reps, -1)[:, :n]
    return np.minimum(idx, n - 1)


def ratio_ci(radar: np.ndarray, gps: np.ndarray, block: int) -> tuple[float, float, float]:
    idx = block_bootstrap(radar.size, block)
    boot = radar[idx].sum(axis=1) / gps[idx].sum(axis=1)
    return float(radar.sum() / gps.sum()), float(np.quantile(boot, 0.05)), float(np.quantile(boot, 0.95))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    data = Path(os.environ.get("IMPALA_FLOW_TEST_DATA", "../shared/data"))
    ap.add_argument("folder", nargs="?", default=str(data / "radiate-edinburgh-head"))
    ap.add_argument("--first", type=int, default=250, help="first scan index of the driving part")
    ap.add_argument("--last", type=int, default=399, help="last scan index")
    ap.add_argument("--no-kiss", action="store_true", help="skip kiss-icp")
    ap.add_argument("--no-deskew", action="store_true", help="skip the deskewed second pass")
    ap.add_argument("--k", type=int, nargs="+", default=[1, 4], help="scan spacings registered (1 always)")
    ap.add_argument("--load", default="", metavar="FILE.npz", help="reuse the registrations of --save")
    ap.add_argument("--save", default="", metavar="FILE.npz", help="write the per-pair registrations there")
    args = ap.parse_args()
    t_start = time.perf_counter()
    report = ImportReport()
    ds = RadiateDataset(args.folder, range_resolution_m=DOC_BIN_M, report=report, gps_offset_s=0.0)  # as stamped
    tg, xyt, _ = ds.truth(report)
    period_s = ds.period_ns / 1e9
    idx = np.arange(args.first, min(args.last, len(ds.scan_paths) - 1) + 1)
    print(f"{args.folder}: scans {idx[0]}-{idx[-1]} (frames {ds.frames[idx[0]]:06d}-{ds.frames[idx[-1]]:06d}), "
          f"turn {period_s:.5f} s; documented bin {DOC_BIN_M:.5f} m (reader default {RADIATE_RANGE_RESOLUTION_M})")
    polar = {int(i): polar_image(ds.read_scan(int(i))) for i in idx}
    t_mid = ds.turn_t_ns[idx] + ds.period_ns // 2  # a registration of whole turns: the middle of each

    def gps_at(t_ns: np.ndarray, offset_s: float = 0.0) -> np.ndarray:
        tq = t_ns + int(round(offset_s * 1e9))
        return np.column_stack([np.interp(tq, tg, xyt[:, 0]), np.interp(tq, tg, xyt[:, 1])])

    if args.load:
        saved = np.load(args.load)
        steps_in = {(n.split("_k")[0], int(n.split("_k")[1])): saved[n] for n in saved.files if "_k" in n}
    # --- pass 1: k = 1..4, no deskew --------------------------------------------------------------
    steps: dict[tuple[str, int], np.ndarray] = {}
    dt1 = np.diff(ds.turn_t_ns[idx]) / 1e9
    if args.load:
        steps = steps_in
        res1 = steps[("raw", 1)]
        rots1 = res1[:, 2]
    else:
        rots1 = np.zeros(idx.size - 1)
        res1 = np.zeros((idx.size - 1, 4))
        guess = 0.0
        for m in range(idx.size - 1):
            wide = 4.0 if m == 0 else 2.0
            dx, dy, rot, r = register(polar[int(idx[m])], polar[int(idx[m + 1])], guess, wide, 1.0, DOC_BIN_M)
            dx, dy, rot, r = register(polar[int(idx[m])], polar[int(idx[m + 1])], rot, 0.3, 0.15, DOC_BIN_M)
            res1[m] = dx, dy, rot, r
            rots1[m] = guess = rot
        steps[("raw", 1)] = res1
        for k in sorted(set(args.k) - {1}):
            out = np.zeros((idx.size - k, 4))
            for m in range(idx.size - k):
                g = float(rots1[m:m + k].sum())
                g = register(polar[int(idx[m])], polar[int(idx[m + k])], g, 1.5, 0.5, DOC_BIN_M)[2]
                out[m] = register(polar[int(idx[m])], polar[int(idx[m + k])], g, 0.3, 0.15, DOC_BIN_M)
            steps[("raw", k)] = out
        print(f"phase correlation, pass 1: {time.perf_counter() - t_start:.0f} s")
        # --- pass 2: deskewed with the constant twist of pass 1 (k = 1 and 4) ---------------------------
        dt1 = np.diff(ds.turn_t_ns[idx]) / 1e9
        # the car's twist (the content moves opposite to the car): turn m's, the mean of the motions
        # into and out of it
        mot = -np.column_stack([res1[:, 0] / dt1, res1[:, 1] / dt1, res1[:, 2] / dt1])
        tw = 0.5 * (np.vstack([mot[:1], mot]) + np.vstack([mot, mot[-1:]]))
        if not args.no_deskew:
            for k in (1, max(args.k)):
                out = np.zeros((idx.size - k, 4))
                for m in range(idx.size - k):
                    g = float(steps[("raw", k)][m, 2])
                    out[m] = register(polar[int(idx[m])], polar[int(idx[m + k])], g, 0.3, 0.15, DOC_BIN_M,
                                      tuple(tw[m]), tuple(tw[m + k]), period_s)
                steps[("deskew", k)] = out
            print(f"phase correlation, pass 2 (deskewed): {time.perf_counter() - t_start:.0f} s")

    if args.save:
        np.savez(args.save, idx=idx, t_mid=t_mid, turn_t_ns=ds.turn_t_ns[idx], tg=tg, xyt=xyt,
                 **{f"{kind}_k{k}": v for (kind, k), v in steps.items()})
    # --- ratios -------------------------------------------------------------------------------------
    block = max(2, int(round(5.0 / period_s)))
    p_mid = gps_at(t_mid)
    speed = np.linalg.norm(np.diff(p_mid, axis=0), axis=1) / dt1  # GPS speed per turn (k = 1)
    driving = speed > 2.0
    n1 = idx.size - 1
    half = n1 // 2
    straight = np.abs(np.degrees(rots1)) < 0.5
    summary: dict[str, tuple[float, float, float]] = {}
    k1_med = ndimage.median_filter(np.hypot(res1[:, 0], res1[:, 1]), 5, mode="nearest")
    print("\nratio radar / GPS of summed displacements over the same times (90 % CI, block bootstrap over turns)")
    print(f"{'method':<10}{'k':>3}  {'set':<22}{'turns':>6}{'GPS m':>8}{'ratio':>8}   CI")
    for (kind, k), out in steps.items():
        p0, p1 = p_mid[: n1 + 1 - k], p_mid[k:]
        gps = np.linalg.norm(p1 - p0, axis=1)
        rad = np.hypot(out[:, 0], out[:, 1])
        first_speed = speed[: gps.size]
        # radar-only sanity: a step within 15 % of the sum of k median-filtered consecutive steps
        expect = np.convolve(k1_med, np.ones(k), "valid")
        good = driving[: gps.size] & (np.abs(rad - expect) < 0.15 * expect)
        print(f"{kind} k={k}: {int((driving[: gps.size] & ~good).sum())} of {int(driving[: gps.size].sum())} "
              "driving registrations off their neighbours by > 15 %: not counted")
        sets = {"driving": good, "first half": good & (np.arange(gps.size) < half),
                "second half": good & (np.arange(gps.size) >= half),
                "< 5 m/s": good & (first_speed < 5.0), "5-8 m/s": good & (first_speed >= 5) & (first_speed < 8),
                "> 8 m/s": good & (first_speed >= 8.0)}
        if k == 1:
            sets["straight (|rot| < 0.5 deg)"] = good & straight
        for name, sel in sets.items():
            if sel.sum() < 5:
                continue
            ratio, lo, hi = ratio_ci(rad[sel], gps[sel], block)
            summary[f"{kind} k={k} {name}"] = (ratio, lo, hi)
            print(f"{kind:<10}{k:>3}  {name:<22}{int(sel.sum()):>6}{gps[sel].sum():8.1f}{ratio:8.4f}   "
                  f"[{lo:.4f}, {hi:.4f}]")

    # --- GPS error over the stretch, from its wander at rest --------------------------------------
    rest = (tg < ds.turn_t_ns[max(0, args.first - 20)])
    dur_ns = int(ds.turn_t_ns[idx[-1]] - ds.turn_t_ns[idx[0]])
    tr = tg[rest]
    wander = np.nan
    if tr.size and tr[-1] - tr[0] > dur_ns // 2:
        d_ns = min(dur_ns, int(tr[-1] - tr[0]) // 2)
        t0s = np.linspace(tr[0], tr[-1] - d_ns, 50).astype(np.int64)
        e0, e1 = gps_at(t0s), gps_at(t0s + d_ns)
        wander = float(np.sqrt(np.mean(np.sum((e1 - e0) ** 2, axis=1))))
        print(f"\nGPS wander at rest over {d_ns / 1e9:.0f} s: {wander:.2f} m rms "
              "(an end-to-end error of the GPS distance)")

    # --- kiss-icp on the strongest returns ----------------------------------------------------------
    # --- clock offset from the speed profiles, per GPS segment -----------------------------------
    # the radar's speed over k turns against the GPS's over the same interval read delta later;
    # the GPS log is cut at its gaps (> 0.5 s): the offset is fitted on each piece apart
    kmax = max(args.k)
    reg = steps[("deskew", kmax)] if ("deskew", kmax) in steps else steps[("raw", kmax)]
    st = np.hypot(reg[:, 0], reg[:, 1])
    dtk = (t_mid[kmax:] - t_mid[:-kmax]) / 1e9
    vr = st / dtk
    expect = np.convolve(k1_med, np.ones(kmax), "valid")
    okk = (np.abs(st - expect) < 0.15 * expect) & driving[: st.size] & (st > 0.8 * kmax)
    deltas = np.arange(-1.0, 3.0 + 1e-9, 0.01)
    vg_all = np.empty((deltas.size, st.size))
    for j, dl in enumerate(deltas):
        p = gps_at(t_mid, dl)
        vg_all[j] = np.linalg.norm(p[kmax:] - p[:-kmax], axis=1) / dtk
    # a pair whose GPS window, shifted by any trial delta, leaves the GPS log is not fitted (the
    # interpolation would hold the last fix: a false stop)
    okk &= (t_mid[kmax:] + int(deltas[-1] * 1e9) <= tg[-1]) & (t_mid[:-kmax] + int(deltas[0] * 1e9) >= tg[0])
    gap_t = tg[1:][np.diff(tg) > 500_000_000]
    n_ok = int(okk.sum())
    part = np.zeros(st.size, dtype=int)
    part[np.flatnonzero(okk)[n_ok // 2:]] = 1

    def fit(sel: np.ndarray) -> float:
        cost = ((vr[sel][None, :] - vg_all[:, sel]) ** 2).sum(axis=1)
        j = int(np.clip(np.argmin(cost), 1, deltas.size - 2))
        y0, y1, y2 = cost[j - 1: j + 2]
        den = y0 - 2 * y1 + y2
        return float(deltas[j] + (np.clip(0.5 * (y0 - y2) / den, -1, 1) * 0.01 if den > 0 else 0.0))

    print(f"\nGPS-radar clock offset (radar speed over {kmax} turns vs the GPS's read delta later; GPS gaps > 0.5 s "
          f"at {', '.join(f'{(g - tg[0]) / 1e9:.1f} s' for g in gap_t) or 'none'} after its first fix):")
    pieces = []
    for name, sel in (("all", okk), ("first half", okk & (part == 0)), ("second half", okk & (part == 1))):
        off = fit(sel)
        boots = [fit(np.flatnonzero(sel)[b]) for b in block_bootstrap(int(sel.sum()), block, reps=300)]
        lo_o, hi_o = (float(np.quantile(boots, q)) for q in (0.05, 0.95))
        j = int(np.argmin(np.abs(deltas - off)))
        rms0 = float(np.sqrt(np.mean((vr[sel] - vg_all[int(np.argmin(np.abs(deltas)))][sel]) ** 2)))
        rms = float(np.sqrt(np.mean((vr[sel] - vg_all[j][sel]) ** 2)))
        r_at = float(st[sel].sum() / (vg_all[j][sel] * dtk[sel]).sum())
        r_0 = float(st[sel].sum() / (vg_all[int(np.argmin(np.abs(deltas)))][sel] * dtk[sel]).sum())
        i0, i1 = idx[np.flatnonzero(sel)[[0, -1]]]
        print(f"  {name}: scans {i0}-{i1 + kmax} ({int(sel.sum())} pairs): offset {off:+.2f} s (90 % CI [{lo_o:+.2f}, "
              f"{hi_o:+.2f}]); speed residual {rms:.2f} m/s rms (at 0 s: {rms0:.2f}); ratio radar/GPS at it "
              f"{r_at:.4f} (at 0 s: {r_0:.4f})")
        pieces.append({"part": name, "scans": [int(i0), int(i1 + kmax)], "offset_s": round(off, 2),
                       "offset_ci90_s": [round(lo_o, 2), round(hi_o, 2)], "ratio": round(r_at, 4)})
        if name == "all":
            ratio_num, ratio_den, offset = st[sel], vg_all[j][sel] * dtk[sel], off
    r_off, lo_off, hi_off = ratio_ci(ratio_num, ratio_den, block)
    print(f"  ratio radar/GPS with the GPS read at {offset:+.2f} s ({kmax}-turn displacements): {r_off:.4f} "
          f"[{lo_off:.4f}, {hi_off:.4f}]")
    # the same sets as above, the GPS read at the offset
    p_off = gps_at(t_mid, offset)
    g_off = np.linalg.norm(p_off[kmax:] - p_off[:-kmax], axis=1)
    v_off = g_off / dtk
    inside = (t_mid[kmax:] + int(offset * 1e9) <= tg[-1]) & (np.abs(st - expect) < 0.15 * expect)
    sets = {"driving": inside & (v_off > 2.0), "first half": inside & (v_off > 2.0) & (np.arange(st.size) < half),
            "second half": inside & (v_off > 2.0) & (np.arange(st.size) >= half),
            "< 5 m/s": inside & (v_off > 2.0) & (v_off < 5.0), "5-8 m/s": inside & (v_off >= 5.0) & (v_off < 8.0),
            "> 8 m/s": inside & (v_off >= 8.0)}
    for name, sel in sets.items():
        if sel.sum() >= 5:
            r, lo_s, hi_s = ratio_ci(st[sel], g_off[sel], block)
            summary[f"offset {name}"] = (r, lo_s, hi_s)
            print(f"    {name:<12} {int(sel.sum()):4d} pairs  GPS {g_off[sel].sum():7.1f} m  ratio {r:.4f} "
                  f"[{lo_s:.4f}, {hi_s:.4f}]")

    dist = float(np.linalg.norm(np.diff(p_mid[driving.nonzero()[0][0]:], axis=0), axis=1).sum())
    kiss = None
    if not args.no_kiss:
        kiss = run_kiss(ds, idx)
        if kiss is not None:
            pk = gps_at(kiss[0])
            sel = driving[: idx.size - 1]
            steps_k = np.linalg.norm(np.diff(kiss[1], axis=0), axis=1)[sel]
            steps_g = np.linalg.norm(np.diff(pk, axis=0), axis=1)[sel]
            ratio, lo, hi = ratio_ci(steps_k, steps_g, block)
            summary["kiss-icp driving"] = (ratio, lo, hi)
            hl = np.arange(sel.sum()) < sel.sum() // 2
            r1 = steps_k[hl].sum() / steps_g[hl].sum()
            r2 = steps_k[~hl].sum() / steps_g[~hl].sum()
            # the same turns with the GPS read at the fitted offset
            t_beg, t_end = kiss[0][:-1][sel], kiss[0][1:][sel]
            keep = t_end + int(offset * 1e9) <= tg[-1]
            steps_o = np.linalg.norm(gps_at(t_end, offset) - gps_at(t_beg, offset), axis=1)
            ro = steps_k[keep].sum() / steps_o[keep].sum()
            summary["kiss-icp with offsets"] = (float(ro), np.nan, np.nan)
            print(f"\nkiss-icp (12 strongest per azimuth, deskew): path {steps_k.sum():.1f} m vs GPS "
                  f"{steps_g.sum():.1f} m over the same turns: ratio {ratio:.4f} [{lo:.4f}, {hi:.4f}]; "
                  f"halves {r1:.4f} / {r2:.4f}; with the GPS at {offset:+.2f} s ({int(keep.sum())} turns): "
                  f"{ro:.4f}")

    # --- expected sizes, from formulas ------------------------------------------------------------------
    v = float(np.median(speed[driving]))
    d = v * period_s
    print(f"\nexpected, at the median driving speed {v:.1f} m/s ({d:.2f} m per turn):")
    for df_hz in (1e9, SPEED_OF_LIGHT / (2 * DOC_BIN_M)):
        beta = F0_HZ / (df_hz * FM_HZ)
        print(f"  Doppler range shift of a sawtooth (f0 {F0_HZ / 1e9:g} GHz, dF {df_hz / 1e6:.0f} MHz, "
              f"Fm {FM_HZ:g} Hz): "
              f"V f0/(dF Fm) = {100 * beta:.1f} cm per m/s: {beta * v:.2f} m towards the car ahead and away "
              f"behind at {v:.0f} m/s, the same in both scans of a pair: a step changes by beta dV <cos^2> only "
              f"(+{100 * beta * 0.5 * 1.0 * period_s:.2f} cm per turn at 1 m/s^2; "
              f"{100 * beta * 0.5 * v / dist:.2f} % of the drive's length from 0 to {v:.0f} m/s)")
    print(f"  motion within a turn: a point at range r and bearing phi (left +) is seen (phi' - phi)/2pi turns "
          f"later in the next turn: its step is d (1 - d sin(phi) / (2 pi r)): {100 * d / (2 * np.pi * 10):.1f} % "
          f"at 10 m, {100 * d / (2 * np.pi * 30):.1f} % at 30 m, opposite on the two sides (net: the scene's "
          "imbalance; measured: raw vs deskew above)")

    ratio, lo, hi = r_off, lo_off, hi_off
    main_key = f"deskew k={kmax} driving" if f"deskew k={kmax} driving" in summary else f"raw k={kmax} driving"
    gps_rel = wander / dist if np.isfinite(wander) else 0.0
    half_ci = math.hypot(0.5 * (hi - lo), 1.645 * gps_rel)
    bin_m = DOC_BIN_M / ratio
    print(f"\nchosen: {kmax}-turn registrations, the GPS read at the fitted offset: ratio {ratio:.4f}, "
          f"90 % CI with the GPS's end-to-end error ({gps_rel * 100:.2f} % of {dist:.0f} m): +-{half_ci:.4f} "
          f"-> range per bin {bin_m:.5f} m (+-{bin_m * half_ci / ratio:.5f})")
    out = {"radiate_range_per_bin_m": round(bin_m, 5),
           "radiate_range_per_bin_ci90_m": round(bin_m * half_ci / ratio, 5),
           "radar_gps_distance_ratio": round(ratio, 4), "radar_gps_ratio_ci90": [round(ratio - half_ci, 4),
                                                                                 round(ratio + half_ci, 4)],
           "ratio_first_half": round(summary["offset first half"][0], 4),
           "ratio_second_half": round(summary["offset second half"][0], 4),
           "ratio_by_speed": {k: round(summary[f"offset {k}"][0], 4) for k in ("< 5 m/s", "5-8 m/s", "> 8 m/s")
                              if f"offset {k}" in summary},
           "ratio_no_offset": round(summary[main_key][0], 4),
           "ratio_no_offset_first_half": round(summary.get(main_key.replace("driving", "first half"), (np.nan,))[0], 4),
           "ratio_no_offset_second_half": round(summary.get(main_key.replace("driving", "second half"),
                                                            (np.nan,))[0], 4),
           "ratio_no_offset_above_8mps": round(summary.get(main_key.replace("driving", "> 8 m/s"), (np.nan,))[0], 4),
           "ratio_k1_raw": round(summary["raw k=1 driving"][0], 4),
           "ratio_kiss_icp_no_offset": (round(summary["kiss-icp driving"][0], 4) if "kiss-icp driving" in summary
                                        else None),
           "ratio_kiss_icp": (round(summary["kiss-icp with offsets"][0], 4) if "kiss-icp with offsets" in summary
                              else None),
           "gps_radar_offset_s": pieces[0]["offset_s"], "gps_radar_offset_ci90_s": pieces[0]["offset_ci90_s"],
           "gps_pieces": pieces, "gps_wander_m": round(wander, 2), "driving_gps_m": round(dist, 1)}
    print(json.dumps(out))
    return 0


def run_kiss(ds, idx):
    """(t_ns, xy) of kiss-icp's poses (at each turn's middle) on the 12 strongest returns per azimuth."""
    try:
        from kiss_icp.config import KISSConfig
        from kiss_icp.config.config import DataConfig, MappingConfig
        from kiss_icp.kiss_icp import KissICP
    except ImportError:
        print("kiss-icp not installed: skipped")
        return None
    from impala_radar.datasets.common import counts_to_power
    from impala_radar.extractor.core import extract_peaks

    icp = KissICP(KISSConfig(data=DataConfig(max_range=100.0, min_range=BLANK_M, deskew=True),
                             mapping=MappingConfig(voxel_size=1.0, max_points_per_voxel=20)))
    ts, xy = [], []
    for i in idx.tolist():
        scan = ds.read_scan(i)
        power = counts_to_power(scan.power, 0.5)  # linear power, as the import writes the beams
        rows, bins = extract_peaks(power, ds.config, k=12, range_min_m=BLANK_M)
        r = ds.config.range_of_bin_m(bins)
        az = scan.azimuth_rad[rows]
        pts = np.column_stack([r * np.cos(az), r * np.sin(az), np.zeros(r.size)])
        tt = (scan.t_ns[rows] - scan.t_ns[0]) / max(1, scan.t_ns[-1] - scan.t_ns[0])
        icp.register_frame(pts, tt)
        # kiss-icp deskews to the frame's middle time (0.5): its pose is at the turn's middle
        ts.append(int(ds.turn_t_ns[i]) + ds.period_ns // 2)
        xy.append(icp.last_pose[:2, 3].copy())
    return np.array(ts, dtype=np.int64), np.array(xy)


if __name__ == "__main__":
    sys.exit(main())
