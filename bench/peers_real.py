"""The chain beside a peer (kiss-icp) on real Navtech drives, one mission at a time (issue 23 item 4).

    python bench/peers_real.py                                 # the RADIATE head and the Oxford sample
    python bench/peers_real.py --missions radiate --kiss-k 6 12 24
    python bench/peers_real.py --radiate out/radiate-head.mcap --out out/bench-peers

Each mission is run through the graphs a user runs, as they are (``impala-flow run GRAPH --var
mission=... --var out=...``): kiss-icp on the strongest returns of each beam
(graphs/kiss_icp_navtech.yaml), R-SLAM (graphs/oxford.yaml), DistortionOdometry
(graphs/odometry_navtech.yaml), FMT + EKF-SLAM and the iSAM2 pose graph
(graphs/fmt_ekf_navtech.yaml). Printed per method: ATE (m, rigid SE(2) alignment, as each graph's
evaluator reports it), ATE in % of the truth's path, and ms per turn from the run summary (each
component's own timing: kiss-icp = radar.PeakExtractor + slam.KissIcp; R-SLAM = matching +
map update; DistortionOdometry = its step; EKF = the odometry's step + FMT + filter, iSAM2 = that +
its solves spread over the turns). A figure of every method over the truth (GPS for RADIATE)
goes to ``OUT/<mission>/trajectories.png`` (each estimate aligned as for its ATE). ``--kiss-k``
runs kiss-icp again with other numbers of points per beam (``--set points.k=K``).

Missions: the RADIATE Edinburgh head (imported here from IMPALA_FLOW_TEST_DATA/radiate-edinburgh-head,
or ``--radiate``: any imported RADIATE mission, e.g. a whole drive)
and the Oxford sample (imported here from IMPALA_FLOW_TEST_DATA/oxford-radar-robotcar-sample: 11
turns, about 20 m, truth from its radar odometry). The last line is one JSON object:
``<mission>_<method>_ate_m``, ``_ate_pct``, ``_ms_per_turn`` (methods kissicp, rslam, odometry,
ekf, isam2) and ``<mission>_kissicp_points_per_turn``, ``<mission>_kissicp_extractor_ms_per_turn`` (radar.PeakExtractor
alone).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "plugins"))
CLI = [sys.executable, "-m", "impala_flow"]
DATA = Path(os.environ.get("IMPALA_FLOW_TEST_DATA", ROOT.parent / "shared" / "data"))
METHODS = {"kissicp": "kiss-icp", "rslam": "R-SLAM", "odometry": "DistortionOdometry", "ekf": "FMT + EKF",
           "isam2": "iSAM2 pose graph"}


def _run(graph: str, mission: Path, out: Path, *extra: str) -> dict:
    """Run ``graphs/GRAPH`` on ``mission`` into ``out``; the run summary (--summary-json)."""
    out.mkdir(parents=True, exist_ok=True)
    summary = out / "run-summary.json"
    cmd = CLI + ["run", str(ROOT / "graphs" / graph), "--var", f"mission={mission}", "--var", f"out={out}",
                 "--no-progress", "--summary-json", str(summary), *extra]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise SystemExit(f"{graph} on {mission} failed (exit {res.returncode}): {res.stderr.strip()[-400:]}")
    return json.loads(summary.read_text())


def _poses(path: Path, topic: str, last_trajectory: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(t_ns, xyt) of the Pose2D stream ``topic`` of a recording, or of the last Trajectory2D."""
    from impala_flow.io import MissionReader

    t, xyt = [], []
    with MissionReader(path) as r:
        for m in r.messages([topic]):
            if last_trajectory:
                t, xyt = list(m.data.t_ns), list(m.data.xyt)
            else:
                t.append(m.t_ns)
                xyt.append((m.data.x_m, m.data.y_m, m.data.theta_rad))
    return np.asarray(t, np.int64), np.asarray(xyt, float).reshape(-1, 3)


