"""``radar.PeakExtractor``: one turn of beams -> the strongest returns of each azimuth as points.

The point front end of the point-based odometries (kiss-icp, ICP, NDT) that radar engineers
try first: in each beam, the ``k`` strongest range bins that stand above the noise, each
point stamped with its beam's own time so that a consumer can deskew the turn.

"Above the noise", ``method``:

- ``kstrongest``: power above ``snr_db`` over the beam's median power within the range limits
  (its noise-and-clutter floor; a Navtech's floor varies by a few dB from beam to beam), as in the k-strongest
  extractor of Kung et al. (2021) and Burnett et al. (2021), with a floor relative to each
  beam instead of a fixed 8-bit level;
- ``cfar``: cell-averaging CFAR along range (:func:`impala_radar.frontend.peaks.cfar_threshold`:
  ``train`` cells each side, ``guard`` cells excluded, threshold factor for ``pfa`` on
  exponentially distributed noise power).

With ``separation_m > 0`` a bin must also be the largest within +-``separation_m`` along its
beam: one extended echo (a wall seen over a metre of range) gives one point instead of the k.
"""

from __future__ import annotations

import time

import numpy as np
from scipy import ndimage

from impala_flow import Component, Input, Output, Param
from impala_msgs import RadarBeam, RadarConfig, RadarDetections

from .peaks import cfar_threshold
from .turns import TurnBuffer

__all__ = ["PeakExtractor", "extract_peaks"]


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


class PeakExtractor(Component):
    """Collects one antenna turn of beams and emits its strongest returns as
    :class:`RadarDetections`: at most ``k`` per beam above the noise (``method``: k-strongest
    over the beam's median, or CA-CFAR along range; see :mod:`impala_radar.frontend.extractor`).

    Each detection carries its beam's own time ``t_ns``, index ``beam`` and ``azimuth_rad``
    (vehicle frame, 0 = forward, counter-clockwise positive, as every ``RadarBeam``), its
    range ``range_m`` at the bin's centre from the beam's own ``RadarConfig``
    (``range_offset_m + k * range_per_bin_m``) and its linear power in ``amplitude``.
    ``radial_speed_mps`` is NaN (a power-only extraction measures no Doppler) and ``score``
    1. The message is stamped with the turn's last beam; a turn with missing beams is
    extracted as it is, a partial last turn only if it holds ``min_turn_fraction`` of a turn
    (else counted in ``dropped_turns``). Uses the rising ramp (``up``) of each beam.
    """

    beams = Input(RadarBeam, maxsize=8192, doc="beams of the rotating radar, in time order")
    detections = Output(RadarDetections, doc="the turn's strongest returns, each with its beam's time")

    method = Param(str, default="kstrongest", choices=("kstrongest", "cfar"),
                   doc="above the noise: snr_db over the beam's median, or CA-CFAR along range")
    k = Param(int, default=12, ge=1, doc="at most this many returns per beam, the strongest")
    snr_db = Param(float, default=10.0, doc="kstrongest: power above the beam's median by this much")
    pfa = Param(float, default=1e-3, gt=0, lt=1, doc="cfar: false-alarm probability per cell")
    train = Param(int, default=16, ge=1, doc="cfar: training cells on each side")
    guard = Param(int, default=4, ge=0, doc="cfar: guard cells on each side")
    separation_m = Param(float, default=0.0, ge=0,
                         doc="a return must be the strongest within +-this range along its beam (0: any bin)")
    range_min_m = Param(float, default=2.5, ge=0, doc="nearer returns are ignored (vehicle body, leakage)")
    range_max_m = Param(float, default=0.0, ge=0, doc="farther returns are ignored; 0 = the radar's range_max_m")
    min_turn_fraction = Param(float, default=0.5, ge=0, le=1,
                              doc="a partial last turn is extracted if it holds this fraction of a turn")

    def start(self) -> None:
        self._turn = TurnBuffer()
        self.turns = 0
        self.points = 0
        self.partial_turns = 0
        self.dropped_turns = 0
        self.seconds = 0.0

    def process(self, t: int) -> None:
        for buf in self._turn.add(t, self.beams.take()):
            self._extract(buf)

    def flush(self, t: int) -> None:
        buf = self._turn.take()
        if not buf:
            return
        if len(buf) >= max(1.0, self.min_turn_fraction * buf[0][1].config.beams_per_turn):
            self._extract(buf)
        else:
            self.dropped_turns += 1

    def _extract(self, buf: list[tuple[int, RadarBeam]]) -> None:
        t0 = time.perf_counter()
        config = buf[0][1].config
        if len(buf) < config.beams_per_turn:
            self.partial_turns += 1
        t_ns = np.array([t for t, _ in buf], np.int64)
        power = np.stack([b.up for _, b in buf])
        rows, bins = extract_peaks(power, config, self.k, self.method, self.snr_db, self.pfa, self.train,
                                   self.guard, self.separation_m, self.range_min_m, self.range_max_m)
        azimuth = np.array([b.azimuth_rad for _, b in buf])
        index = np.array([b.index for _, b in buf], np.int64)
        n = len(rows)
        det = RadarDetections(
            turn=int(buf[0][1].turn), t_ns=t_ns[rows], beam=index[rows], azimuth_rad=azimuth[rows],
            range_m=np.asarray(config.range_of_bin_m(bins), np.float64), radial_speed_mps=np.full(n, np.nan),
            amplitude=power[rows, bins].astype(np.float64), score=np.ones(n))
        self.turns += 1
        self.points += n
        self.seconds += time.perf_counter() - t0
        self.detections.emit(int(t_ns[-1]), det)

    def summary(self) -> dict:
        if not getattr(self, "turns", 0):
            return {}
        return {"turns": self.turns, "points_per_turn": round(self.points / self.turns, 1),
                "partial_turns": self.partial_turns, "dropped_turns": self.dropped_turns,
                "ms_per_turn": round(1e3 * self.seconds / self.turns, 2)}
