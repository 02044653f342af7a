"""Benchmark of FMT registration + trajectory-oriented EKF-SLAM beside GTSAM (RADAR.md item 7, seed 2).

    python bench/fmt_ekf.py                 # campus seed 13, the Oxford sample
    python bench/fmt_ekf.py --seed 14

campus-open (~1 000 m, no loop) and campus-loop (~700 m, a loop) are simulated with a seed the
parameters were never set on (the FMT covariance constants: campus-open seeds 101, 102 and
campus-loop seeds 21, 22; the default scenario seed 2009 is the test's) and replayed through
graphs/fmt_ekf.yaml; the comparison's metrics (rigid alignment) are printed for the EKF, iSAM2
and LM. Then the EKF's cost per step against the number of poses (O(n^2): the covariance is
3n x 3n), measured on slam.EkfSlam's own filter (impala_slam.ekf_slam.core.PoseEkf) grown to 1 200
poses with one registration update and the loop-candidate gate per step, plus the FMT's own
time per registration; the plot goes to out/bench-fmt-ekf/ekf_step_ms.png. Then the Oxford sample through
graphs/oxford.yaml (FMT beside R-SLAM), and the first turns of a real RADIATE drive (--radiate, an imported
mission; :func:`bench_fmt_radiate`) through graphs/oxford.yaml: slam.FmtRegistration's CPU time per turn
(median, on one thread) and wall time (median, on its ``threads``, 2 by default, and OpenCV on as many as in
a graph run, where cv2 keeps its default of one per core; the calling thread's CPU in these turns too), its
split by stage (cProfile, on one thread; a third of the turns each, in turn: the results are the same with 1 or
2 threads) and the FMT's ATE. ``fmt_*_ms_per_turn``: CPU; ``fmt_*_wall_ms_per_turn``: wall (meaningful on a
quiet machine); ``fmt_*_main_cpu_ms_per_turn``: the calling thread's CPU in the wall turns.
Last line: JSON with the issue's keys (peak_rss_mb: this process's, the RADIATE graph's R-SLAM and panoramic
builder included).
"""

from __future__ import annotations

import argparse
import cProfile
import json
import math
import os
import pstats
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "plugins"))
CLI = [sys.executable, "-m", "impala_flow"]


def _run(graph: str, mission: Path, out: Path) -> tuple[dict, dict]:
    cmd = CLI + ["run", str(ROOT / "graphs" / graph), "--var", f"mission={mission}", "--var", f"out={out}",
                 "--no-progress", "--summary-json", str(out.with_suffix(".summary.json"))]
    subprocess.run(cmd, check=True, capture_output=True)
    return json.loads((out / "metrics.json").read_text()), json.loads(out.with_suffix(".summary.json").read_text())


def run_profiled(graph: str, variables: dict) -> tuple[dict, dict]:
    """A graph run in this process as a user runs it (Session, replay) with its slam.FmtRegistration
    ``fmt`` timed, a third of the turns each: CPU ms per turn on one thread (median), wall ms per turn on
    its ``threads`` (median), the split by stage (:func:`fmt_split`) from cProfile on one thread. Returns
    the run's summary ``extra`` and the FMT's figures."""
    import cv2

    from impala_flow import Session

    cv2.setNumThreads(1)
    session = Session()
    net = session.build(session.load(ROOT / "graphs" / graph, variables=variables))
    from impala_slam.fmt.parallel import TaskPool

    fmt = net.components["fmt"]
    prof = cProfile.Profile(time.thread_time)
    cpu_ms: list[float] = []
    wall_ms: list[float] = []
    main_ms: list[float] = []  # the calling thread's CPU in the wall turns: the floor of their wall time
    process = fmt.process
    one = TaskPool(1)

    def timed(t: int) -> None:
        # the turns in turn: CPU on one thread (the same results: all of it on this thread), wall on the
        # component's threads, cProfile on one thread (it sees this thread only)
        k = fmt.images % 3
        pool = fmt._pool
        if k != 1:
            fmt._pool = one
        try:
            if k == 0:
                c0 = time.thread_time()
                process(t)
                cpu_ms.append(1e3 * (time.thread_time() - c0))
            elif k == 1:  # as in a graph run: OpenCV on its threads too (its default there: one per core)
                cv2.setNumThreads(fmt.threads)
                t0, c0 = time.perf_counter(), time.thread_time()
                try:
                    process(t)
                finally:
                    cv2.setNumThreads(1)
                wall_ms.append(1e3 * (time.perf_counter() - t0))
                main_ms.append(1e3 * (time.thread_time() - c0))
            else:
                prof.runcall(process, t)
        finally:
            fmt._pool = pool

    fmt.process = timed
    summary = session.run(net)
    profiled = fmt.images - len(cpu_ms) - len(wall_ms)
    figures = {"ms_per_turn": float(np.median(cpu_ms[1:] or cpu_ms)),  # the first image: no registration
               "wall_ms_per_turn": float(np.median(wall_ms)), "threads": fmt.threads,
               "main_cpu_ms_per_turn": float(np.median(main_ms)),
               "turns": fmt.images, "failures": fmt.failures,
               **{f"{k}_ms": v for k, v in fmt_split(pstats.Stats(prof), profiled).items()}}
    return summary.extra, figures


