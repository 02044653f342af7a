"""Radar turns from ROS 2: Navtech B-scan images (sensor_msgs/Image) and Navtech FFT-data messages -> RadarBeam.

The geometry every beam carries (its :class:`~impala_msgs.RadarConfig`) comes, key by key, from the adapter options
when given, else from Navtech's configuration message (``messages/msg/RadarConfigurationMessage``, the first on any
topic of the bag), else from the data (bins and azimuths from the image's shape, the rotation rate measured on the
first stamps); a range per bin nobody gives is refused with one line. The conventions are the direct Oxford/RADIATE
import's: azimuth counter-clockwise from the heading, ``wrap(offset - a)`` for the clockwise antenna angle ``a``
(``wrap(offset + a)`` counter-clockwise), bin k at ``(k + range_offset_bins)`` bins (0.5: bin centres), linear power
``10^(count x db_per_count / 10)`` (float32, 1 at count 0).

B-scan image: one per turn, row i = azimuth ``i / height`` of a turn (Navtech's B-scan publisher fills row
``encoder / (encoder_size / azimuth_samples)``), width = range bins; encodings 8UC1/mono8 (counts) and 16UC1/mono16
(count = value / 256, the 8-bit scale with fractions). The message has one stamp: the turn's first azimuth, and the
per-azimuth times are lost, so beam i is stamped ``stamp + round(i x span / height)``, the turn spread evenly over
the rotation period ``span = 1 / rotation_hz``, never past the next turn's stamp (``span`` = the interval when it is
shorter but at least half a period: the adapter holds a turn until the next arrives), as the direct RADIATE import
spreads its columns; said in the notes. FFT data: one message per azimuth, with its encoder count and
the radar's own time (``ntp_seconds``, ``ntp_split_seconds``): beams keep their exact times and azimuths.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import Any

import numpy as np

import impala_msgs
from impala_flow import msgs
from impala_flow.io import AdaptedChannel, AdapterContext

from .. import msgdefs
from .cdr import decoder_of, stamp_ns
from .params import check_params

__all__ = ["BScanAdapter", "FftAdapter", "CONFIGURATION", "counts_to_power"]

CONFIGURATION = msgdefs.schema_name("messages/RadarConfigurationMessage")
_EMPTY = np.zeros(0, dtype=np.float32)
_HEAD = 20  # stamps read to measure the rotation rate


def counts_to_power(counts: np.ndarray, db_per_count: float) -> np.ndarray:
    """float32 linear power of 8-bit counts (an integer array), or of fractional counts (float)."""
    c = np.asarray(counts)
    if c.dtype == np.uint8:  # the same float64 expression per count as the direct import's table
        table = np.power(10.0, np.arange(256, dtype=np.float64) * db_per_count / 10.0).astype(np.float32)
        return table[c]
    return np.power(10.0, c.astype(np.float64) * db_per_count / 10.0).astype(np.float32)




def _layout(field_bytes: Any, dtype: str) -> float | None:
    """A Navtech byte-array field as its number (msgdefs.NAVTECH_BYTE_LAYOUT), None when empty."""
    raw = bytes(field_bytes)
    if not raw:
        return None
    if dtype == "<f8" and len(raw) == 2:  # an SDK that writes the raw uint16
        dtype = ">u2"
    size = np.dtype(dtype).itemsize
    if len(raw) != size:
        raise ValueError(f"{len(raw)} bytes where {dtype} needs {size}")
    return float(np.frombuffer(raw, dtype=dtype)[0])


def navtech_configuration(context: AdapterContext) -> tuple[dict[str, float], str] | None:
    """(azimuth_samples, encoder_size, range_resolution_m, range_in_bins, rotation_hz) of the bag's first Navtech
    configuration message, and its topic; None when the bag has none."""
    for ch in context.channels:
        if ch.schema_name == CONFIGURATION and ch.schema_encoding == "ros2msg":
            head = context.head(ch.topic, 1)
            if not head:
                continue
            m = decoder_of(ch)(head[0][0])
            layout = msgdefs.NAVTECH_BYTE_LAYOUT["messages/RadarConfigurationMessage"]
            try:
                v = {k: _layout(getattr(m, k), dt) for k, dt in layout.items()}
            except ValueError as e:
                raise ValueError(f"Navtech configuration on {ch.topic!r}: {e}") from None
            out: dict[str, float] = {}
            if v["azimuth_samples"]:
                out["beams_per_turn"] = v["azimuth_samples"]
            if v["encoder_size"]:
                out["encoder_size"] = v["encoder_size"]
            if v["range_in_bins"]:
                out["n_bins"] = v["range_in_bins"]
            if v["expected_rotation_rate"]:
                out["rotation_hz"] = v["expected_rotation_rate"] / 1000.0  # mHz
            b = v["bin_size"]
            if b:  # metres (SDKs dividing by 10000), or the raw count of 0.1 mm (no radar has 1 m bins)
                out["range_resolution_m"] = b if b < 1.0 else b / 10_000.0
            return out, ch.topic
    return None


class _Radar:
    """What the two radar adapters share: options, geometry, notes."""

    value_type = impala_msgs.RadarBeam

    def __init__(self, channel: AdaptedChannel, context: AdapterContext) -> None:
        self.channel, self.context = channel, context
        self.params = check_params(context.params)
        self.decode = decoder_of(channel)
        self.config: impala_msgs.RadarConfig | None = None
        self.turn = -1
        self._notes: list[str] = []

    def notes(self) -> list[str]:
        return list(self._notes)

    def _geometry(self, n_bins: int, beams: int | None, stamps_ns: list[int]) -> dict[str, Any]:
        """Every number of the radar, from the options, the configuration message, the data; the sources said."""
        found = navtech_configuration(self.context)
        conf, where = found if found is not None else ({}, "")
        g: dict[str, Any] = {"n_bins": n_bins, "beams_per_turn": beams}
        said = []
        gaps = np.diff(np.asarray(stamps_ns, dtype=np.int64))
        gaps = gaps[gaps > 0]
        for key in ("beams_per_turn", "encoder_size", "range_resolution_m", "rotation_hz"):
            if key in self.params:
                g[key], src = self.params[key], "option"
            elif key == "rotation_hz" and gaps.size:  # the turns' own rate before the configuration's nominal one
                g[key] = round(1e9 / float(np.median(gaps)), 3)
                src = f"measured: median interval of the first {gaps.size + 1} stamps"
            elif key in conf:
                g[key], src = conf[key], f"configuration message on {where}"
            else:
                continue
            said.append(f"{key} {g[key]:g} ({src})")
        if g.get("rotation_hz") is None:
            raise ValueError("rotation rate unknown: no rotation_hz option, fewer than two turns to measure it on, "
                             "no Navtech configuration message")
        if g.get("range_resolution_m") is None:
            raise ValueError("range per bin unknown: no Navtech configuration message in the bag; give the option "
                             "range_resolution_m (Replayer adapter_params, or import ros2 --config "
                             "range_resolution_m=0.0438)")
        g["range_offset_bins"] = self.params.get("range_offset_bins", 0.5)
        g["azimuth_offset_deg"] = self.params.get("azimuth_offset_deg", 0.0)
        g["db_per_count"] = self.params.get("db_per_count", 0.5)
        g["sign"] = -1.0 if self.params.get("rotation", "clockwise") == "clockwise" else 1.0
        said.append(f"rotation {self.params.get('rotation', 'clockwise')}, azimuth offset "
                    f"{g['azimuth_offset_deg']:g} deg, bin 0 at {g['range_offset_bins']:g} bins, "
                    f"{g['db_per_count']:g} dB per count")
        self._notes.append("geometry: " + "; ".join(said))
        return g

    def _config(self, g: dict[str, Any]) -> impala_msgs.RadarConfig:
        res = float(g["range_resolution_m"])
        # the direct import's construction (a power-only Navtech, its nominal 76-77 GHz sweep)
        cfg = impala_msgs.RadarConfig.power_only(self.params.get("sensor", "navtech-ros2"), int(g["n_bins"]), res,
                                                 g["range_offset_bins"] * res, int(g["beams_per_turn"]),
                                                 float(g["rotation_hz"]))
        why = cfg.invalid_reason()
        if why is not None:
            raise ValueError(f"radar geometry: {why}")
        return cfg

    def _azimuth(self, cw_fraction: np.ndarray, g: dict[str, Any]) -> np.ndarray:
        """Project azimuths (CCW, wrapped) of antenna angles given as fractions of a turn."""
        a = np.asarray(cw_fraction, dtype=np.float64) * (2.0 * math.pi)
        return msgs.wrap_angle(np.radians(g["azimuth_offset_deg"]) + g["sign"] * a)


class BScanAdapter(_Radar):
    """sensor_msgs/Image B-scan (one turn per message) -> one RadarBeam per row."""

    ENCODINGS = {"8UC1": np.uint8, "mono8": np.uint8, "16UC1": np.uint16, "mono16": np.uint16}

    def __init__(self, channel: AdaptedChannel, context: AdapterContext) -> None:
        super().__init__(channel, context)
        self.pending: tuple[int, np.ndarray] | None = None
        self.shortened = 0

    def _counts(self, m: Any) -> np.ndarray:
        dtype = self.ENCODINGS.get(m.encoding)
        if dtype is None:
            raise ValueError(f"image encoding {m.encoding!r}: a B-scan is one of {', '.join(self.ENCODINGS)}")
        size = np.dtype(dtype).itemsize
        h, w, step = int(m.height), int(m.width), int(m.step)
        data = bytes(m.data)
        if h <= 0 or w <= 0 or step < w * size or len(data) < h * step:
            raise ValueError(f"image {h} x {w}, step {step}, {len(data)} bytes: not a whole {m.encoding} image")
        order = ">" if m.is_bigendian and size > 1 else "<"
        rows = np.frombuffer(data, dtype=np.dtype(dtype).newbyteorder(order) if size > 1 else dtype,
                             count=h * step // size).reshape(h, step // size)[:, :w]
        return rows if size == 1 else rows.astype(np.float64) / 256.0

    def _setup(self, m: Any, log_time_ns: int) -> None:
        head = self.context.head(self.channel.topic, _HEAD)
        stamps = [stamp_ns(self.decode(p).header, t) for p, t in head]
        g = self._geometry(int(m.width), int(m.height), stamps)
        if int(g["beams_per_turn"]) != int(m.height):
            self._notes.append(f"image height {m.height} used as the azimuths per turn "
                               f"(configuration says {g['beams_per_turn']})")
            g["beams_per_turn"] = int(m.height)
        g["n_bins"] = int(m.width)
        self.g, self.config = g, self._config(g)
        self._notes.append("beam times: the image's stamp is the turn's first azimuth; per-azimuth times are not "
                           f"in the message: spread evenly over the rotation period (1/{g['rotation_hz']:g} s), never "
                           "past the next turn's stamp")

    def adapt(self, payload: memoryview, log_time_ns: int) -> list[tuple[int, impala_msgs.RadarBeam]]:
        """The beams of the turn before this one, spread up to this turn's stamp (this one waits for the next)."""
        m = self.decode(payload)
        if self.config is None:
            self._setup(m, log_time_ns)
        assert self.config is not None
        counts = self._counts(m)
        if counts.shape != (self.config.beams_per_turn, self.config.n_bins):
            raise ValueError(f"B-scan {counts.shape[0]} x {counts.shape[1]}, the first was "
                             f"{self.config.beams_per_turn} x {self.config.n_bins}")
        t0 = stamp_ns(m.header, log_time_ns)
        out = self._beams(t0) if self.pending is not None else []
        self.pending = (t0, counts)
        return out

    def finish(self) -> list[tuple[int, impala_msgs.RadarBeam]]:
        """The last turn's beams, spread over the rotation period."""
        return self._beams(None) if self.pending is not None else []

    def _beams(self, next_ns: int | None) -> list[tuple[int, impala_msgs.RadarBeam]]:
        """The pending turn's beams over the rotation period from its stamp, never past the next turn's stamp
        (an interval shorter than the period but at least half of it: the turn ends there)."""
        assert self.pending is not None and self.config is not None
        t0, counts = self.pending
        self.pending = None
        self.turn += 1
        n = counts.shape[0]
        period_ns = 1e9 / self.g["rotation_hz"]
        if next_ns is not None and 0.5 * period_ns <= next_ns - t0 < period_ns:
            period_ns = float(next_ns - t0)
            self.shortened += 1
        azimuth = self._azimuth(np.arange(n) / n, self.g)
        power = counts_to_power(counts, self.g["db_per_count"])
        cfg, turn = self.config, self.turn
        return [(t0 + int(round(i * period_ns / n)), impala_msgs.RadarBeam(float(azimuth[i]), turn, i, power[i],
                                                                            _EMPTY, cfg))
                for i in range(n)]

    def notes(self) -> list[str]:
        extra = [f"{self.shortened} turn(s) whose next stamp came before a rotation period: spread up to it"] \
            if self.shortened else []
        return [*self._notes, *extra]


