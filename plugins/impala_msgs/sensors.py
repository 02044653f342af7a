"""Sensor messages: rotating FMCW radar beams, odometer, gyro, truth of moving objects."""

from __future__ import annotations

import math
import threading
import weakref
from dataclasses import field

import numpy as np

from impala_flow.msgs import invalid_fields, message

__all__ = [
    "RadarConfig", "RadarBeam", "RadarScan", "RadarDetections", "Speed", "YawRate", "ObjectStates",
    "TrackExistence", "SPEED_OF_LIGHT_MPS", "CHIRP_UP", "CHIRP_DOWN", "RadarBeamV1", "upgrade_radar_beam_v1",
]

SPEED_OF_LIGHT_MPS = 299_792_458.0


@message("impala.RadarConfig", version=2)
class RadarConfig:
    """How a rotating radar's beams were acquired; every beam carries the one it came from.

    Triangular FMCW ("roof" modulation): a rising then a falling ramp of excursion
    ``bandwidth_hz`` (Delta F) repeated at ``modulation_hz`` (F_m). Spectra are sampled in
    beat frequency, ``bin_hz`` per bin. A power-only radar (Navtech) has
    ``doppler = False``, ``bandwidth_hz``/``modulation_hz`` of its own and ``bin_hz`` chosen
    so that :meth:`range_of_bin_m` gives its range bins. ``window`` is the weighting
    applied before the FFT: it sets the width of a target's peak (Hann resolves about
    2 dR, ``rect`` dR with -13 dB sidelobes). ``range_offset_m`` is the range of bin 0:
    bin k covers ``range_offset_m + k * range_per_bin_m`` (a reader whose format gives
    bin centres, like Navtech's, sets half a bin; the simulator's spectra are 0 there).
    Version 2 added ``range_offset_m``.
    """

    name: str
    f0_hz: float
    bandwidth_hz: float
    modulation_hz: float
    bin_hz: float
    n_bins: int
    beam_width_rad: float
    rotation_hz: float
    beams_per_turn: int
    range_min_m: float
    range_max_m: float
    doppler: bool = True
    height_m: float = 1.3
    window: str = "hann"  # weighting before the FFT: "hann" (peaks ~4 bins wide) or "rect"
    range_offset_m: float = 0.0  # range of bin 0 (bin k: range_offset_m + k range_per_bin_m)

    @classmethod
    def power_only(cls, name: str, n_bins: int, range_per_bin_m: float, range_offset_m: float, beams_per_turn: int,
                   rotation_hz: float, *, f0_hz: float = 76.5e9, bandwidth_hz: float = 1.0e9,
                   beam_width_rad: float = math.radians(1.8)) -> RadarConfig:
        """A power-only rotating radar (a Navtech: no beat frequencies, one sweep per azimuth) from
        its range bins: ``modulation_hz = beams_per_turn * rotation_hz`` and ``bin_hz`` chosen so
        that ``range_per_bin_m = c bin_hz / (4 bandwidth_hz modulation_hz)``. Bin k lies at
        ``range_offset_m + k range_per_bin_m``; ``range_max_m`` is the far edge of the last bin,
        ``n_bins range_per_bin_m``. The defaults are the Navtech CTS350-X / CIR304-H's nominal
        76-77 GHz sweep and 1.8 deg beam (every dataset reader and the live driver build theirs here)."""
        modulation_hz = beams_per_turn * rotation_hz
        return cls(name=name, f0_hz=f0_hz, bandwidth_hz=bandwidth_hz, modulation_hz=modulation_hz,
                   bin_hz=range_per_bin_m * 4.0 * bandwidth_hz * modulation_hz / SPEED_OF_LIGHT_MPS,
                   n_bins=int(n_bins), beam_width_rad=beam_width_rad, rotation_hz=float(rotation_hz),
                   beams_per_turn=int(beams_per_turn), range_min_m=0.0, range_max_m=n_bins * range_per_bin_m,
                   doppler=False, range_offset_m=float(range_offset_m))

    def invalid_reason(self) -> str | None:
        """Non-finite numbers, or a quantity every range and time formula divides by that is not > 0.

        Checked on every beam (each carries its config): the common case is one expression
        (x * 0 is 0 for a finite x, NaN for NaN and +-inf); the field-by-field walk only names
        what is wrong."""
        finite = (self.f0_hz * 0.0 + self.bandwidth_hz * 0.0 + self.modulation_hz * 0.0 + self.bin_hz * 0.0
                  + self.beam_width_rad * 0.0 + self.rotation_hz * 0.0 + self.range_min_m * 0.0
                  + self.range_max_m * 0.0 + self.height_m * 0.0 + self.range_offset_m * 0.0) == 0.0
        why = None if finite else invalid_fields(self)
        if why is not None:
            return why
        if (self.bandwidth_hz > 0 and self.modulation_hz > 0 and self.bin_hz > 0 and self.rotation_hz > 0
                and self.n_bins > 0 and self.beams_per_turn > 0 and 0.0 <= self.range_min_m < self.range_max_m):
            return None
        for name in ("bandwidth_hz", "modulation_hz", "bin_hz", "rotation_hz", "n_bins", "beams_per_turn"):
            if not getattr(self, name) > 0:
                return f"{name} <= 0"
        return "range_min_m, range_max_m not 0 <= min < max"

    @property
    def range_per_bin_m(self) -> float:
        """Range spanned by one beat-frequency bin (f_r = 4 dF Fm R / c)."""
        return SPEED_OF_LIGHT_MPS * self.bin_hz / (4.0 * self.bandwidth_hz * self.modulation_hz)

    @property
    def range_resolution_m(self) -> float:
        """Rayleigh range resolution dR = c / (2 dF)."""
        return SPEED_OF_LIGHT_MPS / (2.0 * self.bandwidth_hz)

    @property
    def velocity_resolution_mps(self) -> float:
        """Rayleigh velocity resolution dV = c Fm / (2 f0)."""
        return SPEED_OF_LIGHT_MPS * self.modulation_hz / (2.0 * self.f0_hz)

    def range_of_bin_m(self, bins: np.ndarray | float) -> np.ndarray | float:
        """Range (m) of (fractional) bin indices: ``range_offset_m + k * range_per_bin_m``."""
        return self.range_offset_m + np.asarray(bins) * self.range_per_bin_m

    def bin_of_range(self, range_m: np.ndarray | float) -> np.ndarray | float:
        """Fractional bin index of a range (the inverse of :meth:`range_of_bin_m`)."""
        return (np.asarray(range_m) - self.range_offset_m) / self.range_per_bin_m


