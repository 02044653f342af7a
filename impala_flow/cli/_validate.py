"""``impala-flow validate GRAPH``: report every problem of a graph without running it."""

from __future__ import annotations

import argparse

from .._offline import timer_problems
from . import EXIT_USAGE, CommandError
from .helpers import add_graph_args, load_spec, open_session


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "validate", help="check a graph without running it",
        description="Load GRAPH with its includes, variables and --set overrides, and check it against "
        "the installed plugins: component types, parameters, ports, port types, required inputs, "
        "cycles, record streams. Every problem is printed with file:line:column.",
        epilog="example: impala-flow validate graphs/frontend.yaml --var mission=out/beynes.mcap --set pairer.pfa=1e-4",
    )
    add_graph_args(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    session = open_session()
    spec = load_spec(session, args)
    net = session.build(spec)
    bad = timer_problems(net)  # as run does: a timer that would spin over the mission's span
    if bad:
        raise CommandError("; ".join(bad), EXIT_USAGE)
    print(f"{args.graph}: ok - graph '{spec.name}', {len(net.components)} components, "
          f"{len(net.connections)} connections, clock {spec.clock_mode} at speed {spec.speed}")
    return 0
