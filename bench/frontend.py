"""Radar front-end benchmark: CPU ms per turn of each front-end stage, one thread.

    python bench/frontend.py [--turns 6] [--start-s 20] [--repeat 3]
                             [--radiate out/radiate-head.mcap] [--radiate-turns 100]

Beynes (simulated, IMPALA preset, vehicle at cruise speed after ``--start-s``): a few turns
are simulated once; then each stage runs on every turn through the same code as its
component (FuzzyPairer = xcorr Doppler prior + CFAR peaks + candidates + fuzzy scoring +
assignment; EgoVelocity = robust fit; PanoramicBuilder = motion (dead reckoning) + Doppler
compensation + polar -> 0.2 m grid; SpeckleFilter = 4-look co-registration + average).
RADIATE (real Navtech turns of an imported mission, ``--radiate``): the radar.PanoramicBuilder
component itself, fed beam by beam with graphs/oxford.yaml's settings (0.1 m cells, 60 m,
beam_median, motion-corrected with the truth's velocity through its ``twist`` input); its
cost is the CPU time spent inside the component, split by stage (and scan_to_grid by its
compiled loops); each image is let go at once, as R-SLAM and FMT do.

Times are CPU time of this thread (``time.thread_time``: the machine may be shared), the
median over turns of the best of ``--repeat`` runs (Beynes) or of each turn (RADIATE); the
split by stage is measured around each stage's function. Targets: panoramic builder and
pairer <= 15 ms per turn. The last line is one JSON object (keys name their units).

For the summary bench: :func:`bench_beynes` and :func:`bench_panoramic_radiate` return the
same figures as dicts.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import contextlib  # noqa: E402
import json  # noqa: E402
import resource  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from collections import defaultdict  # noqa: E402
from pathlib import Path  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from impala_flow import Component, Input  # noqa: E402
from impala_flow.msgs import Grid, Pose2D, Twist2D  # noqa: E402
from impala_radar.ego_velocity.core import fit_ego_velocity  # noqa: E402
from impala_radar.pairer import core as pairer_core  # noqa: E402
from impala_radar.pairer.component import detections_of_pairs  # noqa: E402
from impala_radar.panoramic import component as panoramic_component  # noqa: E402
from impala_radar.panoramic.core import (  # noqa: E402
    doppler_compensated_power,
    integrate_poses,
    relative_to,
    scan_to_grid,
)
from impala_radar.speckle.core import multilook  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
RADIATE_DEFAULT = ROOT / "out" / "radiate-head.mcap"  # impala-flow import radiate ../shared/data/radiate-edinburgh-head
#: graphs/oxford.yaml's panoramic builder
OXFORD_PANORAMIC = {"cell_m": 0.1, "range_max_m": 60.0, "range_min_m": 2.0, "reference": "middle",
                    "normalise": "beam_median"}


def peak_rss_mb() -> float:
    """Peak resident set size of this process so far (MB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


@contextlib.contextmanager
def timed_functions(module, names: list[str], acc: dict[str, float]):
    """Patch ``module.<name>`` for each name with a wrapper adding its CPU time (ms) to
    ``acc[name]``; restored on exit. Nested stages count in each (name them disjoint)."""
    saved = {n: getattr(module, n) for n in names}

    def wrap(name, fn):
        def inner(*a, **k):
            t0 = time.thread_time()
            try:
                return fn(*a, **k)
            finally:
                acc[name] += (time.thread_time() - t0) * 1e3
        return inner

    for n, fn in saved.items():
        setattr(module, n, wrap(n, fn))
    try:
        yield acc
    finally:
        for n, fn in saved.items():
            setattr(module, n, fn)


def _beynes_turns(n_turns: int, start_s: float):
    from impala_radar.simulator.scenario import load_scenario

    sc = load_scenario("beynes", duration_s=start_s + n_turns + 1.0)
    turns: dict[int, list] = {}
    odo: list[tuple[int, float]] = []
    gyro: list[tuple[int, float]] = []
    t_start = sc.start_t_ns + int(start_s * 1e9)
    for t, port, msg in sc.simulate():
        if port == "odometer":
            odo.append((t, msg.speed_mps))
        elif port == "gyro":
            gyro.append((t, msg.yaw_rate_radps))
        elif port == "beams" and t >= t_start:
            turns.setdefault(msg.turn, []).append((t, msg))
    full = [v for v in turns.values() if len(v) == v[0][1].config.beams_per_turn][:n_turns]
    return full, np.array(odo), np.array(gyro)


def _best(fn, repeat: int) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.thread_time()
        fn()
        best = min(best, time.thread_time() - t0)
    return best * 1e3


PAIRER_STAGES = ["xcorr_speed_prior", "detect_peaks", "candidate_pairs", "pair_score", "assign_pairs"]


def _bench_turn(turn, odo, gyro, pose, looks, repeat):
    """CPU time of each stage on one turn: (ms by stage, ms by sub-stage of the best run, outputs)."""
    t_ns = np.array([t for t, _ in turn], np.int64)
    beams = [b for _, b in turn]
    config = beams[0].config
    az = np.array([b.azimuth_rad for b in beams])
    up = np.stack([b.up for b in beams])
    down = np.stack([b.down for b in beams])
    out: dict = {"odometer_mps": float(np.interp(t_ns[-1], odo[:, 0], odo[:, 1]))}
    split: dict[str, float] = {}

    def pairer() -> None:
        v = pairer_core.xcorr_speed_prior(up, down, az, config)
        out["det"] = detections_of_pairs(pairer_core.pair_turn(up, down, az, config, v), beams[0].turn, t_ns, az,
                                         config)

    def ego() -> None:
        out["fit"] = fit_ego_velocity(out["det"].azimuth_rad, out["det"].radial_speed_mps)

    def panoramic() -> None:
        t0 = time.thread_time()
        v = np.interp(t_ns, odo[:, 0], odo[:, 1])
        w = np.interp(t_ns, gyro[:, 0], gyro[:, 1])
        od = integrate_poses(t_ns, v, w, pose)
        rel = relative_to(od, od[-1])
        t1 = time.thread_time()
        power = doppler_compensated_power(up, down, az, float(v.mean()), config)
        t2 = time.thread_time()
        grid, o = scan_to_grid(power, az, rel, config.range_per_bin_m, 0.2, config.range_max_m)
        t3 = time.thread_time()
        out["grid"] = Grid(grid, 0.2, o[0], o[1], "vehicle", Pose2D(*od[-1], frame="odom"))
        out["panoramic_split"] = {"motion": (t1 - t0) * 1e3, "doppler": (t2 - t1) * 1e3,
                                  "polar_to_grid": (t3 - t2) * 1e3}

    def speckle() -> None:
        multilook(looks + [out["grid"]])

    pairer()  # warm (caches, compiled loops) before timing
    panoramic()
    times = {"pairer": _best(pairer, repeat), "ego_velocity": _best(ego, repeat),
             "panoramic_builder": _best(panoramic, repeat), "speckle_filter": _best(speckle, repeat)}
    acc: dict[str, float] = defaultdict(float)
    with timed_functions(pairer_core, PAIRER_STAGES, acc):
        pairer()
    split.update({f"pairer.{k}": v for k, v in acc.items()})
    split.update({f"panoramic.{k}": v for k, v in out["panoramic_split"].items()})
    return times, split, out


def bench_beynes(turns: int = 6, start_s: float = 20.0, repeat: int = 3, verbose: bool = False) -> dict:
    """Median CPU ms per turn of each front-end stage on simulated Beynes turns, with the
    split of the pairer and the panoramic builder (``split_ms``) and the pairer's Doppler
    speed error against the odometer."""
    cv2.setNumThreads(1)
    t0 = time.perf_counter()
    simulated, odo, gyro = _beynes_turns(turns, start_s)
    if verbose:
        print(f"simulated {len(simulated)} Beynes turns in {time.perf_counter() - t0:.1f} s")
    ms: dict[str, list[float]] = defaultdict(list)
    splits: dict[str, list[float]] = defaultdict(list)
    looks: list[Grid] = []
    pose = (0.0, 0.0, 0.0)
    n_det, speeds = [], []
    for turn in simulated:
        times, split, out = _bench_turn(turn, odo, gyro, pose, looks, repeat)
        for k, v in times.items():
            ms[k].append(v)
        for k, v in split.items():
            splits[k].append(v)
        g = out["grid"]
        pose = (g.pose.x_m, g.pose.y_m, g.pose.theta_rad)
        looks = (looks + [g])[-3:]
        n_det.append(len(out["det"].range_m))
        speeds.append((out["fit"].speed_mps, out["odometer_mps"]))
    err = [abs(e - o) for e, o in speeds]
    return {"ms_per_turn": {k: statistics.median(v) for k, v in ms.items()},
            "split_ms": {k: statistics.median(v) for k, v in splits.items()},
            "turns": len(simulated), "period_ms": 1e3 / simulated[0][0][1].config.rotation_hz,
            "detections_per_turn": statistics.median(n_det),
            "doppler_speed_error_mps": statistics.median(err),
            "odometer_mps": statistics.median(o for _, o in speeds)}


def _radiate_samples(mission: Path, turns: int) -> tuple[list, int]:
    """(t_ns, port, data) of the first ``turns`` + 1 turns' beams and a twist per turn: the
    truth's speed and yaw rate over the turn (finite differences of truth/pose)."""
    from impala_flow.io import MissionReader
    from impala_radar.turns import TurnBuffer

    buf, done = TurnBuffer(), []
    truth_t, truth_xyt = [], []
    with MissionReader(mission) as r:
        for m in r.messages(["radar/beams", "truth/pose"]):
            if m.topic == "truth/pose":
                truth_t.append(m.t_ns)
                truth_xyt.append((m.data.x_m, m.data.y_m, m.data.theta_rad))
                continue
            done += buf.add(m.t_ns, m.data)
            if len(done) > turns:
                break
    done = done[1:turns + 1]  # the first turn may be partial
    tt, xyt = np.array(truth_t, float), np.array(truth_xyt, float)
    samples = []
    for turn in done:
        t0, t1 = float(turn[0][0]), float(turn[-1][0])
        p0 = np.array([np.interp(t0, tt, xyt[:, k]) for k in range(3)])
        p1 = np.array([np.interp(t1, tt, xyt[:, k]) for k in range(3)])
        dt = (t1 - t0) * 1e-9
        speed = float(np.hypot(*(p1[:2] - p0[:2])) / dt)
        yaw = float(np.angle(np.exp(1j * (p1[2] - p0[2]))) / dt)
        samples.append((turn[0][0] - 1, "twist", Twist2D(speed, yaw)))
        samples += [(t, "beams", b) for t, b in turn]
    return samples, len(done)


class _ImageCounter(Component):
    """Takes each image and lets it go, as the graph's consumers (R-SLAM, FMT) do: a sink that
    kept them all would make every new grid fresh memory (page faults: about 3 ms a turn for
    graphs/oxford.yaml's 1201 x 1201 grid) and hold 6 MB a turn."""

    x = Input(Grid, maxsize=8)

    def start(self) -> None:
        self.images = 0

    def process(self, t: int) -> None:
        self.x.take()
        self.images += 1


PANORAMIC_STAGES = ["integrate_poses", "doppler_compensated_power", "normalise_beams", "scan_to_grid"]


def bench_panoramic_radiate(mission_path=RADIATE_DEFAULT, turns: int = 100, threads: int = 2) -> dict:
    """radar.PanoramicBuilder with graphs/oxford.yaml's settings on the first ``turns`` turns
    of an imported Navtech mission, ``threads`` sharing its normalisation and grid loops:
    median CPU ms per turn inside the component (every beam's ``process`` included, its pool
    threads' CPU added), median wall ms per turn (``wall_ms_per_turn``) and the split by stage
    (mean ms per turn: this thread's CPU in each stage, the pool threads' CPU as
    ``pool_threads``), all without the first turn (``first_turn_ms``: it builds the cached grid
    geometry and loads or compiles the numba loops)."""
    from impala_flow.testing import ScriptedSource, run_components

    cv2.setNumThreads(1)
    samples, n = _radiate_samples(Path(mission_path), turns)
    comp = panoramic_component.PanoramicBuilder("panoramic", **OXFORD_PANORAMIC, bootstrap=False, threads=threads)
    per_turn: list[float] = []
    wall: list[float] = []
    pool_ms: list[float] = []  # the pool's threads' CPU per turn
    spent = [0.0, 0.0, 0.0]  # this thread's CPU, wall, the pool's CPU at the turn's start
    acc: dict[str, float] = defaultdict(float)
    grid_acc: dict[str, float] = defaultdict(float)  # inside scan_to_grid
    first: dict[str, float] = {}
    process = comp.process

    def timed_process(t: int) -> None:
        t0, w0 = time.thread_time(), time.perf_counter()
        before = comp.turns if hasattr(comp, "turns") else 0
        process(t)
        spent[0] += time.thread_time() - t0
        spent[1] += time.perf_counter() - w0
        if comp.turns > before:
            pool_s = comp._pool.cpu_s
            pool_ms.append((pool_s - spent[2]) * 1e3)
            per_turn.append(spent[0] * 1e3 + pool_ms[-1])
            wall.append(spent[1] * 1e3)
            spent[:] = [0.0, 0.0, pool_s]
            if len(per_turn) == 1:  # the first turn builds the cached geometry (and compiles): not in the split
                first.update(acc)
                first.update({f"grid.{k}": v for k, v in grid_acc.items()})

    comp.process = timed_process
    sink = _ImageCounter("sink")
    with (timed_functions(panoramic_component, PANORAMIC_STAGES, acc),
          contextlib.ExitStack() as inner):
        from impala_radar.panoramic import _jit, core

        if hasattr(_jit, "polar_cells"):  # the compiled loops of scan_to_grid and its ground ranges
            inner.enter_context(timed_functions(_jit, ["polar_cells", "read_cells"], grid_acc))
            inner.enter_context(timed_functions(core._Disk, ["magnitude"], grid_acc))
        run_components(ScriptedSource("src", samples=samples), comp, sink,
                       connections=["src.beams -> panoramic.beams", "src.twist -> panoramic.twist",
                                    "panoramic.image -> sink.x"])
    steady = per_turn[1:] or per_turn
    split = {k: (v - first.get(k, 0.0)) / len(steady) for k, v in acc.items()} if len(per_turn) > 1 else dict(acc)
    split["pool_threads"] = statistics.fmean(pool_ms[1:] or pool_ms) if pool_ms else 0.0
    split["beams_and_rest"] = statistics.fmean(steady) - sum(split.values())
    grid = {k: (v - first.get(f"grid.{k}", 0.0)) / len(steady) for k, v in grid_acc.items()}
    if grid and threads == 1:  # with a pool the loops' figures are every thread's CPU, the stage's this thread's
        grid["rest"] = split["scan_to_grid"] - sum(grid.values())
    return {"ms_per_turn": statistics.median(steady), "wall_ms_per_turn": statistics.median(wall[1:] or wall),
            "threads": threads, "first_turn_ms": per_turn[0] if per_turn else float("nan"),
            "split_ms": split, "grid_split_ms": grid, "turns": n, "images": sink.images}


def _split_text(split: dict[str, float], prefix: str = "") -> str:
    items = [(k[len(prefix):], v) for k, v in split.items() if k.startswith(prefix)]
    return " + ".join(f"{k} {v:.1f}" for k, v in items)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--turns", type=int, default=6)
    ap.add_argument("--start-s", type=float, default=20.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--radiate", type=Path, default=RADIATE_DEFAULT, help="an imported RADIATE mission (mcap)")
    ap.add_argument("--radiate-turns", type=int, default=100)
    ap.add_argument("--threads", type=int, default=2, help="the RADIATE builder's threads")
    a = ap.parse_args()
    b = bench_beynes(a.turns, a.start_s, a.repeat, verbose=True)
    med, period_ms = b["ms_per_turn"], b["period_ms"]
    for k, v in med.items():
        print(f"{k:18s} {v:7.1f} ms/turn   x{period_ms / v:6.1f} real time")
    print(f"  pairer = {_split_text(b['split_ms'], 'pairer.')} ms")
    print(f"  panoramic = {_split_text(b['split_ms'], 'panoramic.')} ms")
    print(f"detections per turn: {b['detections_per_turn']:.0f}; |Doppler speed - odometer| median "
          f"{b['doppler_speed_error_mps']:.3f} m/s (odometer speed {b['odometer_mps']:.2f} m/s)")
    result = {f"{k}_ms_per_turn": round(v, 2) for k, v in med.items()}
    result["panoramic_beynes_ms_per_turn"] = result["panoramic_builder_ms_per_turn"]
    result["speckle_ms_per_turn"] = result["speckle_filter_ms_per_turn"]
    result.update({f"{k}_x_real_time": round(period_ms / v, 1) for k, v in med.items()})
    result.update({"turns": b["turns"], "detections_per_turn": b["detections_per_turn"],
                   "doppler_speed_error_mps": round(b["doppler_speed_error_mps"], 3)})
    if a.radiate.exists():
        r = bench_panoramic_radiate(a.radiate, a.radiate_turns, a.threads)
        print(f"RADIATE panoramic builder {r['ms_per_turn']:.1f} ms/turn of CPU, {r['wall_ms_per_turn']:.1f} wall with "
              f"{a.threads} threads ({r['turns']} turns; first turn "
              f"{r['first_turn_ms']:.0f} ms) = {_split_text(r['split_ms'])} ms (mean)")
        if r["grid_split_ms"]:
            print(f"  scan_to_grid = {_split_text(r['grid_split_ms'])} ms")
        result["panoramic_radiate_ms_per_turn"] = round(r["ms_per_turn"], 2)
        result["panoramic_radiate_wall_ms_per_turn"] = round(r["wall_ms_per_turn"], 2)
        result["panoramic_radiate_first_turn_ms"] = round(r["first_turn_ms"], 1)
    else:
        print(f"no RADIATE mission at {a.radiate}: import one with `impala-flow import radiate`")
    result["peak_rss_mb"] = round(peak_rss_mb(), 1)
    print(f"peak RSS {result['peak_rss_mb']:.0f} MB")
    print(json.dumps(result))


if __name__ == "__main__":
    main()
