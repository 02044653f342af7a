"""``impala-flow export FILE --topic T --csv``: one recorded stream as CSV."""

from __future__ import annotations

import argparse
import csv
import dataclasses
import sys
from collections.abc import Iterator
from typing import Any

import numpy as np

from ..io import MissionReader, RecordingError
from ..msgs import is_message
from . import EXIT_FAILED, EXIT_USAGE, CommandError
from .info import codecs


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export", help="export a recorded stream (CSV)",
        description="Write one topic as CSV: a t_ns column, then one column per scalar field "
        "(nested messages flattened as pose.x_m; arrays of one element as numbers, other "
        "arrays left out). Poses, speeds, scalars and numbers export completely.",
        epilog="example: impala-flow export out/rslam.mcap --topic slam/pose --csv -o pose.csv",
    )
    p.add_argument("file", metavar="FILE", help="MCAP recording")
    p.add_argument("--topic", required=True, help="recorded topic, e.g. slam/pose")
    p.add_argument("--csv", action="store_true", required=True, help="CSV output (the format)")
    p.add_argument("-o", "--output", metavar="OUT", help="output file (default: stdout)")
    p.add_argument("--start-s", type=float, default=None, help="seconds after the first sample")
    p.add_argument("--end-s", type=float, default=None, help="seconds after the first sample")
    p.set_defaults(func=run)


def flatten(value: Any, prefix: str = "") -> Iterator[tuple[str, Any]]:
    """(column, scalar) pairs of a value: numbers, strings, bools; 1-element arrays."""
    if is_message(value):
        for f in dataclasses.fields(value):
            yield from flatten(getattr(value, f.name), f"{prefix}{f.name}.")
    elif isinstance(value, np.ndarray):
        if value.size == 1 and value.dtype.kind in "biuf":
            yield prefix.rstrip(".") or "value", value.reshape(-1)[0].item()
    elif isinstance(value, (int, float, str, bool)):
        yield prefix.rstrip(".") or "value", value
    elif value is None and prefix:
        yield prefix.rstrip("."), ""


def run(args: argparse.Namespace) -> int:
    out = open(args.output, "w", newline="", encoding="utf-8") if args.output else sys.stdout
    try:
        with MissionReader(args.file, codecs()) as r:
            if args.topic not in r.topics:
                raise CommandError(f"{args.file}: no topic {args.topic!r} (recorded: "
                                   f"{', '.join(sorted(r.topics))})", EXIT_USAGE)
            t0 = r.info().start_ns or 0
            lo = None if args.start_s is None else t0 + int(round(args.start_s * 1e9))
            hi = None if args.end_s is None else t0 + int(round(args.end_s * 1e9))
            writer = csv.writer(out)
            header: list[str] | None = None
            n = 0
            for m in r.messages([args.topic], lo, hi):
                row = dict(flatten(m.data))
                if header is None:
                    header = list(row)
                    writer.writerow(["t_ns", *header])
                writer.writerow([m.t_ns, *(row.get(k, "") for k in header)])
                n += 1
    except RecordingError as e:
        raise CommandError(str(e), EXIT_FAILED) from None
    finally:
        if out is not sys.stdout:
            out.close()
    print(f"{args.topic}: {n} rows", file=sys.stderr)
    return 0
