"""The gap between the simulator and real scans, measured in one run (RADAR.md, issue 10).

    python bench/sim2real.py                       # writes out/sim2real/ (missions, reports, figure)

The same graph (graphs/oxford.yaml) runs on the real Oxford Radar RobotCar sample (11 scans,
imported with ``impala-flow import oxford``) and on a simulated ``urban`` mission of as many
scans at a similar speed (the Navtech CTS350-X preset, truth from its RTK-GPS). For both it
prints the mean per-pair registration error against the truth, the amplitude statistics of
the scans in dB above their noise floor (mean, 5/50/95 % percentiles, fraction of cells 10 dB
above the floor), the correlation between consecutive polar scans, and the fraction of the
beams' energy within 10 m; then the ratios, a PNG of a real and a simulated scan side by side
(polar and Cartesian), and one JSON line. Goal: the simulated registration error within a
factor 2 of the real one, both ways.

Definitions (the same code for both): the floor of a scan is the median power of its cells
between 2 m and 60 m (most cells hold no echo); statistics over those cells; correlation =
Pearson's r of the dB images of consecutive turns, row by row in acquisition order.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import cv2  # noqa: E402
import numpy as np  # noqa: E402

from impala_flow.cli import main as cli  # noqa: E402
from impala_flow.io import MissionReader  # noqa: E402

cv2.setNumThreads(1)
RANGE_M = (2.0, 60.0)


def turns_of(mission: Path, start_ns: int | None = None, n: int | None = None) -> list[dict]:
    """The mission's turns: time-ordered beams stacked (power, azimuth, times, config)."""
    by_turn: dict[int, list] = {}
    with MissionReader(mission) as r:
        for m in r.messages(["radar/beams"]):
            if start_ns is None or m.t_ns >= start_ns:
                by_turn.setdefault(m.data.turn, []).append((m.t_ns, m.data))
    out = []
    for k in sorted(by_turn):
        beams = by_turn[k]
        cfg = beams[0][1].config
        if len(beams) < cfg.beams_per_turn:  # partial turns (the window's edges) left out
            continue
        out.append({"power": np.stack([b.up for _, b in beams]).astype(np.float64),
                    "azimuth": np.array([b.azimuth_rad for _, b in beams]),
                    "t_ns": np.array([t for t, _ in beams], np.int64), "config": cfg})
    return out[:n] if n else out


def scan_statistics(turns: list[dict]) -> dict[str, float]:
    """Amplitude statistics, consecutive-scan correlation, energy within 10 m (module doc)."""
    db_all, above, near, corr = [], [], [], []
    prev = None
    for turn in turns:
        cfg, p = turn["config"], turn["power"]
        r = np.asarray(cfg.range_of_bin_m(np.arange(p.shape[1])))
        band = (r >= RANGE_M[0]) & (r <= RANGE_M[1])
        floor = float(np.median(p[:, band]))
        db = 10.0 * np.log10(np.maximum(p[:, band], 1e-30) / floor)
        db_all.append(db.ravel())
        above.append(float(np.mean(db > 10.0)))
        inside = r <= cfg.range_max_m
        near.append(float(p[:, (r <= 10.0) & inside].sum() / p[:, inside].sum()))
        if prev is not None and prev.shape == db.shape:
            corr.append(float(np.corrcoef(prev.ravel(), db.ravel())[0, 1]))
        prev = db
    d = np.concatenate(db_all)
    p5, p50, p95 = np.percentile(d, [5, 50, 95])
    return {"mean_db": float(d.mean()), "p5_db": float(p5), "p50_db": float(p50), "p95_db": float(p95),
            "frac_above_10db": float(np.mean(above)), "scan_corr": float(np.mean(corr)) if corr else float("nan"),
            "energy_within_10m": float(np.mean(near))}


def run_graph(mission: Path, out: Path, *extra: str) -> dict:
    t0 = time.perf_counter()
    code = cli(["run", str(ROOT / "graphs" / "oxford.yaml"), "--var", f"mission={mission}", "--var", f"out={out}",
                "--no-progress", *extra])
    if code != 0:
        raise SystemExit(f"graphs/oxford.yaml failed on {mission} (exit {code})")
    m = json.loads((out / "metrics.json").read_text())
    m["wall_s"] = time.perf_counter() - t0
    return m


