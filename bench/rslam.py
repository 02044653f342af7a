"""Benchmark of R-SLAM (RADAR.md item 6) on the Beynes scenario, one core.

    python bench/rslam.py --turns 120          # the whole scenario: --turns 662

Simulated Beynes mission (radar.Simulator) -> radar.PanoramicBuilder -> radar.SpeckleFilter
-> slam.RSlam -> eval.TrajectoryEvaluator, with slam.DeadReckoning as the baseline; ms per
turn of R-SLAM (correlation + update) and of the processing chain (every component but
the simulator), ATE RMSE and final drift beside the baseline's; then the Oxford scan-pair
errors of graphs/oxford.yaml on the real sample (imported with ``impala-flow import oxford``).
``--synthetic`` replaces the radar simulator by impala_slam.synthetic's point world.
``--radiate MCAP`` (e.g. the first 400 scans of RADIATE's Edinburgh drive, imported) runs
graphs/oxford.yaml on it and kiss-icp (graphs/kiss_icp_navtech.yaml) on the same scans:
:func:`bench_radiate`, which bench/speed.py can call.

Times are CPU (far less inflated than wall time on a loaded machine): R-SLAM's is the sum of
its stages' thread CPU, on every thread it uses (``--threads``, default the component's 2),
split per stage: amplitude (dB image), prepare (map windows, prepared panoramics, window DFTs),
coarse and fine (the rotations of each level), update (eq. 6); the other components' is
``time.thread_time`` around their process. R-SLAM's wall time per turn (median) is printed
beside it: with 2 threads it is lower than the CPU. The peak RSS and the map's size are printed;
the last line is one JSON object with unit-named keys (rslam_beynes_ms_per_turn,
rslam_beynes_wall_ms_per_turn, rslam_beynes_ate_m, rslam_beynes_drift_pct, rslam_map_mb,
rslam_radiate_ms_per_turn, rslam_radiate_wall_median_ms_per_turn, rslam_radiate_ate_m,
kissicp_radiate_ms_per_scan, peak_rss_mb, ...). Targets (issue 26): R-SLAM <= 30 ms/turn on
Beynes, <= 40 ms/turn on RADIATE; ATE <= 1.0 m, drift <= 0.5 % on Beynes.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

os.environ.setdefault("OMP_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "plugins"))

import cv2  # noqa: E402
import numpy as np  # noqa: E402

cv2.setNumThreads(1)

from impala_flow import (  # noqa: E402
    Component,
    Output,
    Param,
    Session,  # noqa: E402
    Source,
)
from impala_flow.msgs import Grid, Pose2D  # noqa: E402
from impala_msgs import Speed, YawRate  # noqa: E402

GRAPH_SIM = """
name: rslam-bench
clock: {mode: replay, speed: max}
components:
  mission: {type: radar.Simulator, params: {scenario: beynes, duration_s: %(duration)s, seed: %(seed)s}}
  panoramic: {type: radar.PanoramicBuilder, params: {cell_m: 0.2}}
  speckle: {type: radar.SpeckleFilter, params: {looks: 2}}
  slam: {type: slam.RSlam, params: {map_period_s: 1.0e6, threads: %(threads)s}}
  deadreckoning: {type: slam.DeadReckoning, params: {period_s: 0.5}}
  eval: {type: eval.TrajectoryEvaluator, params: {report: "%(report)s"}}
connections:
  - mission.beams -> panoramic.beams
  - mission.odometer -> panoramic.odometer
  - mission.gyro -> panoramic.gyro
  - panoramic.image -> speckle.image
  - speckle.filtered -> slam.image
  - mission.odometer -> deadreckoning.odometer
  - mission.gyro -> deadreckoning.gyro
  - slam.pose -> eval.estimate
  - mission.gps -> eval.truth
  - deadreckoning.pose -> eval.baseline
  - slam.map -> eval.map
"""

GRAPH_SYNTH = """
name: rslam-bench-synthetic
clock: {mode: replay, speed: max}
components:
  mission: {type: bench.SyntheticMission, params: {turns: %(turns)s}}
  slam: {type: slam.RSlam, params: {map_period_s: 1.0e6, range_max_m: 60.0, db_floor_quantile: 0.5,
                                    threads: %(threads)s}}
  deadreckoning: {type: slam.DeadReckoning, params: {period_s: 0.5}}
  eval: {type: eval.TrajectoryEvaluator, params: {report: "%(report)s"}}
