"""``impala-flow run GRAPH``: validate then run a graph."""

from __future__ import annotations

import argparse
import json
import math

from .helpers import (
    add_blas_threads_arg,
    add_graph_args,
    check_output_over_inputs,
    check_speed,
    check_writable_file,
    load_spec,
    open_session,
    run_network,
)

EPILOG = """\
examples:
  impala-flow run graphs/frontend.yaml --var mission=out/beynes.mcap --speed 2 --set pairer.pfa=1e-4
  impala-flow run graphs/frontend.yaml --var mission=out/beynes.mcap --duration 60
                                       its first minute of mission time, then flush and stop (exit 0)
  impala-flow run graphs/live_navtech.yaml --duration 30 --summary-json out/live.json
                                       30 s live, then the recorder closes its file (exit 0)

Ending a run:
  at the end of the inputs   every component flushes (emits what it holds), then stops; exit 0
  --duration S               the same after S s of mission time (live: wall time): sources
                             stop, what they delivered is processed and flushed; exit 0
  Ctrl-C                     what was delivered is processed, nothing flushes; exit 130

The summary gives, per component, the time per process() call (median, p99, total, share of
the run's wall time) and, for a live graph, one LATENCY line per output: from the arrival of
the sample that started the work (its source's sample) to the emit, median / p99 / max.
"""


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run", help="run a graph", description="Validate GRAPH, then run it. Offline graphs (clock mode "
        "'replay') run on the deterministic executor, paced by --speed; 'realtime' graphs run live. "
        "Ctrl-C stops cleanly: every component's stop() runs and the summary prints.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_graph_args(p)
    p.add_argument("--speed", default=None, metavar="X|max",
                   help="replay speed: 1 = real time, 2 = twice as fast, max = as fast as possible "
                   "(default: the graph's clock.speed). Pacing never changes the results.")
    p.add_argument("--duration", type=_duration, default=None, metavar="S",
                   help="stop after S seconds of mission time (live: wall time), flushing as at the end "
                   "of the inputs; exit 0")
    p.add_argument("--summary-json", metavar="FILE", help="also write the run summary as JSON")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_blas_threads_arg(p)
    p.set_defaults(func=run)


def _duration(text: str) -> float:
    """``--duration``: a finite number of seconds > 0 (at most int64 ns)."""
    try:
        v = float(text)
    except ValueError:
        v = math.nan
    if not (math.isfinite(v) and 0 < v <= 9.2e9):
        raise argparse.ArgumentTypeError(f"expected a number of seconds > 0, got {text!r}")
    return v


def run(args: argparse.Namespace) -> int:
    check_speed(args.speed)  # usage errors first, before the plugins load and the run starts
    if args.summary_json:
        check_writable_file(args.summary_json, "--summary-json")
    session = open_session()
    spec = load_spec(session, args)
    if args.summary_json:
        check_output_over_inputs(args.summary_json, "--summary-json", spec, session)

    def write(summary):  # type: ignore[no-untyped-def]
        if args.summary_json:
            with open(args.summary_json, "w", encoding="utf-8") as f:
                json.dump(summary.to_json(), f, indent=2, default=str)

    return run_network(session, spec, speed=args.speed, progress=False if args.no_progress else None,
                       on_summary=write, duration_s=args.duration, blas_threads=args.blas_threads)
