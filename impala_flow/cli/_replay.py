"""``impala-flow replay FILE GRAPH``: run GRAPH with its replayer bound to FILE."""

from __future__ import annotations

import argparse
import json

from .._session import Session
from .._spec import GraphError
from .._summary import RunSummary
from .._yamlloc import YamlError
from ..io import RecordingError, open_recording
from . import EXIT_FAILED, EXIT_USAGE, CommandError
from .helpers import (
    add_blas_threads_arg,
    add_graph_args,
    check_output_over_inputs,
    check_writable_file,
    open_session,
    parse_vars,
    run_network,
)

REPLAYER = "io.Replayer"


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "replay", help="replay a recording through a graph",
        description=f"Run GRAPH offline with the 'path' of its {REPLAYER} component(s) set to "
        "FILE: the recorded topics become the replayer's outputs. Same results at any --speed.",
        epilog="example: impala-flow replay missions/beynes.mcap graphs/rslam_replay.yaml --speed 2",
    )
    p.add_argument("file", metavar="FILE", help="MCAP recording")
    add_graph_args(p)
    p.add_argument("--speed", default=None, metavar="X|max", help="replay speed (default: the "
                   "graph's clock.speed); pacing never changes the results")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    add_blas_threads_arg(p)
    p.add_argument("--summary-json", metavar="OUT", help="also write the run summary as JSON (with 'lost': "
                   "the messages of damaged chunks, per replayer output)")
    p.set_defaults(func=run)


def replayer_ids(graph_path: str, variables: dict | None = None) -> list[str]:
    """Ids of the io.Replayer components of the graph, its includes resolved (the *load*
    stage only: the graph is validated once the recording is bound to them)."""
    try:
        spec, _ = Session.read(graph_path, variables=variables)
    except (GraphError, YamlError) as e:
        raise CommandError(str(e), EXIT_USAGE) from None
    return [c.id for c in spec.components.values() if c.type == REPLAYER]


def check_recording(path: str) -> None:
    """One line, exit 1, when FILE is not a readable recording (before the graph is built)."""
    try:
        with open_recording(path):  # a file, or a rosbag2 folder of split files
            pass
    except RecordingError as e:
        raise CommandError(str(e), EXIT_FAILED) from None


def run(args: argparse.Namespace) -> int:
    check_recording(args.file)
    variables = parse_vars(args.variables)
    ids = replayer_ids(args.graph, variables)
    if not ids:
        raise CommandError(f"{args.graph}: no component of type {REPLAYER} to bind {args.file} "
                           "to", EXIT_USAGE)
    session = open_session()
    overrides = [f"{cid}.path={args.file}" for cid in ids] + list(args.overrides)
    try:
        spec = session.load(args.graph, overrides, variables)
    except (GraphError, YamlError) as e:
        raise CommandError(str(e), EXIT_USAGE) from None
    if args.summary_json:  # checked without creating it (a named pipe would block open())
        check_writable_file(args.summary_json, "--summary-json")
        check_output_over_inputs(args.summary_json, "--summary-json", spec, session, ((args.file, "the recording"),))

    def report(summary: RunSummary) -> None:  # the LOST lines are in summary.format()
        if args.summary_json:
            with open(args.summary_json, "w", encoding="utf-8") as f:
                json.dump(summary.to_json(), f, indent=2, default=str)

    return run_network(session, spec, speed=args.speed,
                       progress=False if args.no_progress else None, on_summary=report,
                       blas_threads=args.blas_threads)