def bench_fmt_radiate(mission_path: str | Path, turns: int = 100, out: str | Path | None = None) -> dict:
    """slam.FmtRegistration on the first ``turns`` turns of an imported Navtech mission (4 turns
    per second) through graphs/oxford.yaml (:func:`run_profiled`): CPU ms per turn (median, single
    thread), the per-stage split, the FMT's ATE and per-pair errors against the mission's truth,
    the peak RSS of this process. Returns the figures (keys with units)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(out or tmp)
        _, f = run_profiled("oxford.yaml", {"mission": str(mission_path), "out": str(out), "end_s": turns / 4.0})
        metrics = json.loads((out / "fmt" / "metrics.json").read_text())
    return {"fmt_radiate_ms_per_turn": round(f["ms_per_turn"], 2),
            "fmt_radiate_wall_ms_per_turn": round(f["wall_ms_per_turn"], 2),
            "fmt_radiate_main_cpu_ms_per_turn": round(f["main_cpu_ms_per_turn"], 2),
            "fmt_threads": f["threads"],
            "fmt_radiate_turns": f["turns"],
            "fmt_radiate_failures": f["failures"],
            "fmt_radiate_ate_m": metrics["ate_rmse_m"],
            "fmt_radiate_pair_trans_err_m": metrics.get("pair_trans_err_mean_m"),
            "fmt_radiate_pair_rot_err_deg": metrics.get("pair_rot_err_mean_deg"),
            **{f"fmt_radiate_{k}": round(v, 2) for k, v in f.items() if k.endswith("_ms")},  # the split
            "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)}


def fmt_split(stats: pstats.Stats, turns: int) -> dict[str, float]:
    """ms per turn of slam.FmtRegistration.process by stage, from a profile of its calls: total;
    prepare (resampling, threshold, polar spectrum); rotation (of the spectra); translation (of the
    two rotation candidates, and the final one on the full grid when the refinement is off or ends
    without a maximum); refine (the rotation refinement's translations, the final one included); of
    which peak (the correlation peaks' search, sub-cell fit and SNR, on the full grid or the coarse
    one), snr (the full grid's and the rotation's SNR) and fft (every FFT: scipy.fft's and cv2.dft's)."""
    ct: dict[str, float] = {}
    for (path, _, fn), (_, _, _, cum, callers) in stats.stats.items():  # type: ignore[attr-defined]
        if path == "~" and ("pypocketfft" in fn or fn == "<dft>"):  # scipy.fft's and cv2.dft
            ct["fft"] = ct.get("fft", 0.0) + cum
        if not path.replace(os.sep, "/").endswith(_FMT_FILES):
            continue
        if fn in ("translations", "final"):  # _Translator's, as register calls them (not through each other)
            ct["translation"] = ct.get("translation", 0.0) + sum(v[3] for c, v in callers.items()
                                                                 if c[2] == "_register")
        elif fn in ("surface_peak", "coarse_peak"):
            ct["peak"] = ct.get("peak", 0.0) + cum
        elif fn in ("masked_snr", "_snr_sums"):
            ct["snr"] = ct.get("snr", 0.0) + sum(v[3] for c, v in callers.items() if c[2] != "_snr_sums")
        elif fn in ("process", "prepare", "_rotation", "_refine_rotation"):
            ct[_STAGE.get(fn, fn)] = cum
    return {k: 1e3 * ct.get(k, 0.0) / max(turns, 1) for k in SPLIT}


SPLIT = ("total", "prepare", "rotation", "translation", "refine", "peak", "snr", "fft")
# the FMT's modules (the registration driver, its preparation, correlation and transforms, the component)
_FMT_FILES = tuple(f"fmt/{m}.py" for m in ("core", "spectra", "correlation", "transforms", "component"))
_STAGE = {"process": "total", "_rotation": "rotation", "_refine_rotation": "refine", "masked_snr": "snr"}


def split_line(name: str, ms: dict[str, float]) -> str:
    """One line of :func:`fmt_split`'s figures."""
    return (f"{name}: {ms['total']:.1f} ms = prepare {ms['prepare']:.1f} + rotation {ms['rotation']:.1f} + "
            f"translation {ms['translation']:.1f} + refine {ms['refine']:.1f} (+ rest); within them peaks "
            f"{ms['peak']:.1f}, snr {ms['snr']:.1f}, FFTs {ms['fft']:.1f} (profiled turns)")


def ekf_growth(n_max: int = 1200) -> list[tuple[int, float]]:
    from impala_slam.ekf_slam.core import PoseEkf

    rng = np.random.default_rng(0)
    ekf = PoseEkf()
    q = np.diag([0.05 ** 2, 0.05 ** 2, math.radians(0.5) ** 2])
    r = np.diag([0.03 ** 2, 0.03 ** 2, math.radians(0.1) ** 2])
    out = []
    for k in range(1, n_max):
        u = (5.0 + rng.normal(0, 0.05), rng.normal(0, 0.05), rng.normal(0, 0.01))
        t0 = time.perf_counter()
        ekf.augment(u, q)
        ekf.update(k - 1, k, u, r)
        ekf.relative(np.arange(0, k, 2), k)  # the loop-closure gate over the keyframes (every other pose)
        out.append((ekf.n, 1e3 * (time.perf_counter() - t0)))
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, default=13)
    ap.add_argument("--oxford", default=str(ROOT.parent / "shared" / "data" / "oxford-radar-robotcar-sample"))
    ap.add_argument("--out", default=str(ROOT / "out" / "bench-fmt-ekf"))
    ap.add_argument("--radiate", default=str(ROOT.parent / "shared" / "data" / "radiate-edinburgh-head"),
                    help="a RADIATE sequence folder (imported here) or an imported mission (.mcap)")
    ap.add_argument("--turns", type=int, default=100, help="turns of the RADIATE drive")
    args = ap.parse_args()
    res: dict = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        for scen in ("campus-open", "campus-loop"):
            mission = tmp / f"{scen}.mcap"
            subprocess.run(CLI + ["simulate", scen, "-o", str(mission), "--seed", str(args.seed), "--no-progress"],
                           check=True, capture_output=True)
            extra, f = run_profiled("fmt_ekf.yaml", {"mission": str(mission), "out": str(tmp / f"out-{scen}")})
            m = json.loads((tmp / f"out-{scen}" / "metrics.json").read_text())
            res[scen] = (m, extra.get("ekf", {}), extra.get("fmt", {}), f)
            e = res[scen][1]
            print(f"{scen} seed {args.seed}: {m['path_length_m']:.0f} m, {e.get('poses')} poses, loop closures "
                  f"{e.get('loop_closures')} (candidates {e.get('loop_candidates_tried')}, refused by the gate "
                  f"{e.get('loop_rejected_gate')}, weak {e.get('loop_rejected_weak')})")
            for n in ("ekf", "isam2", "lm"):
                print(f"  {n:6s} ATE {m[f'{n}_ate_rmse_m']:.3f} m ({m[f'{n}_ate_pct']:.3f} % of the path), final "
                      f"{m[f'{n}_final_err_m']:.3f} m (end to end {m[f'{n}_end_to_end_err_m']:.3f} m), "
                      f"{m[f'{n}_iterations']} iterations")
            print(f"  odometer + gyro ATE {m['baseline_ate_rmse_m']:.2f} m; FMT {f['ms_per_turn']:.1f} CPU ms per "
                  f"registration (median, one thread), wall {f['wall_ms_per_turn']:.1f} ms (median, "
                  f"{f['threads']} threads; calling thread {f['main_cpu_ms_per_turn']:.1f} CPU ms); EKF step median "
                  f"{e.get('step_ms_median')} ms")
            print("  " + split_line("FMT split", {k: f[f"{k}_ms"] for k in SPLIT}))
        ox = None
        if (Path(args.oxford) / "radar").is_dir():
            mission = tmp / "oxford.mcap"
            subprocess.run(CLI + ["import", "oxford", args.oxford, "-o", str(mission), "--no-progress"], check=True,
                           capture_output=True)
            out = tmp / "out-oxford"
            rs, _ = _run("oxford.yaml", mission, out)
            ox = json.loads((out / "fmt" / "metrics.json").read_text())
            print(f"Oxford sample per pair: FMT {100 * ox['pair_trans_err_mean_m']:.1f} cm / "
                  f"{ox['pair_rot_err_mean_deg']:.3f} deg, R-SLAM {100 * rs['pair_trans_err_mean_m']:.1f} cm / "
                  f"{rs['pair_rot_err_mean_deg']:.3f} deg")
    rad = None
    if Path(args.radiate).exists():
        with tempfile.TemporaryDirectory() as tmp:
            mission = Path(args.radiate)
            if mission.is_dir():
                mission = Path(tmp) / "radiate.mcap"
                subprocess.run(CLI + ["import", "radiate", args.radiate, "-o", str(mission), "--no-progress"],
                               check=True, capture_output=True)
            rad = bench_fmt_radiate(mission, args.turns)
        print(f"RADIATE, {rad['fmt_radiate_turns']} turns through graphs/oxford.yaml: FMT "
              f"{rad['fmt_radiate_ms_per_turn']} CPU ms per turn (median, one thread), wall "
              f"{rad['fmt_radiate_wall_ms_per_turn']} ms (median, {rad['fmt_threads']} threads; calling thread "
              f"{rad['fmt_radiate_main_cpu_ms_per_turn']} CPU ms), ATE "
              f"{rad['fmt_radiate_ate_m']} m, pairs "
              f"{rad['fmt_radiate_pair_trans_err_m']} m / {rad['fmt_radiate_pair_rot_err_deg']} deg")
        print("  " + split_line("FMT split", {k: rad[f"fmt_radiate_{k}_ms"] for k in SPLIT}))
    growth = ekf_growth()
    ns = np.array([n for n, _ in growth])
    ms = np.array([t for _, t in growth])
    print("EKF prediction + update + loop gate, ms per step vs poses (median of 20 steps around n):")
    at = {}
    for n in (100, 200, 400, 600, 800, 1000, 1200):
        sel = np.abs(ns - n) <= 10
        if np.any(sel):
            at[n] = float(np.median(ms[sel]))
            print(f"  n = {n:5d}: {at[n]:.2f} ms")
    fit = np.polyfit(ns.astype(float), ms, 2)
    print(f"  quadratic fit: {fit[0] * 1e6:.3f} ms per 1000^2 poses^2 + {fit[1] * 1e3:.3f} ms per 1000 poses "
          f"+ {fit[2]:.2f} ms")
    fmt_ms = res["campus-loop"][2].get("fmt_ms", 0.0)
    fmt_cpu = [res[scen][3]["ms_per_turn"] for scen in ("campus-open", "campus-loop")]
    fmt_wall = [res[scen][3]["wall_ms_per_turn"] for scen in ("campus-open", "campus-loop")]
    fmt_main = [res[scen][3]["main_cpu_ms_per_turn"] for scen in ("campus-open", "campus-loop")]
    outdir = Path(args.out)
    outdir.mkdir(parents=True, exist_ok=True)
    import matplotlib

    matplotlib.use("Agg")
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.5, 4), dpi=110, layout="constrained")
    ax = fig.add_subplot()
    ax.plot(ns, ms, ".", ms=2, alpha=0.4, label="measured")
    ax.plot(ns, np.polyval(fit, ns), "r-", label="quadratic fit")
    ax.set(xlabel="poses in the state", ylabel="ms per step (prediction, update, gate)",
           title="Trajectory-oriented EKF: cost per step grows as n^2")
    ax.grid(alpha=0.3)
    ax.legend(frameon=False)
    fig.savefig(outdir / "ekf_step_ms.png")
    print(f"plot: {outdir / 'ekf_step_ms.png'}")
    mo, ml = res["campus-open"][0], res["campus-loop"][0]
    print(json.dumps({
        "fmt_ms": fmt_ms,
        "ekf_step_ms_at_1000": round(fmt_ms + at.get(1000, float("nan")), 2),
        "ekf_filter_ms_at_1000": round(at.get(1000, float("nan")), 2),
        "ate_open_pct": ml and mo["ekf_ate_pct"],
        "ate_loop_m": ml["ekf_ate_rmse_m"],
        "final_err_loop_m": ml["ekf_final_err_m"],
        "end_to_end_err_loop_m": ml["ekf_end_to_end_err_m"],
        "loop_closures": res["campus-loop"][1].get("loop_closures"),
        "gtsam_lm_ate_loop_m": ml["lm_ate_rmse_m"],
        "isam2_ate_loop_m": ml["isam2_ate_rmse_m"],
        "oxford_fmt_trans_err_m": ox and ox["pair_trans_err_mean_m"],
        "oxford_fmt_rot_err_deg": ox and ox["pair_rot_err_mean_deg"],
        "fmt_campus_ms_per_turn": round(float(np.mean(fmt_cpu)), 2),
        "fmt_campus_wall_ms_per_turn": round(float(np.mean(fmt_wall)), 2),
        "fmt_campus_main_cpu_ms_per_turn": round(float(np.mean(fmt_main)), 2),
        "fmt_radiate_ms_per_turn": rad and rad["fmt_radiate_ms_per_turn"],
        "fmt_radiate_wall_ms_per_turn": rad and rad["fmt_radiate_wall_ms_per_turn"],
        "fmt_radiate_main_cpu_ms_per_turn": rad and rad["fmt_radiate_main_cpu_ms_per_turn"],
        "fmt_radiate_ate_m": rad and rad["fmt_radiate_ate_m"],
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
    }))
    return 0


if __name__ == "__main__":
    sys.exit(main())
