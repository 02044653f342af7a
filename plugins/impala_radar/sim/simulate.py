"""Streaming mission simulation: radar beams, truth of movers, proprioceptive sensors.

:func:`simulate` yields ``(t_ns, port, msg)`` in non-decreasing time order, merging with
``heapq.merge``: ``"beams"`` -> :class:`~impala_flow.msgs.RadarBeam`, ``"movers"`` ->
:class:`~impala_flow.msgs.ObjectStates` (10 Hz), and one port per proprioceptive sensor
(``"odometer"``, ``"gyro"``, ``"gps"`` from :mod:`impala_radar.sim.sensors`). At most one
antenna turn is held in memory.

Beam timing: beam ``j`` of turn ``k`` is acquired during one modulation period centred at
``t = start + (k B + j + 1/2) / (B f_rot)`` (integer ns) with the antenna at
``azimuth = 2 pi (j + 1/2) / B`` in the vehicle frame (counter-clockwise rotation, 0 =
heading; ``RadarParams.clockwise`` and ``start_azimuth_rad`` give a clockwise antenna, like
the Navtech's, and a turn that starts anywhere). Each beam is computed at the vehicle pose
and velocity of its own time, so a moving radar sees the scene distorted (a straight wall becomes a trochoid) and every
static echo carries the vehicle's Doppler V = -v . u (u the line of sight).

Work per turn (vectorised; :mod:`impala_radar.sim.spectra` for the equations): the static
scatterers within reach of the turn's poses are fetched once (k-d tree); the turn is cut
into blocks of 8 beams; per block the scatterers whose bearing can fall inside the beams'
pattern are selected (bearing from the turn centre, widened by the pose spread), their
occlusion is tested at the block's middle pose (8 beams = 22 ms of motion), and their
echoes are evaluated densely over (block beams x scatterers). Movers are evaluated over
the whole turn at every beam time, occlusion included. All echoes of the turn then go
through one :class:`~impala_radar.sim.spectra.Synthesizer` call.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterator, Mapping
from operator import itemgetter

import numpy as np

from impala_flow.msgs import SPEED_OF_LIGHT_MPS, ObjectStates, RadarBeam, RadarConfig
from impala_flow.msgs import wrap_angle as _wrap

from .spectra import Echoes, RadarParams, Synthesizer, echoes
from .world import World

DEFAULT_PARAMS = RadarParams()

__all__ = ["simulate", "RadarSimulator", "beam_times_ns", "beam_azimuths_rad"]


def beam_times_ns(start_t_ns: int, turn: int, config: RadarConfig) -> np.ndarray:
    """Acquisition times (int64 ns) of the beams of ``turn`` (centre of each period)."""
    n = config.beams_per_turn
    k = turn * n + np.arange(n) + 0.5
    return int(start_t_ns) + np.rint(k * (1e9 / (config.rotation_hz * n))).astype(np.int64)


def beam_azimuths_rad(config: RadarConfig, params: RadarParams = DEFAULT_PARAMS) -> np.ndarray:
    """Antenna azimuth of each beam in the vehicle frame (CCW from the heading, in [0, 2 pi)):
    beam j is centred half a step after ``params.start_azimuth_rad`` + j steps, the steps
    counter-clockwise, or clockwise with ``params.clockwise``."""
    step = 2.0 * np.pi / config.beams_per_turn * (-1.0 if params.clockwise else 1.0)
    return np.mod(params.start_azimuth_rad + step * (np.arange(config.beams_per_turn) + 0.5), 2.0 * np.pi)


def _bearing_window(idx, sorted_bearing, mid, half):
    """Entries of ``idx`` whose bearing (sorted, in [-pi, pi)) is within ``half`` of ``mid``."""
    if half >= np.pi:
        return idx
    lo, hi = mid - half, mid + half
    parts = [(max(lo, -np.pi), min(hi, np.pi))]
    if lo < -np.pi:
        parts.append((lo + 2 * np.pi, np.pi))
    if hi > np.pi:
        parts.append((-np.pi, hi - 2 * np.pi))
    return np.concatenate([idx[np.searchsorted(sorted_bearing, a):
                               np.searchsorted(sorted_bearing, b, side="right")]
                           for a, b in parts])


class RadarSimulator:
    """Computes the up/down spectra of whole turns of a rotating radar in a :class:`World`."""

    def __init__(self, world: World, config: RadarConfig, params: RadarParams = DEFAULT_PARAMS,
                 block_beams: int = 8) -> None:
        self.world, self.config, self.params = world, config, params
        self.synth = Synthesizer(config, params)
        self.block_beams = block_beams
        self.azimuth_rad = beam_azimuths_rad(config, params)
        self._k_range = 4.0 * config.bandwidth_hz * config.modulation_hz / SPEED_OF_LIGHT_MPS
        self._cut_rad = params.cut_azimuth_rad(config)

    def range_limit_m(self, closing_mps: float) -> float:
        """Largest range whose beat frequency can fall below fs/2 (eq. 2)."""
        f_d = 2.0 * closing_mps * self.config.f0_hz / SPEED_OF_LIGHT_MPS
        return (0.5 * self.synth.fs_hz + f_d) / self._k_range

    def turn(self, trajectory, t_ns: np.ndarray, rng: np.random.Generator):
        """(up, down) spectra (B, n_bins) float32 of the beams acquired at ``t_ns``."""
        pose = trajectory.pose(t_ns)
        speed, _ = trajectory.velocity(t_ns)
        radar_xy = np.ascontiguousarray(pose[:, :2])
        radar_vxy = speed[:, None] * np.column_stack([np.cos(pose[:, 2]), np.sin(pose[:, 2])])
        beam_dir = pose[:, 2] + self.azimuth_rad[: len(t_ns)]
        center = radar_xy.mean(axis=0)
        spread = float(np.max(np.hypot(*(radar_xy - center).T)))
        r_lim = self.range_limit_m(float(np.max(np.abs(speed))))
        segs = self.world.segments_near(center, r_lim + spread)
        parts = [self._static(radar_xy, radar_vxy, beam_dir, center, spread, r_lim, segs)]
        if self.world.movers:
            parts.append(self._movers(t_ns, radar_xy, radar_vxy, beam_dir, segs))
        return self.synth.spectra(Echoes.concat(parts), len(t_ns), rng)

    def _static(self, radar_xy, radar_vxy, beam_dir, center, spread, r_lim, segs) -> Echoes:
        w = self.world
        idx = w.query(center, r_lim + spread)
        if idx.size == 0:
            return Echoes.concat([])
        sx, sy, sz = w.x_m[idx], w.y_m[idx], w.z_m[idx]
        rcs, phase = w.rcs_m2[idx], w.phase_rad[idx]
        dxc, dyc = sx - center[0], sy - center[1]
        bearing = np.arctan2(dyc, dxc)  # from the turn centre
        rc = np.hypot(dxc, dyc)
        slack = self._cut_rad + np.arcsin(np.minimum(1.0, spread / np.maximum(rc, 1e-9)))
        slack[rc <= spread] = np.pi  # the radar passes around it during the turn
        # far scatterers sorted by bearing (window look-up); near ones tested every block
        r_near = max(10.0, spread / math.sin(math.radians(5.0)))
        near = np.nonzero(rc <= r_near)[0]
        far = np.nonzero(rc > r_near)[0]
        far = far[np.argsort(bearing[far], kind="stable")]
        far_bearing = bearing[far]
        far_slack = self._cut_rad + math.asin(min(1.0, spread / r_near))
        parts = []
        n = len(beam_dir)
        for b0 in range(0, n, self.block_beams):
            sl = slice(b0, min(n, b0 + self.block_beams))
            d = np.unwrap(beam_dir[sl])
            mid, half = _wrap(0.5 * (d[0] + d[-1])), 0.5 * abs(d[-1] - d[0])
            j = np.concatenate([_bearing_window(far, far_bearing, mid, half + far_slack), near])
            j = j[np.abs(_wrap(bearing[j] - mid)) <= half + slack[j]]
            if j.size == 0:
                continue
            vis = None
            if len(segs):
                vis = w.visible(radar_xy[(sl.start + sl.stop - 1) // 2], sx[j], sy[j], segs)
            parts.append(echoes(np.arange(sl.start, sl.stop), radar_xy[sl], radar_vxy[sl],
                                beam_dir[sl], np.column_stack([sx[j], sy[j]]), sz[j], None,
                                rcs[j], phase[j], self.config, self.params, visible=vis,
                                range_limit_m=r_lim))
        return Echoes.concat(parts)

    def _movers(self, t_ns, radar_xy, radar_vxy, beam_dir, segs) -> Echoes:
        movers = self.world.movers
        states = [m.scatterers(t_ns) for m in movers]
        xy = np.concatenate([s[0] for s in states], axis=1)  # (B, K, 2)
        vxy = np.concatenate([s[1] for s in states], axis=1)
        active = np.concatenate([np.repeat(s[2][:, None], len(m.rcs_m2), axis=1)
                                 for s, m in zip(states, movers, strict=True)], axis=1)
        if not active.any():
            return Echoes.concat([])
        z = np.concatenate([m.body_xyz_m[:, 2] for m in movers])
        rcs = np.concatenate([m.rcs_m2 for m in movers])
        phase = np.concatenate([m.phase_rad for m in movers])
        vis = active
        if len(segs):
            vis = active & self.world.visible(radar_xy[:, None, :], xy[..., 0], xy[..., 1], segs)
        closing = np.hypot(vxy[..., 0], vxy[..., 1]).max() + np.hypot(*radar_vxy.T).max()
        r_lim = self.range_limit_m(float(closing))
        return echoes(np.arange(len(t_ns)), radar_xy, radar_vxy, beam_dir, xy, z, vxy, rcs,
                      phase, self.config, self.params, visible=vis, range_limit_m=r_lim)


def _beam_stream(sim: RadarSimulator, trajectory, start: int, end: int,
                 rng: np.random.Generator) -> Iterator[tuple[int, str, RadarBeam]]:
    config = sim.config
    turn = 0
    while True:
        t_ns = beam_times_ns(start, turn, config)
        n = int(np.searchsorted(t_ns, end))  # beams acquired before the end
        if n == 0:
            return
        up, down = sim.turn(trajectory, t_ns[:n], rng)
        for j in range(n):
            yield int(t_ns[j]), "beams", RadarBeam(float(sim.azimuth_rad[j]), turn, j, up[j],
                                                   down[j], config)
        turn += 1


def _mover_stream(world: World, start: int, end: int,
                  rate_hz: float) -> Iterator[tuple[int, str, ObjectStates]]:
    period = int(round(1e9 / rate_hz))
    ids = np.array([m.id for m in world.movers], np.int64)
    for t in range(start, end, period):
        st = [m.state(t) for m in world.movers]
        on = np.array([bool(s[3]) for s in st], bool)
        xy = np.array([s[0] for s in st], float).reshape(-1, 2)[on]
        v = np.array([s[1] for s in st], float).reshape(-1, 2)[on]
        yield t, "movers", ObjectStates(ids[on], xy, v, np.zeros((int(on.sum()), 4, 4)))


def _sensor_stream(name: str, sensor, trajectory, rng, start: int, end: int):
    for t, msg in sensor.samples(trajectory, rng, start, end):
        yield int(t), name, msg


def simulate(world: World, trajectory, config: RadarConfig, rng: np.random.Generator,
             start_t_ns: int | None = None, duration_ns: int | None = None,
             sensors: Mapping[str, object] | None = None, *,
             params: RadarParams = DEFAULT_PARAMS,
             movers_rate_hz: float = 10.0) -> Iterator[tuple[int, str, object]]:
    """Yield ``(t_ns, port, msg)`` of a simulated acquisition, in non-decreasing time.

    ``trajectory`` has ``pose(t_ns)``, ``velocity(t_ns)``, ``start_ns``, ``end_ns``
    (:class:`impala_radar.sim.vehicle.Trajectory`). The run covers ``[start_t_ns,
    start_t_ns + duration_ns)`` clipped to the trajectory's end. ``sensors`` maps a port name
    to an object with ``samples(trajectory, rng, start_ns, end_ns)``. ``rng`` is split
    (``Generator.spawn``) into independent streams for the radar's thermal noise and each
    sensor, so adding a sensor does not change the radar's noise.
    """
    start = trajectory.start_ns if start_t_ns is None else int(start_t_ns)
    end = int(trajectory.end_ns)
    if duration_ns is not None:
        end = min(end, start + int(duration_ns))
    sensors = dict(sensors or {})
    radar_rng, *sensor_rngs = rng.spawn(1 + len(sensors))
    sim = RadarSimulator(world, config, params)
    streams = [_beam_stream(sim, trajectory, start, end, radar_rng)]
    if world.movers:
        streams.append(_mover_stream(world, start, end, movers_rate_hz))
    for (name, sensor), r in zip(sorted(sensors.items()), sensor_rngs, strict=True):
        streams.append(_sensor_stream(name, sensor, trajectory, r, start, end))
    return heapq.merge(*streams, key=itemgetter(0))