#: ``RadarBeam.chirp`` of a beam measured with a rising ramp only
CHIRP_UP = 1
#: ``RadarBeam.chirp`` of a beam measured with a falling ramp only
CHIRP_DOWN = -1


@message("impala.RadarBeam", version=2)
class RadarBeam:
    """One beam of a rotating radar, stamped at its own acquisition time.

    ``azimuth_rad`` is the antenna angle in the vehicle frame (0 = heading, counter-
    clockwise positive). ``up``/``down`` are the power spectra (linear power, float32) of
    the rising and falling ramps, indexed by beat-frequency bin; a power-only radar leaves
    ``down`` empty. ``turn`` counts antenna turns, ``index`` the beam within the turn.
    ``chirp`` says which single ramp a power-only beam (``up`` only) was measured with, for
    radars that alternate them from azimuth to azimuth (Doppler-enabled Navtech firmware,
    Boreas 2024): :data:`CHIRP_UP` (+1) or :data:`CHIRP_DOWN` (-1); 0 when not told (one ramp
    direction for every beam, or both ramps in ``up``/``down``). A target's range differs
    between the two by a term proportional to its radial speed, so neighbouring up and down
    beams give Doppler. Version 2 added ``chirp``; version-1 recordings read with chirp 0.
    """

    azimuth_rad: float
    turn: int
    index: int
    up: np.ndarray
    down: np.ndarray
    config: RadarConfig
    chirp: int = 0

    def invalid_reason(self) -> str | None:
        """:func:`~impala_flow.msgs.invalid_fields`, with a fast path for the valid beam (the
        common case, checked on every beam entering an input): the spectra's finite values
        counted (``count_nonzero`` of ``isfinite``: half the cost of ``isfinite().all()``), and the
        configuration checked once per object. Every beam of a sensor carries the same
        RadarConfig object (a replayed recording's too: its decoder shares equal ones), which
        is never changed once its beams are out, so the last one found valid is remembered.

        A spectrum that is a row of a turn :meth:`check_turn` found finite (a dataset reader's
        frozen turn of power) needs no pass of its own: a whole turn is checked once, where it
        is read, and its beams skip 400 passes and 400 releases of the GIL (each of which can
        cost the calling thread a switch interval when another thread wants the GIL). A frozen
        turn not checked yet is checked here, once; a turn holding a non-finite value has its
        beams checked one by one."""
        up, down = self.up, self.down
        if self.azimuth_rad * 0.0 == 0.0 and (down.size == 0 or down.dtype.kind not in "fc"
                                               or _count_nonzero(_isfinite(down)) == down.size):
            base = up.base
            if base is not None and (ref := _finite_turns.get(id(base))) is not None and ref() is base:
                finite = True
            elif up.dtype.kind not in "fc":
                finite = True
            elif base is not None and base is not _non_finite_turn[0] and _frozen_owner(base):
                finite = RadarBeam.check_turn(base) or _count_nonzero(_isfinite(up)) == up.size
            else:
                finite = _count_nonzero(_isfinite(up)) == up.size
            if finite:
                config = self.config
                if config is _valid_config[0]:
                    return None
                why = config.invalid_reason()
                if why is None:
                    _valid_config[0] = config
                    return None
                return f"config: {why}"
        return invalid_fields(self)

    @staticmethod
    def check_turn(power: np.ndarray) -> bool:
        """Whether every value of ``power`` (a turn of spectra whose rows become beams' ``up``) is
        finite, checked in one pass; a read-only array owning its memory (frozen: its values can no
        longer change) found finite is remembered (the last :data:`FINITE_TURNS_KEPT`, by weak
        reference), so that :meth:`invalid_reason` of its rows needs no pass. A reader calls it on
        the thread that reads the turn, after freezing it."""
        if power.dtype.kind not in "fc":
            return True
        finite = bool(_count_nonzero(_isfinite(power)) == power.size)
        if _frozen_owner(power):
            if finite:
                with _turns_lock:
                    _finite_turns[id(power)] = weakref.ref(power)
                    while len(_finite_turns) > FINITE_TURNS_KEPT:
                        del _finite_turns[next(iter(_finite_turns))]
            else:
                _non_finite_turn[0] = power
        return finite