class FftAdapter(_Radar):
    """Navtech's FFT-data message (one azimuth each) -> one RadarBeam, at the radar's own time."""

    LAYOUT = msgdefs.NAVTECH_BYTE_LAYOUT["messages/RadarFftDataMessage"]

    def adapt(self, payload: memoryview, log_time_ns: int) -> Iterator[tuple[int, impala_msgs.RadarBeam]]:
        m = self.decode(payload)
        data = np.frombuffer(bytes(m.data), dtype=np.uint8)
        if self.config is None:
            g = self._geometry(int(data.size), None, [])
            for key in ("encoder_size", "beams_per_turn"):
                if g.get(key) is None:
                    raise ValueError(f"{key} unknown: no Navtech configuration message in the bag; give the option")
            self.g, self.config = g, self._config(g)
            self._notes.append("beam times: the radar's per-azimuth time (ntp_seconds, ntp_split_seconds)")
            self.last = None
        try:
            enc = int(_layout(m.azimuth, self.LAYOUT["azimuth"]) or 0)
            sec = int(_layout(m.ntp_seconds, self.LAYOUT["ntp_seconds"]) or 0)
            split = int(_layout(m.ntp_split_seconds, self.LAYOUT["ntp_split_seconds"]) or 0)
        except ValueError as e:
            raise ValueError(f"FFT data: {e}") from None
        if data.size != self.config.n_bins:
            raise ValueError(f"FFT data of {data.size} bins, the turn has {self.config.n_bins}")
        if self.last is None or enc < self.last:
            self.turn += 1
        self.last = enc
        t = sec * 1_000_000_000 + split if sec or split else stamp_ns(m.header, log_time_ns)
        encoder = float(self.g["encoder_size"])
        index = int(enc * self.config.beams_per_turn // encoder)
        az = float(self._azimuth(np.array([enc / encoder]), self.g)[0])
        return [(t, impala_msgs.RadarBeam(az, self.turn, index, counts_to_power(data, self.g["db_per_count"]),
                                          _EMPTY, self.config))]
