"""Benchmark of radar-only odometry from scan distortion (RADAR.md item 8, seed 1 §4.2).

    python bench/odometry.py                    # semi-urban seeds 11 12, the Oxford sample
    python bench/odometry.py --seeds 31 --duration 120s

Each semi-urban mission (2.5 km at ~30 km/h through roundabouts; ``impala-flow simulate``) is
replayed through graphs/odometry.yaml: slam.DistortionOdometry from the beams alone, dead
reckoning from the odometer and gyro beside it, eval.TrajectoryEvaluator against the RTK-GPS.
Printed per seed: speed and yaw-rate errors (mean, std; truth over 1 s windows centred on
each estimate), final x / y / rotation errors (first pose aligned), ATE after rigid alignment,
relative error over 100-800 m segments, the dead reckoning's ATE, and ms per turn of the
odometry on one core (CPU time of its own ``step``, split into echoes / estimate / search, the map
excluded and printed apart; and the first registration's, a search of the whole speed and
yaw-rate range). Then the
imported Oxford sample through graphs/odometry_navtech.yaml, with and without the
range-Doppler compensation; then the RADIATE Edinburgh head (real, 400 turns, GPS truth: ATE of
positions after a rigid fit, whole head, first and last 200 turns). The parameters were tuned on
semi-urban seeds 5 and 7: the default seeds here were never used for tuning. The last line is one JSON object with the
issue's keys (semi-urban figures: mean over seeds). Seed figures (IMPALA, 2012): speed error
0.29 +- 1.3 m/s, yaw rate 0.06 deg/s, final 0.59 m / 0.35 m / 0.036 rad, ~100 ms per turn.
Goals: |speed mean| <= 0.1 m/s, std <= 0.3 m/s, relative error <= 2 %, <= 20 ms per turn.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
CLI = [sys.executable, "-m", "impala_flow"]
KEYS = ("speed_err_mean_mps", "speed_err_std_mps", "yaw_rate_err_mean_dps", "yaw_rate_err_std_dps",
        "final_error_x_m", "final_error_y_m", "final_rot_err_rad", "ate_rmse_m", "rel_err_pct",
        "baseline_ate_rmse_m", "path_length_m")


def _run(graph: str, mission: Path, out: Path, *extra: str) -> tuple[dict, dict]:
    cmd = CLI + ["run", str(ROOT / "graphs" / graph), "--var", f"mission={mission}", "--var", f"out={out}",
                 "--no-progress", "--summary-json", str(out.with_suffix(".summary.json")), *extra]
    subprocess.run(cmd, check=True, capture_output=True)
    metrics = json.loads((out / "metrics.json").read_text())
    summary = json.loads(out.with_suffix(".summary.json").read_text())
    return metrics, summary["extra"].get("odometry", {})


def _ate(est: np.ndarray, gps: np.ndarray) -> float:
    """RMS position error after the rigid fit (Kabsch) of ``est`` onto ``gps``, both (n, 2)."""
    p, q = est - est.mean(axis=0), gps - gps.mean(axis=0)
    u, _, vt = np.linalg.svd(p.T @ q)
    rot = (u @ np.diag([1.0, np.sign(np.linalg.det(u @ vt))]) @ vt).T
    return float(np.sqrt(np.mean(np.sum((p @ rot.T - q) ** 2, axis=1))))


def _radiate(mission: Path, recording: Path) -> dict:
    """Positions only (the imported heading is the IMU's): ATE against the GPS at the estimate's
    times, whole head, first and last 200 turns; and the shift of the truth's times that fits
    best (a diagnostic of the GPS log's latency, not a score)."""
    from impala_flow.io import MissionReader

    with MissionReader(mission) as r:
        truth = np.array([(m.t_ns, m.data.x_m, m.data.y_m) for m in r.messages(["truth/pose"])], float)
    with MissionReader(recording) as r:
        est = np.array([(m.t_ns, m.data.x_m, m.data.y_m) for m in r.messages(["odometry/pose"])], float)
    t0 = truth[0, 0]
    tt, te = (truth[:, 0] - t0) * 1e-9, (est[:, 0] - t0) * 1e-9

    def score(sel: np.ndarray, shift_s: float = 0.0) -> tuple[float, float]:
        sel = sel & (te + shift_s >= tt[0]) & (te + shift_s <= tt[-1])
        g = np.column_stack([np.interp(te[sel] + shift_s, tt, truth[:, 1]),
                             np.interp(te[sel] + shift_s, tt, truth[:, 2])])
        return _ate(est[sel, 1:], g), float(np.sum(np.hypot(*np.diff(g, axis=0).T)))

    every = np.ones(len(te), bool)
    ate, path = score(every)
    first, first_path = score(np.arange(len(te)) < 200)
    last, last_path = score(np.arange(len(te)) >= len(te) - 200)
    shifts = np.arange(0.0, 3.01, 0.1)
    shifted = [score(every, s)[0] for s in shifts]
    est_path = float(np.sum(np.hypot(*np.diff(est[:, 1:], axis=0).T)))
    return {"ate_m": ate, "path_m": path, "ate_pct": round(100 * ate / path, 3), "first_ate_m": first,
            "first_path_m": first_path, "last_ate_m": last, "last_path_m": last_path,
            "last_pct": 100 * last / last_path, "path_ratio": est_path / path,
            "best_shift_s": float(shifts[int(np.argmin(shifted))]), "shifted_ate_m": float(min(shifted))}


def _split(odo: dict) -> str:
    """The per-stage split of the odometry's CPU time per turn, as the component counts it."""
    return (f"{odo.get('odo_ms_per_turn')} ms per turn = echoes {odo.get('echoes_ms_per_turn')} + estimate "
            f"{odo.get('estimate_ms_per_turn')} + search {odo.get('search_ms_per_turn')} + filter/clock/rest "
            f"(+ map {odo.get('map_ms_per_turn')} ms); first registration {odo.get('first_registration_ms')} ms")


def bench_radiate(mission_path: str | Path, turns: int | None = None) -> dict:
    """An imported RADIATE mission (``impala-flow import radiate``) through graphs/odometry_navtech.yaml
    as a user runs it, its map included (printed apart): CPU ms per turn of the odometry and its split,
    ATE against the GPS (metrics of eval.TrajectoryEvaluator), peak RSS of the run. ``turns``: only the
    first ones (the replayer's end_s at 4 Hz)."""
    import resource

    extra = ("--set", f"mission.end_s={turns / 4.0:.3f}") if turns else ()
    with tempfile.TemporaryDirectory() as tmp:
        m, odo = _run("odometry_navtech.yaml", Path(mission_path), Path(tmp) / "out-radiate", *extra)
    return {"odometry_radiate_ms_per_turn": odo.get("odo_ms_per_turn"),
            "odometry_radiate_map_ms_per_turn": odo.get("map_ms_per_turn"),
            "odometry_radiate_echoes_ms_per_turn": odo.get("echoes_ms_per_turn"),
            "odometry_radiate_estimate_ms_per_turn": odo.get("estimate_ms_per_turn"),
            "odometry_radiate_search_ms_per_turn": odo.get("search_ms_per_turn"),
            "odometry_radiate_first_registration_ms": odo.get("first_registration_ms"),
            "odometry_radiate_ate_m": m.get("ate_rmse_m"), "odometry_radiate_turns": odo.get("turns"),
            "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024, 1)}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=[11, 12])
    ap.add_argument("--duration", default="", help="mission length (default: the whole scenario)")
    ap.add_argument("--oxford", default=str(ROOT.parent / "shared" / "data" / "oxford-radar-robotcar-sample"))
    ap.add_argument("--radiate", default=str(ROOT.parent / "shared" / "data" / "radiate-edinburgh-head"))
    ap.add_argument("--radiate-mission", default=str(ROOT.parent / "out" / "lead" / "radiate-head.mcap"),
                    help="an imported RADIATE mission for bench_radiate (skipped when absent)")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for seed in args.seeds:
            mission = tmp / f"semi-urban-{seed}.mcap"
            sim = CLI + ["simulate", "semi-urban", "-o", str(mission), "--seed", str(seed), "--no-progress"]
            subprocess.run(sim + (["--duration", args.duration] if args.duration else []), check=True,
                           capture_output=True)
            m, odo = _run("odometry.yaml", mission, tmp / f"out-{seed}")
            row = {k: m.get(k) for k in KEYS} | {"odo_ms_per_turn": odo.get("odo_ms_per_turn"),
                                                 "first_registration_ms": odo.get("first_registration_ms"),
                                                 "map_ms_per_turn": odo.get("map_ms_per_turn"),
                                                 "degraded_turns": odo.get("degraded_turns"),
                                                 "wide_searches": odo.get("wide_searches")}
            rows.append(row)
            print(f"semi-urban seed {seed}: {row['path_length_m']:.0f} m")
            print(f"  speed error   {row['speed_err_mean_mps']:+.3f} +- {row['speed_err_std_mps']:.3f} m/s "
                  f"(seed 0.29 +- 1.3)")
            print(f"  yaw-rate error {row['yaw_rate_err_mean_dps']:+.3f} +- {row['yaw_rate_err_std_dps']:.3f} deg/s "
                  f"(seed 0.06)")
            print(f"  final error   x {row['final_error_x_m']:.2f} m, y {row['final_error_y_m']:.2f} m, "
                  f"rotation {row['final_rot_err_rad']:.3f} rad (seed 0.59 / 0.35 / 0.036)")
            print(f"  ATE {row['ate_rmse_m']:.2f} m, relative error {row['rel_err_pct']:.2f} % over 100-800 m, "
                  f"odometer + gyro ATE {row['baseline_ate_rmse_m']:.2f} m")
            print(f"  {_split(odo)}, degraded turns {row['degraded_turns']}, wide searches {row['wide_searches']}")
        ox = {}
        if (Path(args.oxford) / "radar").is_dir():
            mission = tmp / "oxford.mcap"
            subprocess.run(CLI + ["import", "oxford", args.oxford, "-o", str(mission), "--no-progress"], check=True,
                           capture_output=True)
            for tag, extra in (("", ()), ("_no_doppler", ("--set", "odometry.doppler=false"))):
                m, odo = _run("odometry_navtech.yaml", mission, tmp / f"out-oxford{tag}", *extra)
                ox[tag] = m
                print(f"Oxford sample{' without Doppler compensation' if tag else ''}: per pair "
                      f"{100 * m['pair_trans_err_mean_m']:.1f} cm / {m['pair_rot_err_mean_deg']:.3f} deg "
                      f"(max {100 * m['pair_trans_err_max_m']:.1f} cm / {m['pair_rot_err_max_deg']:.3f} deg); speed "
                      f"{m['speed_err_mean_mps']:+.3f} +- {m['speed_err_std_mps']:.3f} m/s, yaw rate "
                      f"{m['yaw_rate_err_mean_dps']:+.3f} +- {m['yaw_rate_err_std_dps']:.3f} deg/s; "
                      f"{odo.get('odo_ms_per_turn')} ms per turn")
        else:
            print(f"Oxford sample not found at {args.oxford}: skipped")
        rad = {}
        if (Path(args.radiate) / "Navtech_Polar").is_dir():
            mission = tmp / "radiate.mcap"
            subprocess.run(CLI + ["import", "radiate", args.radiate, "-o", str(mission), "--no-progress"], check=True,
                           capture_output=True)
            _, odo = _run("odometry_navtech.yaml", mission, tmp / "out-radiate", "--set", "odometry.map_cell_m=0")
            rad = _radiate(mission, tmp / "out-radiate" / "odometry_navtech.mcap")
            print(f"RADIATE head ({rad['path_m']:.0f} m of GPS path): ATE {rad['ate_m']:.2f} m "
                  f"({rad['ate_pct']:.2f} %); first 200 turns {rad['first_ate_m']:.2f} m of "
                  f"{rad['first_path_m']:.1f} m, last 200 {rad['last_ate_m']:.2f} m ({rad['last_pct']:.2f} % of "
                  f"{rad['last_path_m']:.0f} m); path {rad['path_ratio']:.3f} x the GPS's; truth later by "
                  f"{rad['best_shift_s']:.2f} s fits best (ATE {rad['shifted_ate_m']:.2f} m); "
                  f"{odo.get('filter_resets')} filter resets, {odo.get('late_stamps')} late stamps in "
                  f"{odo.get('turns')} turns; {_split(odo)}")
            lead = Path(args.radiate_mission)
            if lead.is_file():
                rad |= bench_radiate(lead)
                print(f"RADIATE head {lead} through graphs/odometry_navtech.yaml (map on): ATE "
                      f"{rad['odometry_radiate_ate_m']} m; {rad['odometry_radiate_ms_per_turn']} ms per turn = echoes "
                      f"{rad['odometry_radiate_echoes_ms_per_turn']} + estimate "
                      f"{rad['odometry_radiate_estimate_ms_per_turn']} + search "
                      f"{rad['odometry_radiate_search_ms_per_turn']} (+ map "
                      f"{rad['odometry_radiate_map_ms_per_turn']} ms); first registration "
                      f"{rad['odometry_radiate_first_registration_ms']} ms")
        else:
            print(f"RADIATE head not found at {args.radiate}: skipped")

    def mean(k):
        vals = [r[k] for r in rows if r.get(k) is not None]
        return round(sum(vals) / len(vals), 4) if vals else None

    out = {k: mean(k) for k in ("odo_ms_per_turn", "first_registration_ms", "speed_err_mean_mps", "speed_err_std_mps",
                                 "yaw_rate_err_mean_dps", "rel_err_pct", "ate_rmse_m")}
    o = ox.get("")
    out["oxford_speed_err_mps"] = round(abs(o["speed_err_mean_mps"]), 4) if o else None
    out["oxford_pair_trans_err_m"] = round(o["pair_trans_err_mean_m"], 4) if o else None
    out["oxford_pair_rot_err_deg"] = round(o["pair_rot_err_mean_deg"], 4) if o else None
    out["radiate_ate_pct"] = rad.get("ate_pct")
    out["odometry_semiurban_ms_per_turn"] = out["odo_ms_per_turn"]
    for k in ("odometry_radiate_ms_per_turn", "odometry_radiate_map_ms_per_turn", "odometry_radiate_ate_m"):
        out[k] = rad.get(k)
    import resource

    print(f"peak RSS {resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024:.0f} MB (largest run)")
    out["peak_rss_mb"] = round(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024, 1)
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
