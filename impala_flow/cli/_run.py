"""``impala-flow run GRAPH``: validate then run a graph."""

from __future__ import annotations

import argparse
import json

from .helpers import (
    add_graph_args,
    check_output_over_inputs,
    check_speed,
    check_writable_file,
    load_spec,
    open_session,
    run_network,
)


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "run", help="run a graph", description="Validate GRAPH, then run it. Offline graphs (clock mode "
        "'replay') run on the deterministic executor, paced by --speed; 'realtime' graphs run live. "
        "Ctrl-C stops cleanly: every component's stop() runs and the summary prints.",
        epilog="example: impala-flow run graphs/frontend.yaml --var mission=out/beynes.mcap --speed 2 "
               "--set pairer.pfa=1e-4",
    )
    add_graph_args(p)
    p.add_argument("--speed", default=None, metavar="X|max",
                   help="replay speed: 1 = real time, 2 = twice as fast, max = as fast as possible "
                   "(default: the graph's clock.speed). Pacing never changes the results.")
    p.add_argument("--summary-json", metavar="FILE", help="also write the run summary as JSON")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


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
                       on_summary=write)