def _ms(extra: dict, comp: str, *keys: str) -> float:
    return float(sum(extra.get(comp, {}).get(k, 0.0) or 0.0 for k in keys))


def run_mission(name: str, mission: Path, out: Path, kiss_k: list[int]) -> dict:
    """Every method on one mission: {method: {ate_m, ate_pct, ms_per_turn, t_ns, xyt}}, the truth."""
    res: dict[str, dict] = {}

    def metrics(folder: Path, prefix: str = "") -> tuple[float, float]:
        m = json.loads((folder / "metrics.json").read_text())
        ate = m[f"{prefix}ate_rmse_m"]
        pct = m.get(f"{prefix}ate_pct") if prefix else 100.0 * ate / m["path_length_m"]
        return ate, pct

    d = out / "kissicp"
    s = _run("kiss_icp_navtech.yaml", mission, d)["extra"]
    ate, pct = metrics(d)
    res["kissicp"] = {"ate_m": ate, "ate_pct": pct,
                      "ms_per_turn": _ms(s, "points", "ms_per_turn") + _ms(s, "kissicp", "ms_per_turn"),
                      "points_per_turn": s.get("kissicp", {}).get("points_per_turn"),
                      "extractor_ms_per_turn": _ms(s, "points", "ms_per_turn"),
                      "poses": _poses(d / "kiss_icp_navtech.mcap", "kissicp/pose")}
    for k in kiss_k:
        dk = out / f"kissicp-k{k}"
        sk = _run("kiss_icp_navtech.yaml", mission, dk, "--set", f"points.k={k}")["extra"]
        a, p = metrics(dk)
        res[f"kissicp_k{k}"] = {"ate_m": a, "ate_pct": p, "ms_per_turn": _ms(sk, "points", "ms_per_turn")
                                + _ms(sk, "kissicp", "ms_per_turn"),
                                "points_per_turn": sk.get("kissicp", {}).get("points_per_turn"),
                                "extractor_ms_per_turn": _ms(sk, "points", "ms_per_turn")}
    d = out / "rslam"
    s = _run("oxford.yaml", mission, d)["extra"]
    ate, pct = metrics(d)
    res["rslam"] = {"ate_m": ate, "ate_pct": pct, "ms_per_turn": _ms(s, "slam", "match_ms_per_turn",
                                                                      "update_ms_per_turn"),
                    "poses": _poses(d / "oxford.mcap", "slam/pose")}
    d = out / "odometry"
    s = _run("odometry_navtech.yaml", mission, d)["extra"]
    ate, pct = metrics(d)
    res["odometry"] = {"ate_m": ate, "ate_pct": pct, "ms_per_turn": _ms(s, "odometry", "odo_ms_per_turn"),
                       "poses": _poses(d / "odometry_navtech.mcap", "odometry/pose")}
    d = out / "fmt_ekf"
    s = _run("fmt_ekf_navtech.yaml", mission, d)["extra"]
    ekf_ms = _ms(s, "odometry", "odo_ms_per_turn") + _ms(s, "ekf", "fmt_ms_per_turn", "filter_ms_per_turn")
    turns = max(1, s.get("ekf", {}).get("turns", 1))
    rec = d / "fmt_ekf_navtech.mcap"
    for key, topic in (("ekf", "ekf/trajectory"), ("isam2", "posegraph/trajectory")):
        ate, pct = metrics(d, f"{key}_")
        ms = ekf_ms + (_ms(s, "posegraph", "solve_ms") / turns if key == "isam2" else 0.0)
        res[key] = {"ate_m": ate, "ate_pct": pct, "ms_per_turn": ms, "poses": _poses(rec, topic, True)}
    res["_truth"] = {"poses": _poses(mission, "truth/pose")}
    return res