connections:
  - mission.image -> slam.image
  - mission.odometer -> deadreckoning.odometer
  - mission.gyro -> deadreckoning.gyro
  - slam.pose -> eval.estimate
  - mission.truth -> eval.truth
  - deadreckoning.pose -> eval.baseline
  - slam.map -> eval.map
"""


class SyntheticMission(Source):
    """impala_slam.synthetic's Beynes-like mission as a source."""

    image = Output(Grid)
    odometer = Output(Speed)
    gyro = Output(YawRate)
    truth = Output(Pose2D)
    turns = Param(int, default=60, ge=2)

    def generate(self):  # type: ignore[no-untyped-def]
        from impala_slam.synthetic import synthetic_mission

        return synthetic_mission(self.turns)


def _timed(comp: Component, acc: dict[str, float], cpu: dict[str, float] | None = None,
           walls: list[float] | None = None) -> None:
    """Accumulate the wall time of ``comp.process`` into ``acc[comp.name]`` (and its thread
    CPU time into ``cpu[comp.name]``: what a loaded machine does not inflate; each call's wall
    time appended to ``walls``)."""
    inner = comp.process

    def process(t: int) -> None:
        t0, c0 = time.perf_counter(), time.thread_time()
        inner(t)
        acc[comp.name] = acc.get(comp.name, 0.0) + time.perf_counter() - t0
        if walls is not None:
            walls.append(time.perf_counter() - t0)
        if cpu is not None:
            cpu[comp.name] = cpu.get(comp.name, 0.0) + time.thread_time() - c0

    comp.process = process  # type: ignore[method-assign]


STAGES = ("amplitude", "prepare", "coarse", "fine", "update")


def _split(core, turns: int) -> dict[str, float]:  # type: ignore[no-untyped-def]
    """R-SLAM's thread CPU per stage (ms per turn): amplitude, prepare, coarse, fine, update."""
    return {f"{k}_cpu_ms_per_turn": 1e3 * core.split.get(k, 0.0) / max(1, turns) for k in STAGES}


def _cpu_ms(split: dict[str, float]) -> float:
    """R-SLAM's CPU per turn, every thread: the sum of its stages."""
    return sum(split[f"{k}_cpu_ms_per_turn"] for k in STAGES)


def _wall_median_ms(walls: list[float]) -> float:
    """Median wall time of R-SLAM's calls (ms), its first turn (no map yet) left out."""
    return 1e3 * float(np.median(walls[1:] or walls)) if walls else float("nan")


def _split_line(split: dict[str, float]) -> str:
    total = sum(split[f"{k}_cpu_ms_per_turn"] for k in STAGES)
    return f"R-SLAM {total:.1f} ms CPU/turn = " + " + ".join(f"{k} {split[f'{k}_cpu_ms_per_turn']:.1f}"
                                                            for k in STAGES)


