"""Radar front-end benchmark: ms per turn of each plugin on the Beynes scenario, one core.

    python bench/frontend.py [--turns 6] [--start-s 20] [--repeat 3]

A few turns of the Beynes mission (IMPALA preset, vehicle at cruise speed after
``--start-s``) are simulated once; then each front-end stage runs on every turn through
the same code path as its component (the component's per-turn work: FuzzyPairer =
xcorr Doppler prior + CFAR + features + fuzzy scoring + assignment + eq. 3; EgoVelocity =
robust fit; PanoramicBuilder = dead reckoning + Doppler compensation + polar -> 0.2 m grid;
SpeckleFilter = 4-look co-registration + average). Figures are the median over turns of the
best of ``--repeat`` runs, and the ratio of the turn period (1 s) to that time ("x real
time"). Targets: pairer <= 50 ms, panoramic builder <= 30 ms, speckle filter <= 20 ms.
The last line is one JSON object.
"""

from __future__ import annotations

import os

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import argparse  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from impala_flow.msgs import Grid, Pose2D  # noqa: E402
from impala_radar.ego_velocity.core import fit_ego_velocity  # noqa: E402
from impala_radar.pairer.component import detections_of_pairs  # noqa: E402
from impala_radar.pairer.core import pair_turn, xcorr_speed_prior  # noqa: E402
from impala_radar.panoramic.core import (  # noqa: E402
    doppler_compensated_power,
    integrate_poses,
    relative_to,
    scan_to_grid,
)
from impala_radar.simulator.scenario import load_scenario  # noqa: E402
from impala_radar.speckle.core import multilook  # noqa: E402


def _turns(n_turns: int, start_s: float):
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
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best * 1e3


def _bench_turn(turn, odo, gyro, pose, looks, repeat):
    """Time each stage on one turn; returns (ms by stage, outputs)."""
    t_ns = np.array([t for t, _ in turn], np.int64)
    beams = [b for _, b in turn]
    config = beams[0].config
    az = np.array([b.azimuth_rad for b in beams])
    up = np.stack([b.up for b in beams])
    down = np.stack([b.down for b in beams])
    out: dict = {"odometer_mps": float(np.interp(t_ns[-1], odo[:, 0], odo[:, 1]))}

    def pairer() -> None:
        v = xcorr_speed_prior(up, down, az, config)
        out["det"] = detections_of_pairs(pair_turn(up, down, az, config, v), beams[0].turn, t_ns, az, config)

    def ego() -> None:
        out["fit"] = fit_ego_velocity(out["det"].azimuth_rad, out["det"].radial_speed_mps)

    def panoramic() -> None:
        v = np.interp(t_ns, odo[:, 0], odo[:, 1])
        w = np.interp(t_ns, gyro[:, 0], gyro[:, 1])
        od = integrate_poses(t_ns, v, w, pose)
        power = doppler_compensated_power(up, down, az, float(v.mean()), config)
        grid, o = scan_to_grid(power, az, relative_to(od, od[-1]), config.range_per_bin_m, 0.2,
                               config.range_max_m)
        out["grid"] = Grid(grid, 0.2, o[0], o[1], "vehicle", Pose2D(*od[-1], frame="odom"))

    def speckle() -> None:
        multilook(looks + [out["grid"]])

    times = {"pairer": _best(pairer, repeat), "ego_velocity": _best(ego, repeat),
             "panoramic_builder": _best(panoramic, repeat), "speckle_filter": _best(speckle, repeat)}
    return times, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--turns", type=int, default=6)
    ap.add_argument("--start-s", type=float, default=20.0)
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    cv2.setNumThreads(1)
    t0 = time.perf_counter()
    turns, odo, gyro = _turns(a.turns, a.start_s)
    print(f"simulated {len(turns)} Beynes turns in {time.perf_counter() - t0:.1f} s")
    ms: dict[str, list[float]] = {"pairer": [], "ego_velocity": [], "panoramic_builder": [], "speckle_filter": []}
    looks: list[Grid] = []
    pose = (0.0, 0.0, 0.0)
    n_det, speeds = [], []
    for turn in turns:
        times, out = _bench_turn(turn, odo, gyro, pose, looks, a.repeat)
        for k, v in times.items():
            ms[k].append(v)
        g = out["grid"]
        pose = (g.pose.x_m, g.pose.y_m, g.pose.theta_rad)
        looks = (looks + [g])[-4:]
        n_det.append(len(out["det"].range_m))
        speeds.append((out["fit"].speed_mps, out["odometer_mps"]))
    med = {k: statistics.median(v) for k, v in ms.items()}
    period_ms = 1e3 / turns[0][0][1].config.rotation_hz
    for k, v in med.items():
        print(f"{k:18s} {v:7.1f} ms/turn   x{period_ms / v:6.1f} real time")
    err = [abs(e - o) for e, o in speeds]
    print(f"detections per turn: {statistics.median(n_det):.0f}; |Doppler speed - odometer| median "
          f"{statistics.median(err):.3f} m/s (odometer speed {statistics.median(o for _, o in speeds):.2f} m/s)")
    result = {f"{k}_ms_per_turn": round(v, 2) for k, v in med.items()}
    result.update({f"{k}_x_real_time": round(period_ms / v, 1) for k, v in med.items()})
    result.update({"turns": len(turns), "detections_per_turn": statistics.median(n_det),
                   "doppler_speed_error_mps": round(statistics.median(err), 3)})
    print(json.dumps(result))


if __name__ == "__main__":
    main()
