"""Benchmark of DATMO (RADAR.md item 9, seed 1 §4.3): graphs/datmo.yaml on simulated missions.

    python bench/datmo.py                               # datmo seeds 11 12 13, traffic seeds 11 12
    python bench/datmo.py --datmo-seeds 21 --traffic-seeds 21 --jobs 2

Each mission is simulated (``impala-flow simulate``: the whole 145 s datmo scenario, the 60 s
traffic scenario) and replayed through graphs/datmo.yaml: radar.FuzzyPairer ->
radar.EgoVelocity -> tracking.MoverDetector -> tracking.Tracker -> eval.TrackingEvaluator
(motmetrics). Printed per scenario and seed: MOTA, MOTP, IDF1, ID switches, fragmentations,
the longest track's mean position and speed errors (the seed's figures), false tracks and
their longest life in turns, and the ms per turn of detector + tracker on one core (their
``process`` calls timed). The parameters were tuned on datmo seeds 3-5 and traffic seeds 3-4:
the default seeds here were never used for tuning. The last line is one JSON object: the
datmo scenario's figures (mean over seeds; ``false_track_max_turns`` and ``id_switches`` the
worst / total) with the issue's keys, and the traffic scenario's prefixed ``traffic_``.
Targets (issue 13): datmo position error <= 1 m, speed error <= 0.2 m/s, MOTA >= 0.9,
IDF1 >= 0.9, false tracks dead within 3 turns; traffic MOTA >= 0.8; <= 20 ms per turn.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")
ROOT = Path(__file__).resolve().parents[1]
GRAPH = ROOT / "graphs" / "datmo.yaml"
KEYS = ("mota", "motp_m", "idf1", "id_switches", "fragmentations", "pos_err_m", "speed_err_mps",
        "pos_err_all_m", "speed_err_all_mps", "false_tracks", "false_tracks_confirmed", "false_track_max_turns",
        "misses", "false_positives", "truth_objects")


def simulate(args: tuple[str, int, str]) -> str:
    scenario, seed, out = args
    from impala_flow.cli import main

    if main(["simulate", scenario, "-o", out, "--seed", str(seed), "--overwrite"]) != 0:
        raise RuntimeError(f"simulate {scenario} seed {seed} failed")
    return out


def _timed(comp, acc: dict[str, float]) -> None:  # type: ignore[no-untyped-def]
    inner = comp.process

    def process(t: int) -> None:
        t0 = time.perf_counter()
        inner(t)
        acc[comp.name] = acc.get(comp.name, 0.0) + time.perf_counter() - t0

    comp.process = process


def run(args: tuple[str, str]) -> dict:
    mission, report = args
    from impala_flow import Session

    session = Session()
    spec = session.load(GRAPH, variables={"mission": mission, "out": report})
    net = session.build(spec)
    acc: dict[str, float] = {}
    for name in ("detector", "tracker"):
        _timed(net.components[name], acc)
    session.run(net)
    f = net.components["eval"].figures
    turns = max(1, net.components["tracker"].turn)
    out = {k: f.get(k) for k in KEYS}
    out["datmo_ms_per_turn"] = 1e3 * (acc.get("detector", 0.0) + acc.get("tracker", 0.0)) / turns
    out["detector_ms_per_turn"] = 1e3 * acc.get("detector", 0.0) / turns
    out["tracker_ms_per_turn"] = 1e3 * acc.get("tracker", 0.0) / turns
    out["turns"] = turns
    return out


def _summary(rows: list[dict]) -> dict:
    def mean(k: str) -> float | None:
        vals = [r[k] for r in rows if isinstance(r.get(k), (int, float))]
        return round(sum(vals) / len(vals), 4) if vals else None

    s = {k: mean(k) for k in ("mota", "motp_m", "idf1", "pos_err_m", "speed_err_mps", "pos_err_all_m",
                              "speed_err_all_mps", "datmo_ms_per_turn")}
    s["id_switches"] = sum(int(r["id_switches"] or 0) for r in rows)
    s["fragmentations"] = sum(int(r["fragmentations"] or 0) for r in rows)
    s["false_track_max_turns"] = max(int(r["false_track_max_turns"] or 0) for r in rows)
    s["false_tracks_confirmed"] = sum(int(r["false_tracks_confirmed"] or 0) for r in rows)
    return s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--datmo-seeds", type=int, nargs="*", default=[11, 12, 13])
    ap.add_argument("--traffic-seeds", type=int, nargs="*", default=[11, 12])
    ap.add_argument("--jobs", type=int, default=2, help="missions simulated / evaluated in parallel")
    ap.add_argument("--out", default="out/bench-datmo", help="reports (one folder per mission)")
    args = ap.parse_args()
    cases = [("datmo", s) for s in args.datmo_seeds] + [("traffic", s) for s in args.traffic_seeds]
    with tempfile.TemporaryDirectory() as tmp, ProcessPoolExecutor(args.jobs) as pool:
        t0 = time.perf_counter()
        missions = list(pool.map(simulate, [(sc, seed, str(Path(tmp) / f"{sc}-{seed}.mcap")) for sc, seed in cases]))
        print(f"simulated {len(missions)} missions in {time.perf_counter() - t0:.0f} s")
        reports = [str(Path(args.out) / f"{sc}-{seed}") for sc, seed in cases]
        rows = list(pool.map(run, zip(missions, reports, strict=True)))
    by: dict[str, list[dict]] = {}
    for (sc, seed), r in zip(cases, rows, strict=True):
        by.setdefault(sc, []).append(r)
        print(f"{sc:8s} seed {seed:3d}: MOTA {r['mota']:.3f}  MOTP {r['motp_m']:.2f} m  IDF1 {r['idf1']:.3f}  "
              f"IDsw {r['id_switches']}  frag {r['fragmentations']}  FN {r['misses']}  FP {r['false_positives']}"
              f" / {r['truth_objects']}  longest track {r['pos_err_m']} m {r['speed_err_mps']} m/s  "
              f"(all {r['pos_err_all_m']} m {r['speed_err_all_mps']} m/s)  false tracks {r['false_tracks']} "
              f"(confirmed {r['false_tracks_confirmed']}, max {r['false_track_max_turns']} turns)  "
              f"{r['datmo_ms_per_turn']:.2f} ms/turn (detector {r['detector_ms_per_turn']:.2f}, "
              f"tracker {r['tracker_ms_per_turn']:.2f})")
    out = _summary(by.get("datmo", []) or rows)
    for k, v in _summary(by.get("traffic", [])).items() if "traffic" in by else ():
        out[f"traffic_{k}"] = v
    out["datmo_seeds"], out["traffic_seeds"] = args.datmo_seeds, args.traffic_seeds
    for k, v in out.items():
        print(f"{k:32s} {v}")
    print(json.dumps(out))


if __name__ == "__main__":
    sys.exit(main())
