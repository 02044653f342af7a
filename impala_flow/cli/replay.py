"""``impala-flow replay FILE GRAPH``: run GRAPH with its replayer bound to FILE."""

from __future__ import annotations

import argparse

from ..graph import GraphError, resolve_graph
from ..yamlloc import YamlError
from . import EXIT_USAGE, CommandError
from ._common import add_graph_args, open_session, parse_vars, run_network

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
    p.set_defaults(func=run)


def replayer_ids(graph_path: str, variables: dict | None = None) -> list[str]:
    """Ids of the io.Replayer components of the graph, its includes resolved."""
    try:
        spec, _ = resolve_graph(graph_path, variables=variables)
    except (GraphError, YamlError) as e:
        raise CommandError(str(e), EXIT_USAGE) from None
    return [c.id for c in spec.components.values() if c.type == REPLAYER]


def run(args: argparse.Namespace) -> int:
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
    return run_network(session, spec, speed=args.speed,
                       progress=False if args.no_progress else None)