def peak_rss_mb() -> float:
    """Peak resident set of this process (ru_maxrss is in KiB on Linux)."""
    import resource

    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def run_mission(turns: int, synthetic: bool, report: str, seed: int = -1, threads: int = 2) -> dict:
    from importlib.metadata import entry_points

    from impala_flow.testing import plugin_of

    plugins = {"bench": plugin_of(SyntheticMission)}
    installed = {ep.name for ep in entry_points(group="impala_flow")}
    for name in ("slam", "eval"):  # from the source tree when the plugins are not installed
        if name not in installed:
            plugins[name] = importlib.import_module(f"impala_{name}.plugin")
    session = Session(extra_plugins=plugins)
    if not synthetic and "radar.Simulator" not in session.registry.components:
        synthetic = True
    text = (GRAPH_SYNTH if synthetic else GRAPH_SIM) % {"turns": turns, "duration": float(turns) + 0.5,
                                                        "report": report, "seed": seed, "threads": threads}
    net = session.build(session.load_text(text))
    acc: dict[str, float] = {}
    cpu: dict[str, float] = {}
    walls: list[float] = []
    for c in net.components.values():
        if c.name != "mission":
            _timed(c, acc, cpu, walls if c.name == "slam" else None)
    t0 = time.perf_counter()
    session.run(net, speed="max")
    wall = time.perf_counter() - t0
    slam, ev = net.components["slam"], net.components["eval"]
    n = max(1, slam.turns)
    f = ev.figures
    split = _split(slam.core, n)
    return {
        "source": "synthetic" if synthetic else "radar.Simulator",
        "turns": slam.turns,
        "rslam_threads": threads,
        "rslam_ms_per_turn": 1e3 * acc.get("slam", 0.0) / n,
        "rslam_wall_median_ms_per_turn": _wall_median_ms(walls),
        "rslam_cpu_ms_per_turn": _cpu_ms(split),
        **split,
        "rslam_match_ms_per_turn": 1e3 * slam.core.match_s / n,
        "rslam_update_ms_per_turn": 1e3 * slam.core.update_s / n,
        "chain_ms_per_turn": 1e3 * sum(acc.values()) / n,
        "run_wall_s": wall,
        "match_failures": slam.core.failures,
        "ate_rmse_m": f.get("ate_rmse_m"), "ate_max_m": f.get("ate_max_m"), "drift_pct": f.get("drift_pct"),
        "path_length_m": f.get("path_length_m"),
        "baseline_ate_rmse_m": f.get("baseline_ate_rmse_m"), "baseline_drift_pct": f.get("baseline_drift_pct"),
        "map_mb": round(slam.core.map.nbytes / 2 ** 20, 1) if slam.core.map else 0.0,
        "map_tiles_dropped": slam.core.map.dropped_tiles if slam.core.map else 0,
    }


def _cli(cli: Any, argv: list[str]) -> None:
    """``impala-flow argv``, in this process; a non-zero exit stops the bench with the command named."""
    code = cli(argv)
    if code:
        raise SystemExit(f"bench: impala-flow {' '.join(argv[:2])} exited with {code}")


def run_oxford(report: str) -> dict:
    """The real Oxford scans through the user's path: ``impala-flow import oxford`` then
    ``graphs/oxford.yaml``; the per-pair errors come from the graph's recorded poses (the
    evaluator's metrics.json, which the tests check against the ground-truth file)."""
    sys.path.insert(0, str(ROOT))  # the data lookup lives beside the tests
    from impala_flow.cli import main as cli
    from tests.datasets import find_oxford_sample

    folder = find_oxford_sample()
    if folder is None:
        return {}
    out = Path(report + "-oxford")
    out.mkdir(parents=True, exist_ok=True)
    mission = Path(report + "-oxford-sample.mcap")  # beside the graph's folder: a run refuses an out holding its input
    _cli(cli, ["import", "oxford", str(folder), "-o", str(mission), "--no-progress", "--overwrite"])
    t0 = time.perf_counter()
    _cli(cli, ["run", str(ROOT / "graphs" / "oxford.yaml"), "--var", f"mission={mission}", "--var", f"out={out}",
               "--no-progress", "--summary-json", str(out / "summary.json")])
    wall = time.perf_counter() - t0
    m = json.loads((out / "metrics.json").read_text())
    pairs = m.get("pairs", [])
    for k, p in enumerate(pairs, 1):
        print(f"  oxford pair {k:2d}: {100 * p['trans_err_m']:5.1f} cm {p['rot_err_deg']:6.3f} deg "
              f"(along {100 * p['along_err_m']:+5.1f} cm, lateral {100 * p['lateral_err_m']:+5.1f} cm, "
              f"step {p['true_step_m']:.2f} m)")
    return {"oxford_trans_err_m": m["pair_trans_err_mean_m"], "oxford_rot_err_deg": m["pair_rot_err_mean_deg"],
            "oxford_trans_err_max_m": m["pair_trans_err_max_m"], "oxford_rot_err_max_deg": m["pair_rot_err_max_deg"],
            "oxford_along_err_mean_m": m["pair_along_err_mean_m"],
            "oxford_lateral_err_mean_m": m["pair_lateral_err_mean_m"],
            "oxford_cv_baseline_trans_err_m": m.get("baseline_pair_trans_err_mean_m"),
            "oxford_ms_per_scan": 1e3 * wall / max(1, len(pairs) + 1), "oxford_pairs": len(pairs)}


