"""Streaming mission simulation: radar beams, truth of movers, proprioceptive sensors.

:func:`simulate` yields ``(t_ns, port, msg)`` in non-decreasing time order, merging with
``heapq.merge``: ``"beams"`` -> :class:`~impala_msgs.RadarBeam`, ``"movers"`` ->
:class:`~impala_msgs.ObjectStates` (10 Hz), and one port per proprioceptive sensor
(``"odometer"``, ``"gyro"``, ``"gps"`` from :mod:`impala_radar.simulator.sensors`). At most one
antenna turn is held in memory (two with threads: one being synthesized while the next is computed).

Beam timing: beam ``j`` of turn ``k`` is acquired during one modulation period centred at
``t = start + (k B + j + 1/2) / (B f_rot)`` (integer ns) with the antenna at
``azimuth = 2 pi (j + 1/2) / B`` in the vehicle frame (counter-clockwise rotation, 0 =
heading; ``RadarParams.clockwise`` and ``start_azimuth_rad`` give a clockwise antenna, like
the Navtech's, and a turn that starts anywhere). Each beam is computed at the vehicle pose
and velocity of its own time, so a moving radar sees the scene distorted (a straight wall becomes a trochoid) and every
static echo carries the vehicle's Doppler V = -v . u (u the line of sight).

Work per turn (:mod:`impala_radar.simulator.spectra` for the equations; ``bench/simulator.py``
prints its split by stage): the static
scatterers within reach of the turn's poses are fetched once (k-d tree), clutter tiles near
the radar split for developed speckle, vegetation jittered, facade mirror images added
(:mod:`.clutter`, :mod:`.receiver`); each scatterer gets the azimuth window where its echo
can still matter (:mod:`.antenna`); a polar map of the shadowing discs (trunks, crowns,
parked cars, movers swept over the turn) marks what may be shadowed; the turn is cut
into blocks of 8 beams; per block the scatterers whose bearing can fall inside the beams'
pattern are selected (bearing from the turn centre, widened by the pose spread), their
occlusion (walls; discs on the marked ones) is tested at the block's middle pose (8 beams =
22 ms of motion), and the (beam, scatterer) pairs inside the beams' pattern are kept, all
blocks in one compiled pass (:func:`.kernels.block_pairs`); the echoes of all the pairs are
then evaluated at once, the arithmetic compiled around numpy's transcendental functions, and
the echoes too weak to change the noise floor culled there. The loops over scatterers and
echoes (block selection, pairs, ray tests, physics, NUFFT preparation and spreading) are
compiled with numba (:mod:`.kernels`, :mod:`.synth_kernels`, cached on disk, compiled at their first call), with the
arithmetic of the numpy formulation they replaced, so seeded missions are the same bit for
bit; the transcendental functions stay numpy's. Movers are evaluated over
the whole turn at every beam time, occlusion included (walls and static discs). With the
transmitter leakage echoes, all echoes of the turn then go through one
:class:`~impala_radar.simulator.spectra.Synthesizer`: :meth:`~.Synthesizer.draw` (the random
draws) then :meth:`~.Synthesizer.synthesize` (no randomness).

Threads (``threads``, default :func:`default_threads`: the cores, at most 2): turns are
pipelined, turn k's synthesis (NUFFT, spectra, output stage) running on a thread of its own
while the calling thread computes turn k + 1's echoes and draws its noise (so two turns are in
memory at most); a turn's blocks are cut into contiguous runs (3 a thread), which the threads
take in order whenever one is free (the calling thread too, so a helper busy with the synthesis
never leaves it waiting for a fixed half); each run's pairs and their echoes are computed by the
thread that took it, and the runs' echoes reach the synthesizer as parts, read in run order
(never concatenated). The random stream is drawn on the calling thread in the one-thread order,
the compiled loops release the GIL, so does numpy on large arrays. A mission is the same bit
for bit whatever the thread count and the scheduling.
"""

from __future__ import annotations

import heapq
import math
import os
import threading
from collections.abc import Iterator, Mapping
from concurrent.futures import ThreadPoolExecutor
from operator import itemgetter

import numpy as np

from impala_flow.msgs import wrap_angle as _wrap
from impala_msgs import SPEED_OF_LIGHT_MPS, ObjectStates, RadarBeam, RadarConfig

