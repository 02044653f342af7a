"""``impala-flow demo``: a short simulated mission through the whole chain, then its report.

Two graphs shipped with this package (the embedded default): ``demo_simulate.yaml``
simulates a Beynes-like mission and records it; ``demo_rslam.yaml`` (the same chain as
``graphs/rslam.yaml``) replays it through the panoramic builder, the speckle filter,
R-SLAM and the evaluator, with dead reckoning as the baseline. The graphs name their
components by type (``radar.Simulator``, ``slam.RSlam``...), so this plugin imports no
other plugin: the registry wires them.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

from impala_flow.cli import EXIT_OK, CommandError
from impala_flow.cli.helpers import open_session, run_network

from .report import format_metrics, load_metrics

__all__ = ["add_demo_command", "GRAPHS"]

GRAPHS = {name: Path(__file__).with_name(f"demo_{name}.yaml") for name in ("simulate", "rslam")}


def add_demo_command(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo", help="simulate a short mission, run the radar SLAM chain, print the report",
        description="The main job on its embedded default: simulate about a minute of the Beynes-like "
        "scenario (FMCW radar with speckle, clutter and motion distortion; odometer, gyro, RTK-GPS "
        "truth), record it to MCAP, replay it through panoramic builder -> anti-speckle filter -> "
        "R-SLAM -> evaluator (dead reckoning beside it), and print the metrics and where the report is.",
        epilog="example: impala-flow demo --duration 30 --out out/demo",
    )
    p.add_argument("--duration", type=float, default=60.0, metavar="SECONDS", help="mission length (default 60)")
    p.add_argument("--seed", type=int, default=1, help="seed of the world and the sensor noise (default 1)")
    p.add_argument("--out", default="out/demo", help="output folder (default out/demo)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.set_defaults(func=run_demo)


def run_demo(args: argparse.Namespace) -> int:
    if args.duration <= 0:
        raise CommandError(f"--duration must be positive, got {args.duration}", 2)
    out = Path(args.out)
    progress = False if args.no_progress else None
    variables: dict[str, Any] = {"duration_s": float(args.duration), "seed": args.seed, "out": str(out)}
    t0 = time.perf_counter()
    print(f"[1/2] simulating {args.duration:g} s of the Beynes scenario -> {out / 'mission.mcap'}", file=sys.stderr)
    session = open_session()
    code = run_network(session, session.load(GRAPHS["simulate"], variables=variables), progress=progress)
    if code != EXIT_OK:
        return code
    print(f"[2/2] replaying it through panoramic -> speckle -> R-SLAM -> evaluator -> {out / 'report'}",
          file=sys.stderr)
    session = open_session()
    chain = {"mission": str(out / "mission.mcap"), "out": str(out / "report")}
    code = run_network(session, session.load(GRAPHS["rslam"], variables=chain), progress=progress)
    if code != EXIT_OK:
        return code
    report = out / "report"
    print(f"\nR-SLAM vs RTK-GPS truth (dead reckoning from odometer + gyro as baseline), "
          f"{time.perf_counter() - t0:.0f} s:")
    print(format_metrics(load_metrics(report)))
    print(f"\nreport: {report}/ (metrics.json, error_vs_distance.png, trajectory_map.png, map.png)")
    print(f"mission: {out / 'mission.mcap'} (impala-flow info {out / 'mission.mcap'})")
    return EXIT_OK