def _frozen_owner(a: object) -> bool:
    """Whether ``a`` is a numpy array that owns its memory and is read-only (frozen)."""
    return type(a) is np.ndarray and a.flags.owndata and not a.flags.writeable


_isfinite, _count_nonzero = np.isfinite, np.count_nonzero
_valid_config: list[RadarConfig | None] = [None]  # the last RadarConfig a beam's check found valid
#: frozen turns found finite kept (readers read a few turns ahead of the beams being checked)
FINITE_TURNS_KEPT = 16
# id -> weak reference of the last frozen turns found finite (a dead one, or another array under a reused id,
# never matches: the reference must give the very array), oldest first; written under the lock, read without
_finite_turns: dict[int, weakref.ref] = {}
_turns_lock = threading.Lock()
_non_finite_turn: list[np.ndarray | None] = [None]  # the last frozen turn found holding a non-finite value


@message("impala.RadarBeam", version=1)
class RadarBeamV1:
    """The layout of :class:`RadarBeam` version 1 (no ``chirp``), to read older recordings:
    :func:`upgrade_radar_beam_v1` turns one into a :class:`RadarBeam` with chirp 0."""

    azimuth_rad: float
    turn: int
    index: int
    up: np.ndarray
    down: np.ndarray
    config: RadarConfig


def upgrade_radar_beam_v1(old: RadarBeamV1) -> RadarBeam:
    return RadarBeam(old.azimuth_rad, old.turn, old.index, old.up, old.down, old.config)