from .clutter import grazing_factor, hash_uniform, split_tiles, vegetation_jitter
from .receiver import adc_counts, leakage_echoes, mirror_images
from .spectra import (
    Echoes,
    RadarParams,
    Synthesizer,
    azimuth_pattern,
    echoes,
    received_power_w,
)
from .world import VEGETATION_KINDS, World, car_discs, disc_transmission

DEFAULT_PARAMS = RadarParams()

__all__ = ["simulate", "RadarSimulator", "beam_times_ns", "beam_azimuths_rad", "default_threads"]


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


_POLAR_BIN_RAD = math.radians(0.5)
_POOLS: dict[tuple[int, str], ThreadPoolExecutor] = {}
_POOLS_LOCK = threading.Lock()


def default_threads() -> int:
    """Threads of a simulator by default: the machine's cores, at most 2 (the turn's work
    splits in two halves; beyond, the Python glue between the compiled loops dominates)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return max(1, min(2, cores or 1))


def _pool(workers: int, name: str = "radar-sim") -> ThreadPoolExecutor:
    """A process-wide pool of ``workers`` threads named ``name`` (shared by the simulators, created once)."""
    with _POOLS_LOCK:
        if (workers, name) not in _POOLS:
            _POOLS[workers, name] = ThreadPoolExecutor(workers, thread_name_prefix=name)
        return _POOLS[workers, name]


def _stable_argsort(x: np.ndarray, max_ties: int = 256) -> np.ndarray:
    """``np.argsort(x, kind="stable")`` of NaN-free keys: numpy's (SIMD) quicksort, 3 times faster,
    then the indices of each run of equal keys put in increasing order (the stable sort's); with
    more than ``max_ties`` such runs, the stable sort itself."""
    order = np.argsort(x)
    s = x[order]
    eq = s[1:] == s[:-1]
    if not eq.any():
        return order
    lo = np.flatnonzero(eq[1:] & ~eq[:-1]) + 1  # runs of equal keys: order[lo:hi + 1]
    if eq[0]:
        lo = np.concatenate([[0], lo])
    if len(lo) > max_ties:
        return np.argsort(x, kind="stable")
    hi = np.flatnonzero(eq[:-1] & ~eq[1:]) + 1
    if eq[-1]:
        hi = np.concatenate([hi, [len(eq)]])
    for a, b in zip(lo.tolist(), hi.tolist(), strict=True):
        order[a:b + 1] = np.sort(order[a:b + 1])
    return order


def _maybe_behind(discs, center, spread, bearing, rc, sz, radar_z_m, bin_rad=_POLAR_BIN_RAD):
    """Scatterers that a disc may shadow during the turn: on a polar map around the turn
    centre (bins of ``bin_rad``), each bin keeps the nearest distance of the discs covering
    it (widened by the pose spread); discs above the radar only count for scatterers above
    the radar. The exact test (:func:`disc_transmission`) runs on these only."""
    n_bins = int(round(2 * np.pi / bin_rad))
    dx, dy = discs[:, 0] - center[0], discs[:, 1] - center[1]
    dist = np.hypot(dx, dy)
    reach = discs[:, 2] + spread
    inside = dist <= reach
    wide = np.where(inside, np.pi, np.arcsin(np.minimum(1.0, reach / np.maximum(dist, 1e-9))))
    near_edge = np.where(inside, 0.0, dist - reach)
    b0 = np.floor((np.arctan2(dy, dx) - wide + np.pi) / bin_rad).astype(np.intp)
    span = np.minimum(np.ceil(2 * wide / bin_rad).astype(np.intp) + 1, n_bins)
    rows = np.repeat(np.arange(len(discs)), span)
    cols = (np.repeat(b0, span) + np.arange(int(span.sum())) - np.repeat(np.cumsum(span) - span, span)) % n_bins
    out = np.zeros(len(rc), bool)
    b = np.minimum(((bearing + np.pi) / bin_rad).astype(np.intp), n_bins - 1)
    for high in (False, True):
        sel = (discs[rows, 3] > radar_z_m) == high
        first = np.full(n_bins, np.inf)
        np.minimum.at(first, cols[sel], near_edge[rows[sel]])
        hit = rc > first[b]
        out |= (hit & (sz > radar_z_m)) if high else hit
    return out


class RadarSimulator:
    """Computes the up/down spectra of whole turns of a rotating radar in a :class:`World`."""

    def __init__(self, world: World, config: RadarConfig, params: RadarParams = DEFAULT_PARAMS,
                 block_beams: int = 8, threads: int | None = None) -> None:
        self.world, self.config, self.params = world, config, params
        self.threads = default_threads() if threads is None else max(1, int(threads))
        self.synth = Synthesizer(config, params, pool=_pool(1) if self.threads > 1 else None)
        self.block_beams = block_beams
        self.azimuth_rad = beam_azimuths_rad(config, params)
        self._k_range = 4.0 * config.bandwidth_hz * config.modulation_hz / SPEED_OF_LIGHT_MPS
        self._cut_rad = params.cut_azimuth_rad(config)
        self._pattern = azimuth_pattern(config.beam_width_rad, params.sidelobe_db)
        self._veg = np.isin(world.kind, VEGETATION_KINDS)
        self._tile_gain = None  # the clutter tiles' exponential RCS factors, by world index (at the first turn)
        self._pairs_hint = 0

    def range_limit_m(self, closing_mps: float) -> float:
        """Largest range whose beat frequency can fall below fs/2 (eq. 2)."""
        f_d = 2.0 * closing_mps * self.config.f0_hz / SPEED_OF_LIGHT_MPS * self.synth.doppler_factor
        return (0.5 * self.synth.fs_hz + f_d) / self._k_range

    def turn(self, trajectory, t_ns: np.ndarray, rng: np.random.Generator):
        """(up, down) spectra (B, n_bins) float32 of the beams acquired at ``t_ns``."""
        return self.synth.spectra(self.echoes(trajectory, t_ns, rng), len(t_ns), rng)

    def echoes(self, trajectory, t_ns: np.ndarray, rng: np.random.Generator) -> Echoes:
        """The echoes of the beams acquired at ``t_ns`` (static, movers, leakage): what :meth:`turn`
        gives the synthesizer; ``rng`` draws the vegetation's jitter."""
        return Echoes.concat(self.echo_parts(trajectory, t_ns, rng))

    def echo_parts(self, trajectory, t_ns: np.ndarray, rng: np.random.Generator) -> list[Echoes]:
        """:meth:`echoes` in parts, not concatenated (the synthesizer joins them, on its own thread
        with threads)."""
        pose = trajectory.pose(t_ns)
        speed, _ = trajectory.velocity(t_ns)
        radar_xy = np.ascontiguousarray(pose[:, :2])
        radar_vxy = speed[:, None] * np.column_stack([np.cos(pose[:, 2]), np.sin(pose[:, 2])])
        beam_dir = pose[:, 2] + self.azimuth_rad[: len(t_ns)]
        center = radar_xy.mean(axis=0)
        spread = float(np.max(np.hypot(*(radar_xy - center).T)))
        r_lim = self.range_limit_m(float(np.max(np.abs(speed))))
        segs = self.world.segments_near(center, r_lim + spread)
        discs = self.world.discs_near(center, r_lim + spread) if self.params.shadows else np.zeros((0, 6))
        parts = self._static(radar_xy, radar_vxy, beam_dir, center, spread, r_lim, segs, discs, t_ns, rng)
        if self.world.movers:
            parts.append(self._movers(t_ns, radar_xy, radar_vxy, beam_dir, segs, discs))
        if self.params.leakage_dbm is not None:
            p_w = 10.0 ** (self.params.leakage_dbm / 10.0) * 1e-3
            parts.append(Echoes(*leakage_echoes(len(t_ns), p_w, self.params.leakage_range_m)))
        return parts

    def _windows(self, rc, sz, rcs, area):
        """Azimuth half-window per scatterer (:mod:`.antenna`): where its echo can still
        reach the culling level, from its boresight power at the turn centre's distance."""
        p = self.params
        floor = 10.0 ** (-p.pattern_cut_db / 10.0)
        if not p.thermal_noise:
            return np.full(len(rc), self._cut_rad)
        dz = sz - self.config.height_m
        r = np.sqrt(rc * rc + dz * dz)
        g_el = np.exp(-8.0 * math.log(2.0) * (np.arctan2(dz, rc) / p.elevation_beam_width_rad) ** 2)
        p0 = received_power_w(r, rcs * grazing_factor(r, dz, area, p.grazing_ref_deg), g_el,
                              self.config, p)
        with np.errstate(divide="ignore"):
            level = np.maximum(self.synth.noise_per_bin_w * 10.0 ** (-p.window_below_noise_db / 10.0) / p0,
                               floor)
        # distributed clutter: main lobe only (its sidelobe returns are the pattern's
        # integrated sidelobe ratio, about -40 dB, of its main-lobe return)
        clutter_level = 10.0 ** (-p.clutter_cut_db / 10.0)
        level = np.where(area > 0, np.maximum(level, clutter_level), level)
        # most clutter sits at clutter_level: its window looked up once (window_rad is element-wise)
        common = level == clutter_level
        window = np.empty(len(level))
        window[common] = self._pattern.window_rad(clutter_level)
        window[~common] = self._pattern.window_rad(level[~common])
        return np.minimum(window, self._cut_rad)

    def _scene(self, idx, center, rng):
        """Static scatterers of a turn: the world's, clutter tiles split for developed
        speckle, vegetation jitter and facade mirror images (:mod:`.clutter`, :mod:`.receiver`)."""
        w, p = self.world, self.params
        sx, sy, sz = w.x_m[idx], w.y_m[idx], w.z_m[idx]
        rcs, phase, area = w.rcs_m2[idx], w.phase_rad[idx], w.area_m2[idx]
        veg = self._veg[idx]
        if veg.any() and (p.vegetation_motion_m > 0 or p.vegetation_rcs_jitter_db > 0):
            d_phase, factor = vegetation_jitter(int(veg.sum()), rng, self.synth.lambda_m,
                                                p.vegetation_motion_m, p.vegetation_rcs_jitter_db)
            phase, rcs = phase.copy(), rcs.copy()
            phase[veg] += d_phase
            rcs[veg] *= factor
        ghost = np.zeros(len(idx), bool)
        tile = area > 0  # clutter tiles: exponential RCS around the tile's mean (hashed)
        if tile.any():
            rcs = rcs.copy()
            if self._tile_gain is None or len(self._tile_gain) != len(w.area_m2):  # once per world: by index only
                tiles = np.flatnonzero(w.area_m2 > 0)
                self._tile_gain = np.zeros(len(w.area_m2))
                self._tile_gain[tiles] = -np.log1p(-hash_uniform(tiles.astype(np.uint64), 7))
            rcs[tile] *= self._tile_gain[idx[tile]]
        if p.speckle_range_m > 0:
            near = np.nonzero((area > 0) & (np.hypot(sx - center[0], sy - center[1]) < p.speckle_range_m))[0]
            if near.size:
                dist = np.hypot(w.tile_x_m[idx[near]] - center[0], w.tile_y_m[idx[near]] - center[1])
                parent, x, y, r_sub, ph_sub, split = split_tiles(
                    idx[near], w.tile_x_m[idx[near]], w.tile_y_m[idx[near]], area[near], w.rcs_m2[idx[near]],
                    dist, self.config.range_resolution_m, self.config.beam_width_rad, p.speckle_max_split)
                if split.any():
                    keep = np.ones(len(idx), bool)
                    keep[near[split]] = False
                    par = near[parent]
                    q2 = np.bincount(parent, minlength=len(near))[parent]
                    sx, sy = np.concatenate([sx[keep], x]), np.concatenate([sy[keep], y])
                    sz = np.concatenate([sz[keep], sz[par]])
                    area = np.concatenate([area[keep], area[par] / q2])
                    rcs, phase = np.concatenate([rcs[keep], r_sub]), np.concatenate([phase[keep], ph_sub])
                    ghost = np.zeros(len(sx), bool)
        if p.multipath_reflection_db is not None and len(self._segs):
            par, gx, gy = mirror_images(sx, sy, rcs, center, self._segs, p.multipath_min_rcs_m2)
            if par.size:
                gamma2 = 10.0 ** (2.0 * p.multipath_reflection_db / 10.0)
                sx, sy = np.concatenate([sx, gx]), np.concatenate([sy, gy])
                sz, area = np.concatenate([sz, sz[par]]), np.concatenate([area, np.zeros(par.size)])
                rcs, phase = np.concatenate([rcs, rcs[par] * gamma2]), np.concatenate([phase, phase[par]])
                ghost = np.concatenate([ghost, np.ones(par.size, bool)])
        return sx, sy, sz, rcs, phase, area, ghost

    def _static(self, radar_xy, radar_vxy, beam_dir, center, spread, r_lim, segs, discs, t_ns,
                rng) -> list[Echoes]:
        """The static scatterers' echoes of a turn, in parts (one per thread's run of pairs)."""
        w = self.world
        idx = w.query(center, r_lim + spread)
        if idx.size == 0:
            return []
        self._segs = segs
        sx, sy, sz, rcs, phase, area, ghost = self._scene(idx, center, rng)
        dxc, dyc = sx - center[0], sy - center[1]
        bearing = np.arctan2(dyc, dxc)  # from the turn centre
        rc = np.hypot(dxc, dyc)
        window = self._windows(rc, sz, rcs, area)
        live = window > 0.0
        if not live.all():
            sx, sy, sz, rcs, phase, area, ghost, bearing, rc, window = (
                a[live] for a in (sx, sy, sz, rcs, phase, area, ghost, bearing, rc, window))
        behind = None
        swept = np.concatenate([discs, self._swept_mover_discs(t_ns)]) if self.params.shadows else discs
        if len(swept):  # shadows: prefilter on a polar map, exact test per block
            behind = _maybe_behind(swept, center, spread, bearing, rc, sz, self.config.height_m) & ~ghost
        slack = window + np.arcsin(np.minimum(1.0, spread / np.maximum(rc, 1e-9)))
        slack[rc <= spread] = np.pi  # the radar passes around it during the turn
        # far scatterers sorted by bearing (window look-up); near ones tested every block
        r_near = max(3.0, spread / math.sin(math.radians(5.0)))
        near = np.nonzero(rc <= r_near)[0]
        far = np.nonzero(rc > r_near)[0]
        far = far[_stable_argsort(bearing[far])]
        far_bearing = bearing[far]
        far_slack = (float(window[far].max()) if far.size else 0.0) + math.asin(min(1.0, spread / r_near))
        from . import kernels  # numba: compiled (cached) at the first call, not at import

        tan_cut = np.tan(np.minimum(window, 1.5))
        n, bb = len(beam_dir), self.block_beams
        mids, halves = kernels.block_spans(beam_dir, bb)  # np.unwrap of each block's directions

        rx, ry = radar_xy[:, 0].copy(), radar_xy[:, 1].copy()
        cos_b, sin_b = np.cos(beam_dir), np.sin(beam_dir)
        segs_c = np.ascontiguousarray(segs, float).reshape(-1, 4)
        no_behind = np.zeros(0, bool)

        def run(blocks: range):  # a run of blocks: their discs, pairs (one compiled pass), then echoes
            occ = [self._block_discs(discs, radar_xy[(b0 + min(n, b0 + bb) - 1) // 2], float(mids[b0 // bb]),
                                     float(halves[b0 // bb]) + self._cut_rad, t_ns[(b0 + min(n, b0 + bb) - 1) // 2])
                   for b0 in blocks]
            occ_lo = np.concatenate([[0], np.cumsum([len(o) for o in occ])]).astype(np.intp)
            occ_all = np.ascontiguousarray(np.concatenate(occ), float) if occ_lo[-1] else np.zeros((0, 6))
            beam, jj, d = kernels.block_pairs(
                blocks.start // bb, (blocks.stop - 1) // bb + 1, bb, mids, halves, far, far_bearing, near, bearing,
                slack, far_slack, rx, ry, cos_b, sin_b, sx, sy, sz, tan_cut, r_lim**2, ghost,
                no_behind if behind is None else behind, behind is not None, segs_c, occ_all, occ_lo,
                self.config.height_m, 0.05, self._pairs_hint * len(blocks) // max(1, -(-n // bb)))
            return [(len(beam), self._pair_echoes(beam, jj, d, radar_vxy, sz, rcs, phase, area) if len(beam) else None)]

        # blocks are independent: contiguous runs of them on the threads, their echoes joined in block order
        # (by the synthesizer: the physics is element-wise per pair, so the runs' echoes are those of all pairs)
        parts = self._map_chunks(run, range(0, n, bb))
        self._pairs_hint = sum(k for k, _ in parts) * 5 // 4  # the buffers' first size next turn
        return [e for _, e in parts if e is not None]

    def _pair_echoes(self, beam, jj, d, radar_vxy, sz, rcs, phase, area) -> Echoes:
        """:func:`.spectra.pair_echoes` of static pairs (beam, scatterer ``jj``, ``d`` from
        :func:`.kernels.block_pairs`): compiled arithmetic around numpy's transcendental functions,
        and the synthesizer's culling of weak echoes done here (element-wise: the same echoes reach it).
        Element-wise per pair, so runs of pairs on the threads joined in order give the same bits."""
        from . import kernels  # numba: compiled (cached) at the first call, not at import

        p, cfg = self.params, self.config
        lam = SPEED_OF_LIGHT_MPS / cfg.f0_hz
        k_eq = p.pt_g2_w(cfg) * lam**2 / (4.0 * math.pi) ** 3  # received_power_w's constant
        sin_ref = math.sin(math.radians(p.grazing_ref_deg)) if p.grazing_ref_deg is not None else 1.0
        rvx, rvy = radar_vxy[:, 0].copy(), radar_vxy[:, 1].copy()
        r_h, dz, range_m, radial = kernels.pair_ranges(beam, jj, d, sz, cfg.height_m, rvx, rvy)
        g_az = self._pattern.gain2(np.arctan2(d[3], d[2]))
        e_el = np.exp(kernels.elevation_exponent(np.arctan2(dz, r_h), p.elevation_beam_width_rad,
                                                 -8.0 * math.log(2.0)))
        return Echoes(*kernels.pair_power(beam, jj, d, g_az, e_el, dz, range_m, range_m**4, radial, rcs, phase, area,
                                          p.grazing_ref_deg is not None, sin_ref, k_eq,
                                          10.0 ** (-p.pattern_cut_db / 10.0), p.thermal_noise, self.synth._cull_w))

    def _map_chunks(self, fn, items: range, min_len: int = 2, per_thread: int = 3) -> list:
        """``fn`` of contiguous runs of ``items`` (lists), concatenated in run order: the result does
        not depend on the thread count or on scheduling. With threads, ``per_thread`` runs a thread
        are handed out in order to whichever thread is free (this one included), so a helper busy
        elsewhere (or descheduled) does not leave this thread waiting for a fixed half."""
        k = min(self.threads * per_thread, len(items) // min_len) if self.threads > 1 else 1
        if k <= 1:
            return fn(items)
        cuts = [items.start + len(items) * i // k * items.step for i in range(k + 1)]
        runs = [range(cuts[i], cuts[i + 1], items.step) for i in range(k)]
        results: list = [None] * k
        order = iter(range(k))
        lock = threading.Lock()

        def work() -> None:
            while True:
                with lock:  # each run handed out once
                    i = next(order, None)
                if i is None:
                    return
                results[i] = fn(runs[i])

        pool = _pool(self.threads - 1)
        futures = [pool.submit(work) for _ in range(self.threads - 1)]
        work()
        for f in futures:
            f.result()
        return [x for r in results for x in r]

    def _swept_mover_discs(self, t_ns, n_samples: int = 9):
        """The movers' discs at ``n_samples`` times of the turn, widened by the motion between."""
        out = [np.zeros((0, 6))]
        ts = np.linspace(int(t_ns[0]), int(t_ns[-1]), n_samples).astype(np.int64)
        for m in self.world.movers:
            xy, _, h, on = m.state(ts)
            if on.any():
                d = car_discs(xy[on, 0], xy[on, 1], h[on])
                d[:, 2] += 0.5 * m.speed_mps * (ts[1] - ts[0]) * 1e-9 if n_samples > 1 else 0.0
                out.append(d)
        return np.concatenate(out)

    def _block_discs(self, discs, pos, mid, half, t_ns):
        """The shadowing discs (static and movers' at ``t_ns``) within a block's sector."""
        if not self.params.shadows:
            return discs
        if self.world.movers:
            st = [m.state(t_ns) for m in self.world.movers]
            on = [s for s in st if bool(s[3])]
            if on:
                discs = np.concatenate([discs, car_discs([s[0][0] for s in on], [s[0][1] for s in on],
                                                         [s[2] for s in on])])
        if len(discs) == 0:
            return discs
        dx, dy = discs[:, 0] - pos[0], discs[:, 1] - pos[1]
        dist = np.hypot(dx, dy)
        wide = np.arcsin(np.minimum(1.0, discs[:, 2] / np.maximum(dist, 1e-9)))
        return discs[np.abs(_wrap(np.arctan2(dy, dx) - mid)) <= half + wide]

    def _movers(self, t_ns, radar_xy, radar_vxy, beam_dir, segs, discs) -> Echoes:
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
        if len(discs) and self.params.shadows:
            vis = vis * disc_transmission(radar_xy[:, None, :], self.config.height_m, xy[..., 0],
                                          xy[..., 1], np.broadcast_to(z, xy.shape[:2]), discs)
        closing = np.hypot(vxy[..., 0], vxy[..., 1]).max() + np.hypot(*radar_vxy.T).max()
        r_lim = self.range_limit_m(float(closing))
        return echoes(np.arange(len(t_ns)), radar_xy, radar_vxy, beam_dir, xy, z, vxy, rcs,
                      phase, self.config, self.params, visible=vis, range_limit_m=r_lim)


def _beam_stream(sim: RadarSimulator, trajectory, start: int, end: int,
                 rng: np.random.Generator) -> Iterator[tuple[int, str, RadarBeam]]:
    config = sim.config
    p = sim.params
    adc = None
    if p.adc_db_per_count is not None:
        noise_w = sim.synth.noise_per_bin_w

        def adc(x: np.ndarray) -> np.ndarray:
            return adc_counts(x, noise_w, p.adc_db_per_count, p.adc_zero_db, p.adc_max_count)

    def synthesize(e, draws, n):  # no randomness: on the pipeline's thread with threads > 1
        up, down = sim.synth.synthesize(e, draws, n)
        if adc is not None:  # the radar's own output stage (Navtech: 8-bit counts of 0.5 dB)
            up = adc(up)
            down = adc(down) if np.size(down) else down
        return up, down

    # turn k's synthesis runs on its own thread while this one computes turn k + 1's echoes and
    # draws; the draws stay on this thread in the one-thread order, so the bits do not depend on it
    pipe = _pool(1, "radar-sim-pipe") if sim.threads > 1 else None
    pending = None
    turn = 0
    while True:
        t_ns = beam_times_ns(start, turn, config)
        n = int(np.searchsorted(t_ns, end))  # beams acquired before the end
        job = None
        if n:
            e, draws = sim.synth.draw(sim.echo_parts(trajectory, t_ns[:n], rng), n, rng)
            job = (turn, t_ns, n, pipe.submit(synthesize, e, draws, n) if pipe else synthesize(e, draws, n))
            if pipe is None:
                pending, job = job, None
        if pending is not None:
            k, t_k, n_k, spectra = pending
            up, down = spectra.result() if pipe else spectra
            for j, t_j, az_j in zip(range(n_k), t_k.tolist(), sim.azimuth_rad.tolist(), strict=False):
                yield t_j, "beams", RadarBeam(az_j, k, j, up[j], down[j], config)
        if not n:
            return
        pending = job
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
             movers_rate_hz: float = 10.0, threads: int | None = None) -> Iterator[tuple[int, str, object]]:
    """Yield ``(t_ns, port, msg)`` of a simulated acquisition, in non-decreasing time.

    ``trajectory`` has ``pose(t_ns)``, ``velocity(t_ns)``, ``start_ns``, ``end_ns``
    (:class:`impala_radar.simulator.vehicle.Trajectory`). The run covers ``[start_t_ns,
    start_t_ns + duration_ns)`` clipped to the trajectory's end. ``sensors`` maps a port name
    to an object with ``samples(trajectory, rng, start_ns, end_ns)``. ``rng`` is split
    (``Generator.spawn``) into independent streams for the radar's thermal noise and each
    sensor, so adding a sensor does not change the radar's noise. ``threads`` (default
    :func:`default_threads`) share each turn's work; the result is the same bit for bit
    whatever their number.
    """
    start = trajectory.start_ns if start_t_ns is None else int(start_t_ns)
    end = int(trajectory.end_ns)
    if duration_ns is not None:
        end = min(end, start + int(duration_ns))
    sensors = dict(sensors or {})
    radar_rng, *sensor_rngs = rng.spawn(1 + len(sensors))
    sim = RadarSimulator(world, config, params, threads=threads)
    streams = [_beam_stream(sim, trajectory, start, end, radar_rng)]
    if world.movers:
        streams.append(_mover_stream(world, start, end, movers_rate_hz))
    for (name, sensor), r in zip(sorted(sensors.items()), sensor_rngs, strict=True):
        streams.append(_sensor_stream(name, sensor, trajectory, r, start, end))
    return heapq.merge(*streams, key=itemgetter(0))