def figure(real: dict, sim: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    fig = Figure(figsize=(12, 10), dpi=100, layout="constrained")
    axes = fig.subplots(2, 2)
    for col, (name, turn) in enumerate((("real (Oxford Radar RobotCar)", real), ("simulated (urban)", sim))):
        cfg, p = turn["config"], turn["power"]
        r = np.asarray(cfg.range_of_bin_m(np.arange(p.shape[1])))
        keep = r <= RANGE_M[1]
        floor = float(np.median(p[:, keep & (r >= RANGE_M[0])]))
        db = 10.0 * np.log10(np.maximum(p[:, keep], 1e-30) / floor)
        order = np.argsort(np.mod(turn["azimuth"], 2 * np.pi))
        az_deg = np.degrees(np.mod(turn["azimuth"][order], 2 * np.pi))
        ax = axes[0, col]
        im = ax.imshow(db[order], aspect="auto", origin="lower", cmap="magma", vmin=-5, vmax=35,
                       extent=[r[keep][0], r[keep][-1], az_deg[0], az_deg[-1]])
        ax.set(title=f"{name}: polar", xlabel="range (m)", ylabel="azimuth, CCW from forward (deg)")
        fig.colorbar(im, ax=ax, label="dB above the scan's floor")
        # Cartesian, vehicle frame (x forward up, y left), nearest beam and bin
        half, cell = 60.0, 0.15
        xs = np.arange(-half, half, cell) + cell / 2
        x, y = np.meshgrid(xs, xs)
        rho, bearing = np.hypot(x, y), np.mod(np.arctan2(y, x), 2 * np.pi)
        row = np.interp(bearing, np.mod(turn["azimuth"][order], 2 * np.pi), np.arange(len(order)))
        col_bins = np.clip(np.rint(np.asarray(cfg.bin_of_range(rho))).astype(int), 0, db.shape[1] - 1)
        img = db[order][np.rint(row).astype(int) % len(order), col_bins]
        img[rho > half] = np.nan
        ax = axes[1, col]
        im = ax.imshow(img, origin="lower", cmap="magma", vmin=-5, vmax=35, extent=[-half, half, -half, half])
        ax.set(title=f"{name}: Cartesian (vehicle frame, 60 m)", xlabel="x forward (m)", ylabel="y left (m)")
        fig.colorbar(im, ax=ax, label="dB above the scan's floor")
    fig.suptitle("Real and simulated Navtech scans, same processing")
    fig.savefig(path)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default="out/sim2real", help="output folder")
    ap.add_argument("--seed", type=int, default=2019, help="seed of the simulated urban mission")
    ap.add_argument("--scenario", default="urban", help="scenario name or file simulated (calibration runs)")
    ap.add_argument("--start-s", type=float, default=10.0, help="where the simulated window starts (s): at speed")
    args = ap.parse_args()
    from tests.datasets import find_oxford_sample

    folder = find_oxford_sample()
    if folder is None:
        raise SystemExit("the Oxford sample was not found (set IMPALA_FLOW_TEST_DATA)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    real_mission, sim_mission = out / "oxford-sample.mcap", out / "urban.mcap"
    cli(["import", "oxford", str(folder), "-o", str(real_mission), "--no-progress", "--overwrite"])
    n_scans = len(turns_of(real_mission))
    window_s = n_scans / 4.0 + 0.3
    t0 = time.perf_counter()
    cli(["simulate", args.scenario, "-o", str(sim_mission), "--duration", f"{args.start_s + window_s + 0.2:.2f}s",
         "--seed", str(args.seed), "--no-progress", "--overwrite"])
    sim_wall = time.perf_counter() - t0
    real = run_graph(real_mission, out / "real")
    sim = run_graph(sim_mission, out / "sim", "--var", "truth=gps/pose", "--set", f"mission.start_s={args.start_s}",
                    "--set", f"mission.end_s={args.start_s + window_s:.2f}")
    with MissionReader(sim_mission) as r:
        first = next(iter(r.messages(["radar/beams"]))).t_ns
    real_turns = turns_of(real_mission)
    sim_turns = turns_of(sim_mission, first + int(args.start_s * 1e9), n_scans)
    stats = {"real": scan_statistics(real_turns), "sim": scan_statistics(sim_turns)}
    speed = {"real": float(np.mean([p["true_step_m"] for p in real["pairs"]]) * 4.0) if "pairs" in real else math.nan,
             "sim": float(np.mean([p["true_step_m"] for p in sim["pairs"]]) * 4.0) if "pairs" in sim else math.nan}
    rows = [("pairs", "n_pairs", "", real.get("n_pairs"), sim.get("n_pairs")),
            ("speed", "", "m/s", speed["real"], speed["sim"]),
            ("pair error", "pair_trans_err_mean_m", "m", real["pair_trans_err_mean_m"], sim["pair_trans_err_mean_m"]),
            ("pair rotation error", "pair_rot_err_mean_deg", "deg", real["pair_rot_err_mean_deg"],
             sim["pair_rot_err_mean_deg"])]
    rows += [(k.replace("_", " "), k, "", stats["real"][k], stats["sim"][k]) for k in stats["real"]]
    print(f"{'':28s}{'real':>12s}{'simulated':>12s}{'sim / real':>12s}")
    for label, _, unit, a, b in rows:
        ratio = b / a if isinstance(a, float) and a not in (0.0,) and isinstance(b, float) else float("nan")
        print(f"{label + (' (' + unit + ')' if unit else ''):28s}{a:12.4f}{b:12.4f}{ratio:12.2f}")
    print(f"simulating {window_s + args.start_s + 0.2:.1f} s of the urban mission took {sim_wall:.1f} s")
    figure(real_turns[0], sim_turns[0], out / "real_vs_sim.png")
    print(f"figure: {out / 'real_vs_sim.png'}")
    result = {"real_pair_err_m": real["pair_trans_err_mean_m"], "sim_pair_err_m": sim["pair_trans_err_mean_m"],
              "real_pair_err_deg": real["pair_rot_err_mean_deg"], "sim_pair_err_deg": sim["pair_rot_err_mean_deg"],
              "pair_err_ratio_sim_over_real": sim["pair_trans_err_mean_m"] / real["pair_trans_err_mean_m"],
              "real_speed_mps": speed["real"], "sim_speed_mps": speed["sim"]}
    for who in ("real", "sim"):
        s = stats[who]
        result.update({f"{who}_mean_db": s["mean_db"], f"{who}_p5_db": s["p5_db"], f"{who}_p50_db": s["p50_db"],
                       f"{who}_p95_db": s["p95_db"], f"{who}_frac_above_10db": s["frac_above_10db"],
                       f"{who}_scan_corr": s["scan_corr"], f"{who}_energy_within_10m": s["energy_within_10m"]})
    print(json.dumps({k: round(v, 4) if isinstance(v, float) else v for k, v in result.items()}))


if __name__ == "__main__":
    main()