def run_radiate(report: str) -> dict:
    """The RADIATE fog_6_0 head (6 scans, no truth in the sample) through the same graph:
    the scan-to-scan translation and rotation R-SLAM finds (the car drives straight ahead)."""
    import math

    sys.path.insert(0, str(ROOT))
    from impala_flow.cli import main as cli
    from impala_flow.io import MissionReader
    from tests.datasets import find_radiate_head

    folder = find_radiate_head()
    if folder is None:
        return {}
    out = Path(report + "-radiate")
    out.mkdir(parents=True, exist_ok=True)
    mission = Path(report + "-radiate-fog_6_0-head.mcap")  # beside the graph's folder, as above
    _cli(cli, ["import", "radiate", str(folder), "-o", str(mission), "--no-progress", "--overwrite"])
    _cli(cli, ["run", str(ROOT / "graphs" / "oxford.yaml"), "--var", f"mission={mission}", "--var", f"out={out}",
               "--no-progress"])
    with MissionReader(out / "oxford.mcap") as r:
        poses = [(m.t_ns, m.data) for m in r.messages(["slam/pose"])]
    fwd, lat, rot, speed = [], [], [], []
    for (t0, a), (t1, b) in zip(poses[:-1], poses[1:], strict=True):
        c, s = math.cos(a.theta_rad), math.sin(a.theta_rad)
        dx, dy = b.x_m - a.x_m, b.y_m - a.y_m
        fwd.append(c * dx + s * dy)
        lat.append(-s * dx + c * dy)
        rot.append(math.degrees(b.theta_rad - a.theta_rad))
        speed.append(fwd[-1] / ((t1 - t0) * 1e-9))
    for k in range(len(fwd)):
        print(f"  radiate pair {k + 1}: forward {fwd[k]:.3f} m, lateral {lat[k]:+.3f} m, rotation {rot[k]:+.3f} deg, "
              f"{speed[k]:.2f} m/s")
    return {"radiate_trans_m_mean": float(np.mean(np.hypot(fwd, lat))), "radiate_lateral_m_mean": float(np.mean(lat)),
            "radiate_rot_deg_mean": float(np.mean(rot)), "radiate_speed_mps_mean": float(np.mean(speed)),
            "radiate_pairs": len(fwd)}


def _run_graph(graph: str, mission: str | Path, out: Path, turns: int | None, overrides: tuple[str, ...] = (),
               walls: list[float] | None = None) -> tuple:
    """Build graphs/GRAPH on ``mission`` as ``impala-flow run`` does (first ``turns`` turns at
    4 Hz when given, ``overrides`` as on its command line), time every component but the
    replayer (wall and thread CPU; the wall time of each of slam's calls into ``walls``), run it."""
    out.mkdir(parents=True, exist_ok=True)
    session = Session()
    spec = session.load(ROOT / "graphs" / graph, ([f"mission.end_s={turns / 4.0}"] if turns else []) + list(overrides),
                        variables={"mission": str(mission), "out": str(out)})
    net = session.build(spec)
    acc: dict[str, float] = {}
    cpu: dict[str, float] = {}
    for c in net.components.values():
        if c.name != "mission":
            _timed(c, acc, cpu, walls if c.name == "slam" else None)
    session.run(net, speed="max")
    return net, acc, cpu


