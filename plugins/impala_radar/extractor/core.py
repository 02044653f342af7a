"""``radar.PeakExtractor``: one turn of beams -> the strongest returns of each azimuth as points.

The point front end of the point-based odometries (kiss-icp, ICP, NDT) that radar engineers
try first: in each beam, the ``k`` strongest range bins that stand above the noise, each
point stamped with its beam's own time so that a consumer can deskew the turn.

"Above the noise", ``method``:

- ``kstrongest``: power above ``snr_db`` over the beam's median power within the range limits
  (its noise-and-clutter floor; a Navtech's floor varies by a few dB from beam to beam), as in the k-strongest
  extractor of Kung et al. (2021) and Burnett et al. (2021), with a floor relative to each
  beam instead of a fixed 8-bit level;
- ``cfar``: cell-averaging CFAR along range (:func:`impala_radar.peaks.cfar_threshold`:
  ``train`` cells each side, ``guard`` cells excluded, threshold factor for ``pfa`` on
  exponentially distributed noise power).

With ``separation_m > 0`` a bin must also be the largest within +-``separation_m`` along its
beam: one extended echo (a wall seen over a metre of range) gives one point instead of the k.
"""

from __future__ import annotations

import numpy as np

from impala_msgs import RadarConfig

from ..peaks import cfar_threshold

__all__ = ["extract_peaks"]


def extract_peaks(power: np.ndarray, config: RadarConfig, k: int = 12, method: str = "kstrongest",
                  snr_db: float = 10.0, pfa: float = 1e-3, train: int = 16, guard: int = 4,
                  separation_m: float = 0.0, range_min_m: float = 0.0,
                  range_max_m: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(row, bin) of at most ``k`` returns per row of ``power`` (beams x bins, linear power),
    strongest first within a row, rows in order; see the module doc for the methods.

    Bin ``b`` is at ``config.range_of_bin_m(b)``; bins outside [``range_min_m``,
    ``range_max_m``] are never returned (``range_max_m`` 0: the radar's ``range_max_m``).
    """
    power = np.asarray(power, np.float32)
    n_beams, n_bins = power.shape
    r_max = range_max_m if range_max_m > 0 else config.range_max_m
    lo = max(0, int(np.ceil(config.bin_of_range(range_min_m))))
    hi = min(n_bins, int(np.floor(config.bin_of_range(r_max))) + 1)
    if n_beams == 0 or hi <= lo or k <= 0:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    if method == "kstrongest":
        p = power[:, lo:hi]
        floor = np.median(p, axis=1, keepdims=True)
        ok = p > floor * np.float32(10.0 ** (snr_db / 10.0))
    elif method == "cfar":
        m = train + guard  # the training cells of the bins at the ends of [lo, hi) lie outside it
        a, b = max(0, lo - m), min(n_bins, hi + m)
        thr = cfar_threshold(power[:, a:b], pfa=pfa, train=train, guard=guard, method="ca")
        p = power[:, lo:hi]
        ok = p > thr[:, lo - a:hi - a]
    else:
        raise ValueError(f"unknown method {method!r}; valid: kstrongest, cfar")
    half = int(round(separation_m / config.range_per_bin_m)) if separation_m > 0 else 0
    if half > 0:
        from scipy import ndimage  # here, not at import: 0.1-0.2 s paid by every command's start

        ok &= p >= ndimage.maximum_filter1d(p, 2 * half + 1, axis=1, mode="nearest")
    score = np.where(ok, p, -np.inf)
    kk = min(k, hi - lo)
    top = np.argpartition(-score, kk - 1, axis=1)[:, :kk]  # the kk largest of each row, unordered
    top_score = np.take_along_axis(score, top, axis=1)
    order = np.argsort(-top_score, axis=1, kind="stable")
    top, top_score = np.take_along_axis(top, order, axis=1), np.take_along_axis(top_score, order, axis=1)
    rows = np.broadcast_to(np.arange(n_beams)[:, None], top.shape)
    keep = np.isfinite(top_score)
    return rows[keep].astype(np.int64), top[keep].astype(np.int64) + lo