def figure(name: str, res: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    from impala_eval.metrics import trajectory_metrics

    tt, truth = res["_truth"]["poses"]
    fig = Figure(figsize=(7.5, 6.5), dpi=120, layout="constrained")
    ax = fig.add_subplot()
    ax.plot(truth[:, 0], truth[:, 1], "k-", lw=3, alpha=0.35, label="truth (GPS)" if name == "radiate" else "truth")
    for key, title in METHODS.items():
        t, xyt = res[key]["poses"]
        if len(t) < 2:
            continue
        try:
            m = trajectory_metrics(t, xyt, tt, truth, align="rigid")
        except ValueError:
            continue
        a = m.est_aligned_xyt
        ax.plot(a[:, 0], a[:, 1], "-", lw=1.2, label=f"{title}: ATE {res[key]['ate_m']:.2f} m "
                                                    f"({res[key]['ate_pct']:.2f} %)")
    ax.set(xlabel="x (m)", ylabel="y (m)", title=f"{name}: every method over the truth (rigid SE(2) alignment)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(frameon=False, fontsize=8)
    fig.savefig(path)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--missions", nargs="+", default=["radiate", "oxford"], choices=["radiate", "oxford"])
    ap.add_argument("--radiate", default="", help="an imported RADIATE mission (default: the Edinburgh head "
                    "imported from IMPALA_FLOW_TEST_DATA into OUT/radiate)")
    ap.add_argument("--out", default=str(ROOT / "out" / "bench-peers"))
    ap.add_argument("--kiss-k", type=int, nargs="*", default=[], help="kiss-icp again with these points per beam")
    args = ap.parse_args()
    out = Path(args.out).resolve()
    result: dict[str, float | int | None] = {}
    for name in args.missions:
        folder = out / name
        folder.mkdir(parents=True, exist_ok=True)
        if name == "radiate":
            mission = Path(args.radiate) if args.radiate else folder / "radiate-head.mcap"
            if not args.radiate:  # imported afresh: the reader's truth (GPS offset, headings) as it is now
                src = DATA / "radiate-edinburgh-head"
                if not src.is_dir():
                    print(f"radiate: no {src}: skipped")
                    continue
                subprocess.run(CLI + ["import", "radiate", str(src), "-o", str(mission), "--no-progress",
                                      "--overwrite"],
                               check=True, capture_output=True)
        else:
            src = DATA / "oxford-radar-robotcar-sample"
            if not src.is_dir():
                print(f"oxford: no {src}: skipped")
                continue
            mission = folder / "oxford-sample.mcap"
            subprocess.run(CLI + ["import", "oxford", str(src), "-o", str(mission), "--no-progress", "--overwrite"],
                           check=True, capture_output=True)
        res = run_mission(name, mission.resolve(), folder, args.kiss_k)
        print(f"{name} ({mission}):")
        print(f"  {'method':24s} {'ATE (m)':>8s} {'% of path':>10s} {'ms per turn':>12s}")
        for key in list(METHODS) + [k for k in res if k.startswith("kissicp_k")]:
            r = res[key]
            title = METHODS.get(key, f"kiss-icp, k = {key.split('_k')[-1]}")
            pts = (f"  ({r['points_per_turn']} points per turn; extractor {r['extractor_ms_per_turn']:.1f} ms)"
                   if r.get("points_per_turn") is not None else "")
            print(f"  {title:24s} {r['ate_m']:8.2f} {r['ate_pct']:10.2f} {r['ms_per_turn']:12.1f}{pts}")
            result[f"{name}_{key}_ate_m"] = round(r["ate_m"], 3)
            result[f"{name}_{key}_ate_pct"] = round(r["ate_pct"], 3)
            result[f"{name}_{key}_ms_per_turn"] = round(r["ms_per_turn"], 1)
            if r.get("points_per_turn") is not None:
                result[f"{name}_{key}_points_per_turn"] = r["points_per_turn"]
                result[f"{name}_{key}_extractor_ms_per_turn"] = round(r["extractor_ms_per_turn"], 1)
        figure(name, res, folder / "trajectories.png")
        print(f"  figure: {folder / 'trajectories.png'}")
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