def bench_radiate(mission_path: str | Path, turns: int | None = None, out: str | Path | None = None,
                  threads: int | None = None) -> dict:
    """R-SLAM through graphs/oxford.yaml on an imported RADIATE mission (e.g. the first 400 scans
    of the Edinburgh drive) beside kiss-icp through graphs/kiss_icp_navtech.yaml on the same
    scans: R-SLAM's CPU per turn and its split per stage, ATE (rigid alignment, as the graph's
    evaluator reports it), map size; kiss-icp's CPU per scan (slam.KissIcp, and with
    radar.PeakExtractor that feeds it), its ATE; the peak RSS. ``turns``: only the first ones;
    ``threads``: R-SLAM's (default: the graph's). R-SLAM's CPU is the sum of its stages on every
    thread; its median wall time per call is ``rslam_radiate_wall_median_ms_per_turn``."""
    import tempfile

    base = Path(out) if out else Path(tempfile.mkdtemp(prefix="bench-rslam-radiate-"))
    walls: list[float] = []
    net, acc, cpu = _run_graph("oxford.yaml", mission_path, base / "rslam", turns,
                               (f"slam.threads={threads}",) if threads else (), walls)
    slam = net.components["slam"]
    n = max(1, slam.turns)
    split = _split(slam.core, n)
    res: dict = {"rslam_radiate_turns": slam.turns, "rslam_radiate_threads": slam.threads,
                 "rslam_radiate_ms_per_turn": _cpu_ms(split),
                 "rslam_radiate_wall_ms_per_turn": 1e3 * acc.get("slam", 0.0) / n,
                 "rslam_radiate_wall_median_ms_per_turn": _wall_median_ms(walls),
                 **{f"rslam_radiate_{k}": v for k, v in split.items()},
                 "rslam_radiate_ate_m": net.components["eval"].figures.get("ate_rmse_m"),
                 "rslam_radiate_map_mb": slam.core.map.nbytes / 2 ** 20 if slam.core.map else 0.0,
                 "rslam_radiate_map_tiles_dropped": slam.core.map.dropped_tiles if slam.core.map else 0}
    net, acc, cpu = _run_graph("kiss_icp_navtech.yaml", mission_path, base / "kissicp", turns)
    k = max(1, net.components["kissicp"].turns)
    res.update({"kissicp_radiate_ms_per_scan": 1e3 * cpu.get("kissicp", 0.0) / k,
                "kissicp_radiate_with_peaks_ms_per_scan": 1e3 * (cpu.get("kissicp", 0.0) + cpu.get("points", 0.0)) / k,
                "kissicp_radiate_ate_m": net.components["eval"].figures.get("ate_rmse_m"),
                "peak_rss_mb": peak_rss_mb()})
    return res


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--turns", type=int, default=120, help="antenna turns (the full Beynes mission: 662)")
    ap.add_argument("--synthetic", action="store_true", help="point-scatterer world instead of radar.Simulator")
    ap.add_argument("--report", default="out/bench-rslam", help="evaluator report folder")
    ap.add_argument("--no-oxford", action="store_true")
    ap.add_argument("--seed", type=int, default=-1, help="seed of the simulated world and noise (-1: the scenario's)")
    ap.add_argument("--radiate", metavar="MCAP", help="also an imported RADIATE mission through graphs/oxford.yaml, "
                    "beside kiss-icp (graphs/kiss_icp_navtech.yaml) on the same scans")
    ap.add_argument("--radiate-turns", type=int, default=0, help="only the first turns of --radiate (0: all)")
    ap.add_argument("--no-beynes", action="store_true", help="skip the simulated mission")
    ap.add_argument("--threads", type=int, default=2, help="R-SLAM's threads (results bit-identical whatever)")
    args = ap.parse_args()
    out: dict = {}
    if not args.no_beynes:
        out = run_mission(args.turns, args.synthetic, args.report, args.seed, args.threads)
        for k, v in out.items():
            print(f"{k:28s} {v:.3f}" if isinstance(v, float) else f"{k:28s} {v}")
        print(_split_line(out))
        out.update({"rslam_beynes_ms_per_turn": out["rslam_cpu_ms_per_turn"],
                    "rslam_beynes_wall_ms_per_turn": out["rslam_wall_median_ms_per_turn"],
                    "rslam_beynes_ate_m": out["ate_rmse_m"],
                    "rslam_beynes_drift_pct": out["drift_pct"], "rslam_map_mb": out["map_mb"]})
    if args.radiate:
        ra = bench_radiate(args.radiate, args.radiate_turns or None, args.report + "-radiate-drive", args.threads)
        for k, v in ra.items():
            print(f"{k:40s} {v:.3f}" if isinstance(v, float) else f"{k:40s} {v}")
        print(_split_line({k.removeprefix("rslam_radiate_"): v for k, v in ra.items()}))
        out.update(ra)
    if not args.no_oxford:
        ox = run_oxford(args.report)
        for k, v in ox.items():
            print(f"{k:28s} {v:.4f}" if isinstance(v, float) else f"{k:28s} {v}")
        out.update(ox)
        ra = run_radiate(args.report)
        for k, v in ra.items():
            print(f"{k:28s} {v:.4f}" if isinstance(v, float) else f"{k:28s} {v}")
        out.update(ra)
    out["peak_rss_mb"] = peak_rss_mb()
    print(json.dumps({k: (round(v, 4) if isinstance(v, float) else v) for k, v in out.items()}))


if __name__ == "__main__":
    main()
