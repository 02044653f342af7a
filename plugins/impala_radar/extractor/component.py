"""``radar.PeakExtractor``: the component (ports, parameters, sample handling). The algorithm, and
what it follows, is described in :mod:`impala_radar.extractor.core`.
"""

from __future__ import annotations

import importlib
import time

import numpy as np

from impala_flow import Component, Input, Output, Param
from impala_msgs import RadarBeam, RadarDetections

from ..turns import TurnBuffer
from .core import extract_peaks

__all__ = ["PeakExtractor"]


class PeakExtractor(Component):
    """Collects one antenna turn of beams and emits its strongest returns as
    :class:`RadarDetections`: at most ``k`` per beam above the noise (``method``: k-strongest
    over the beam's median, or CA-CFAR along range; see :mod:`impala_radar.extractor.component`).

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
        for m in ("scipy.ndimage", "scipy.optimize"):  # before the first turn (core, peaks import them where used)
            importlib.import_module(m)
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
