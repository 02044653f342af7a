"""``radar.FuzzyPairer``: fuzzy up/down peak pairing, one batch of detections per turn."""

from __future__ import annotations

import importlib

import numpy as np

from impala_flow import Component, Input, Output, Param
from impala_msgs import RadarBeam, RadarConfig, RadarDetections, Speed

from ..turns import TurnBuffer
from .core import Pairs, pair_turn, radial_speed_from_beats_mps, range_from_beats_m, xcorr_speed_prior

__all__ = ["FuzzyPairer", "detections_of_pairs"]


def detections_of_pairs(pairs: Pairs, turn: int, t_ns: np.ndarray, azimuth_rad: np.ndarray,
                        config: RadarConfig) -> RadarDetections:
    """RadarDetections of the pairs of one turn (range and radial speed by eq. 3)."""
    up, down, iu, id_ = pairs.up, pairs.down, pairs.iu, pairs.id
    f_up, f_down = up.bin[iu] * config.bin_hz, down.bin[id_] * config.bin_hz
    beam = up.beam[iu]
    return RadarDetections(
        turn=turn, t_ns=np.asarray(t_ns, np.int64)[beam], beam=beam.astype(np.int64),
        azimuth_rad=np.asarray(azimuth_rad, float)[beam],
        range_m=np.asarray(range_from_beats_m(f_up, f_down, config), float),
        radial_speed_mps=np.asarray(radial_speed_from_beats_mps(f_up, f_down, config), float),
        amplitude=np.sqrt(up.power[iu] * down.power[id_]), score=pairs.score.astype(float))


class FuzzyPairer(Component):
    """Pairs the CFAR peaks of the up- and down-ramp spectra with a fuzzy operator (seed 1
    §2.4) and converts each pair to range and radial speed (eq. 3).

    Beams are buffered and processed one whole turn at a time (vectorised over its
    beams): one :class:`RadarDetections` per turn, stamped with the time of the turn's
    last beam, every detection keeping its own beam time and azimuth. A turn is complete
    at its last beam index, or when a beam of another turn arrives; one with fewer beams than
    ``beams_per_turn`` (cut by the recording, or beams lost) is counted in ``partial_turns``. The
    static-target Doppler offset the position criterion is centred on comes from the
    ``speed`` input (odometer) when it holds a sample, otherwise from the spectra
    (``doppler_prior="xcorr"``) or zero (``"none"``). A power-only radar (no down
    spectrum) gives one detection per up peak with NaN radial speed and score.
    """

    beams = Input(RadarBeam, maxsize=8192, doc="beams of the rotating radar, in time order")
    speed = Input(Speed, policy="sampling", required=False, doc="ego-speed prior (odometer)")
    detections = Output(RadarDetections, doc="paired targets of one turn")

    cfar = Param(str, default="os", choices=("ca", "os"), doc="cell-averaging or ordered-statistic CFAR")
    pfa = Param(float, default=1e-4, gt=0, lt=1, doc="CFAR false-alarm probability per bin")
    train = Param(int, default=12, ge=2, doc="CFAR training cells on each side")
    guard = Param(int, default=4, ge=0, doc="CFAR guard cells on each side (Hann main lobe: 4)")
    min_score = Param(float, default=0.45, ge=0, le=1, doc="pairs scoring less are dropped")
    max_radial_speed_mps = Param(float, default=30.0, gt=0,
                                 doc="gate: largest |radial speed| of a target relative to the ground")
    doppler_prior = Param(str, default="xcorr", choices=("xcorr", "none"),
                          doc="ego-speed prior when the speed input has no sample")
    membership = Param(dict, default={}, doc="fuzzy membership overrides (see fuzzy.DEFAULT_MEMBERSHIP)")
    rules = Param(list, default=[], doc="fuzzy rules replacing fuzzy.DEFAULT_RULES when not empty")

    def start(self) -> None:
        for m in ("scipy.fft", "scipy.ndimage", "scipy.optimize"):  # before the first turn (imported where used)
            importlib.import_module(m)
        self._turn = TurnBuffer()
        self.turns = 0
        self.partial_turns = 0
        self.n_detections = 0
        self.last_prior_mps = float("nan")

    def process(self, t: int) -> None:
        for buf in self._turn.add(t, self.beams.take()):
            self._flush(buf)

    def flush(self, t: int) -> None:
        """The beams are exhausted: the partial last turn's detections are emitted too."""
        buf = self._turn.take()
        if buf:
            self._flush(buf)

    def _flush(self, buf: list[tuple[int, RadarBeam]]) -> None:
        t_ns = np.array([t for t, _ in buf], np.int64)
        first = buf[0][1]
        config = first.config
        if len(buf) < config.beams_per_turn:  # cut by the recording's start or end, or beams lost
            self.partial_turns += 1
        azimuth = np.array([b.azimuth_rad for _, b in buf])
        up = np.array([b.up for _, b in buf])  # np.stack's rows, in a seventh of its time
        if not config.doppler or first.down.size == 0:
            dets = self._power_only(up, t_ns, azimuth, first.turn, config)
        else:
            down = np.array([b.down for _, b in buf])
            prior = self.speed.get()
            if prior is not None:
                v = float(prior.speed_mps)
            elif self.doppler_prior == "xcorr":
                v = xcorr_speed_prior(up, down, azimuth, config)
            else:
                v = 0.0
            self.last_prior_mps = v
            pairs = pair_turn(up, down, azimuth, config, v, pfa=self.pfa, train=self.train,
                              guard=self.guard, cfar=self.cfar, min_score=self.min_score,
                              max_radial_speed_mps=self.max_radial_speed_mps,
                              membership=self.membership or None, rules=self.rules or None)
            dets = detections_of_pairs(pairs, first.turn, t_ns, azimuth, config)
        self.turns += 1
        self.n_detections += len(dets.range_m)
        self.detections.emit(int(t_ns[-1]), dets)

    def _power_only(self, up, t_ns, azimuth, turn, config) -> RadarDetections:
        from .core import detect_peaks

        p = detect_peaks(up, self.pfa, self.train, self.guard, self.cfar,
                         max(0, int(config.bin_of_range(config.range_min_m))))
        nan = np.full(len(p), np.nan)
        return RadarDetections(turn, t_ns[p.beam], p.beam, azimuth[p.beam],
                               np.asarray(config.range_of_bin_m(p.bin), float), nan, p.power, nan)

    def summary(self) -> dict:
        out = {"turns": self.turns, "detections": self.n_detections}
        if self.partial_turns:
            out["partial_turns"] = self.partial_turns
        return out