@message("impala.RadarScan", version=1)
class RadarScan:
    """One antenna turn as a polar image: ``power[i, k]`` is beam ``i`` at range bin ``k``.

    Every beam keeps its own acquisition time ``t_ns[i]`` and azimuth ``azimuth_rad[i]``
    (vehicle frame), so motion during the turn can be corrected downstream. ``down`` is
    the falling-ramp power (empty for a power-only radar).
    """

    turn: int
    t_ns: np.ndarray
    azimuth_rad: np.ndarray
    power: np.ndarray
    down: np.ndarray
    config: RadarConfig

    def invalid_reason(self) -> str | None:
        """Non-finite numbers, or a power image whose rows are not the beams."""
        why = invalid_fields(self)
        if why is None and not (np.ndim(self.power) == 2
                                and len(self.t_ns) == len(self.azimuth_rad) == len(self.power)):
            return "t_ns, azimuth_rad and power rows differ in length"
        return why


@message("impala.RadarDetections", version=1, nan_ok=("radial_speed_mps", "score"))
class RadarDetections:
    """Targets detected in beams: one entry per detection, with its beam's time and azimuth.

    ``radial_speed_mps`` follows the seed's sign (negative when the target approaches);
    ``score`` is the pairing confidence in [0, 1]; ``beam`` the beam index in its turn.
    ``radial_speed_mps`` and ``score`` are NaN when not measured (a power-only radar).
    """

    turn: int
    t_ns: np.ndarray
    beam: np.ndarray
    azimuth_rad: np.ndarray
    range_m: np.ndarray
    radial_speed_mps: np.ndarray
    amplitude: np.ndarray
    score: np.ndarray

    def invalid_reason(self) -> str | None:
        """Non-finite numbers (NaN allowed in ``radial_speed_mps`` and ``score``), or columns of
        different lengths."""
        why = invalid_fields(self)
        n = len(self.t_ns)
        if why is None and not (len(self.beam) == len(self.azimuth_rad) == len(self.range_m) == n
                                and len(self.radial_speed_mps) == len(self.amplitude) == len(self.score) == n):
            return "detection columns differ in length"
        return why


@message("impala.Speed", version=1, nan_ok=("std_mps",))
class Speed:
    """Forward speed (odometer, or estimated: then ``std_mps`` is its standard deviation; NaN: unknown)."""

    speed_mps: float
    std_mps: float = float("nan")


@message("impala.YawRate", version=1)
class YawRate:
    """Gyrometer yaw rate (counter-clockwise positive)."""

    yaw_rate_radps: float


@message("impala.ObjectStates", version=1)
class ObjectStates:
    """States of several objects at one time (truth of movers, or tracker output)."""

    ids: np.ndarray
    xy_m: np.ndarray
    v_xy_mps: np.ndarray
    cov: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    frame: str = "map"

    def invalid_reason(self) -> str | None:
        """Non-finite numbers, or rows that do not match: ``ids`` (n), ``xy_m`` and ``v_xy_mps``
        (n, 2), ``cov`` (n, 4, 4) or empty."""
        why = invalid_fields(self)
        n = len(self.ids)
        if why is None and not (np.shape(self.xy_m) == np.shape(self.v_xy_mps) == (n, 2)
                                and (np.size(self.cov) == 0 or np.shape(self.cov) == (n, 4, 4))):
            return "ids, xy_m, v_xy_mps, cov rows do not match"
        return why


@message("impala.TrackExistence", version=1)
class TrackExistence:
    """Every live track of a tracker at one time, tentative or confirmed (seed 1 Fig. 18):
    ``probability`` is each track's existence probability, ``confirmed`` whether it passed
    the confirmation threshold (confirmed tracks are the ones published as ObjectStates)."""

    ids: np.ndarray
    xy_m: np.ndarray
    probability: np.ndarray
    confirmed: np.ndarray
    frame: str = "map"

    def invalid_reason(self) -> str | None:
        """Non-finite numbers, a probability outside [0, 1], or rows that do not match."""
        why = invalid_fields(self)
        n = len(self.ids)
        if why is None and not (np.shape(self.xy_m) == (n, 2) and len(self.probability) == len(self.confirmed) == n):
            return "ids, xy_m, probability, confirmed rows do not match"
        if why is None and n and not (np.min(self.probability) >= 0.0 and np.max(self.probability) <= 1.0):
            return "probability outside [0, 1]"
        return why
