"""``impala-flow demo``: the embedded default mission (placeholder until the radar chain lands)."""

from __future__ import annotations

import argparse


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="simulate a short mission through the full chain, then report",
                       description="Simulate a short mission, run it through the radar chain and print "
                       "its evaluation report.", epilog="example: impala-flow demo")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    print("no demo yet: the radar chain lands with issues 4-6")
    return 0
