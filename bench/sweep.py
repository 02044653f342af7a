"""Sweep benchmark: the same graphs in a plain loop, then as a sweep on Dask with 1 and 2 workers.

    python bench/sweep.py [--missions 8] [--duration 20] [--graph graphs/rslam.yaml] [--out out/bench-sweep]

The missions (Beynes, seeds 1..N, --duration seconds) are simulated once beforehand into
files (not timed), so every mode runs exactly the same graph runs. Each mode runs in a
fresh process and is timed end to end, start-up included:
- plain loop: one Python process running the graph on each mission in turn (Session, load,
  run at max speed), the way a script would without the sweep;
- sweep, 1 worker: `impala-flow sweep` with a LocalCluster of one worker process;
- sweep, 2 workers: the same with two (this machine has 2 cores).
Figures: speed-up of 2 workers over 1 (goal >= 1.7x), overhead of the sweep machinery with
1 worker against the plain loop ((sweep - loop) / loop, goal <= 5 %), split into a fixed
start-up (import Dask, start and close the cluster, write the summary and the figure) and
the tasks' own overhead (each graph run as a task on a worker vs alone in the loop), tasks
per minute with 2 workers, and whether the three modes gave identical metrics. The fixed
start-up (about 2 s) weighs less as missions get longer: --duration 60 shows it.
The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
METRICS = ["eval.ate_rmse_m", "eval.drift_pct"]


def simulate(folder: Path, n: int, duration_s: float) -> list[Path]:
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for seed in range(1, n + 1):
        path = folder / f"beynes-{seed}.mcap"
        if not path.exists():
            tmp = path.with_name(f".{path.name}.part")
            subprocess.run([sys.executable, "-m", "impala_flow", "simulate", "beynes", "-o", str(tmp), "--duration",
                            f"{duration_s}s", "--seed", str(seed), "--no-progress"], check=True, capture_output=True)
            os.replace(tmp, path)
        paths.append(path)
    return paths


def plain_loop(graph: str, out: str, missions: list[str]) -> None:
    """The loop timed as the baseline (run in a fresh process: ``--plain-loop``)."""
    from impala_flow import Session

    rows = []
    for m in missions:
        t0 = time.perf_counter()
        session = Session()
        spec = session.load(graph, (), {"mission": m, "out": str(Path(out) / Path(m).stem)})
        summary = session.run(session.build(spec), speed="max", mode=spec.clock_mode)
        rows.append({"mission": m, "run_s": time.perf_counter() - t0,
                     **{k: summary.extra[k.split(".")[0]][k.split(".")[1]] for k in METRICS}})
    (Path(out) / "rows.json").write_text(json.dumps(rows))


def timed(cmd: list[str]) -> float:
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        sys.exit(f"{' '.join(cmd)}: exit {r.returncode}\n{r.stderr[-3000:]}")
    return wall


def sweep_rows(folder: Path) -> dict[str, dict[str, str]]:
    with open(folder / "results.csv", encoding="utf-8", newline="") as f:
        return {r["mission"]: r for r in csv.DictReader(f)}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--missions", type=int, default=8)
    ap.add_argument("--duration", type=float, default=20.0, help="seconds of each simulated Beynes mission")
    ap.add_argument("--graph", default=str(ROOT / "graphs" / "rslam.yaml"))
    ap.add_argument("--out", default=str(ROOT / "out" / "bench-sweep"))
    ap.add_argument("--plain-loop", nargs="+", metavar=("OUT", "MISSION"), help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.plain_loop:
        plain_loop(args.graph, args.plain_loop[0], args.plain_loop[1:])
        return

    out = Path(args.out).resolve()
    missions = simulate(out / "missions", args.missions, args.duration)
    for d in ("loop", "w1", "w2"):
        shutil.rmtree(out / d, ignore_errors=True)
    sweep = out / "sweep.yaml"
    sweep.write_text(f"graph: {Path(args.graph).resolve()}\nmissions: {{files: [missions/*.mcap]}}\n"
                     f"metrics: [{', '.join(METRICS)}]\n", encoding="utf-8")
    print(f"{len(missions)} missions of {args.duration:g} s (beynes, seeds 1-{len(missions)}), graph {args.graph}, "
          f"{os.cpu_count()} CPUs")

    (out / "loop").mkdir()
    loop_s = timed([sys.executable, __file__, "--graph", args.graph, "--plain-loop", str(out / "loop"),
                    *map(str, missions)])
    print(f"plain loop                  {loop_s:7.1f} s  ({loop_s / len(missions):.2f} s per mission)")
    w1_s = timed([sys.executable, "-m", "impala_flow", "sweep", str(sweep), "-o", str(out / "w1"), "--workers", "1",
                  "--no-progress"])
    print(f"sweep, 1 worker             {w1_s:7.1f} s")
    w2_s = timed([sys.executable, "-m", "impala_flow", "sweep", str(sweep), "-o", str(out / "w2"), "--workers", "2",
                  "--no-progress"])
    print(f"sweep, 2 workers            {w2_s:7.1f} s")

    loop_rows = {r["mission"]: r for r in json.loads((out / "loop" / "rows.json").read_text())}
    w1, w2 = sweep_rows(out / "w1"), sweep_rows(out / "w2")
    same = all(float(w1[m][k]) == float(w2[m][k]) == float(loop_rows[m][k]) for m in loop_rows for k in METRICS)
    loop_runs_s = sum(r["run_s"] for r in loop_rows.values())  # the graph runs alone, in the loop
    task_s = sum(float(r["wall_s"]) for r in w1.values())  # the same, as tasks on the worker
    res = {
        "missions": len(missions),
        "mission_s": args.duration,
        "plain_loop_s": loop_s,
        "sweep_1_worker_s": w1_s,
        "sweep_2_workers_s": w2_s,
        "speedup_2_workers": w1_s / w2_s,
        "overhead_pct": (w1_s - loop_s) / loop_s * 100.0,
        "overhead_per_task_s": (w1_s - loop_s) / len(missions),
        "task_overhead_pct": (task_s - loop_runs_s) / loop_runs_s * 100.0,
        "startup_s": (w1_s - task_s) - (loop_s - loop_runs_s),
        "loop_run_s_mean": loop_runs_s / len(missions),
        "task_run_s_mean": task_s / len(missions),
        "tasks_per_min_2_workers": len(missions) / w2_s * 60.0,
        "identical_metrics": same,
    }
    print(f"speed-up, 2 workers vs 1    {res['speedup_2_workers']:7.2f} x   (goal >= 1.7)")
    print(f"sweep overhead vs the loop  {res['overhead_pct']:7.1f} %   (goal <= 5; end to end, 1 worker: "
          f"{res['overhead_per_task_s']:.2f} s per task)")
    print(f"  of which the start-up     {res['startup_s']:7.1f} s   (Dask, cluster, closing, summary.md, figure)")
    print(f"  and the tasks themselves  {res['task_overhead_pct']:7.1f} %   (graph run as a task on the worker, "
          f"{res['task_run_s_mean']:.2f} s, vs alone in the loop, {res['loop_run_s_mean']:.2f} s)")
    print(f"tasks per minute, 2 workers {res['tasks_per_min_2_workers']:7.1f}")
    print(f"same metrics in all modes   {same}")
    print(json.dumps({k: round(v, 3) if isinstance(v, float) else v for k, v in res.items()}))


if __name__ == "__main__":
    main()
