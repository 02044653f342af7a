"""``impala-flow export FILE --topic T --csv``: one recorded stream as CSV, never silently lossy
(``--ros2 OUT.mcap``: the recording as standard ROS 2 messages, :mod:`._export_ros2`).

Columns: ``t_ns``, then every scalar field (nested messages flattened as ``pose.x_m``).
Arrays are never dropped:

- a message whose array fields share their first dimension N (``ObjectStates``: ids, xy_m,
  v_xy_mps, cov; ``Trajectory2D``: t_ns, xyt; ``Points2D``) gives N rows, one per object or
  pose, with its ``index`` and the array's columns (``xy_m.0``, ``xy_m.1``, ``cov.0.3``...;
  a field named ``t_ns`` is the column ``msg.t_ns``, ``t_ns`` being the sample's time);
  an empty one (no object at that time) still gives one row, with an empty ``index``;
- any other array of at most 16 values (a pose covariance) gives one column per value;
- a larger array (a ``Grid``'s data, a beam's power) is refused with one line naming the
  field, unless ``--npy DIR``: then each one is written to ``DIR/<field>_<row>.npy`` and its
  column holds that file's name.

A recording whose damaged chunks held messages of the topic stops the export (exit 1, one
line saying how many and when) unless ``--allow-loss``; nothing is written then.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import math
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from .._component import MAX_SECONDS
from .._paths import not_writable, output_clash
from ..io import MissionReader, RecordingError, open_recording
from ..msgs import is_message
from . import EXIT_FAILED, EXIT_USAGE, CommandError
from ._info import codecs
from .helpers import check_writable_file, loss_line, window

#: arrays up to this many values become columns; larger ones need --npy
SMALL_ARRAY = 16


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "export", help="export a recorded stream (CSV) or a recording as ROS 2 messages",
        description="Write one topic as CSV: a t_ns column, then one column per scalar field "
        "(nested messages flattened as pose.x_m). Messages holding N objects or poses (ObjectStates, "
        "Trajectory2D, Points2D) give N rows with their index; small arrays (a covariance) one column "
        "per value; large arrays (a Grid's data) are refused unless --npy DIR writes them as .npy "
        "files. Or, with --ros2 OUT.mcap, write the recording (every topic, or --topic) as standard "
        "ROS 2 messages (the ros2 plugin: poses as PoseStamped + Path + Odometry, /tf, maps as "
        "OccupancyGrid, detections and tracks as radar_msgs, scans as Image; ros2msg schemas, CDR) "
        "that `ros2 bag play` and Foxglove read; --native keeps the native channels beside them. "
        "Lost messages (damaged chunks) fail the export unless --allow-loss.",
        epilog="examples:\n  impala-flow export out/rslam.mcap --topic slam/pose --csv -o pose.csv\n"
        "  impala-flow export out/rslam.mcap --ros2 out/rslam-ros2.mcap   # then: ros2 bag play out/rslam-ros2.mcap",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("file", metavar="FILE", help="MCAP recording")
    p.add_argument("--topic", help="recorded topic, e.g. slam/pose (required with --csv; with --ros2: only it)")
    p.add_argument("--csv", action="store_true", help="CSV output of --topic")
    p.add_argument("--ros2", metavar="OUT.mcap", default=None,
                   help="write the recording as ROS 2 messages to OUT.mcap (replaced if it exists; needs the "
                   "ros2 plugin)")
    p.add_argument("--native", action="store_true",
                   help="with --ros2: keep the native channels (and their Foxglove mirrors) beside the ROS 2 ones")
    p.add_argument("-o", "--output", metavar="OUT", help="output file (default: stdout)")
    p.add_argument("--start-s", type=float, default=None, help="seconds after the first sample")
    p.add_argument("--end-s", type=float, default=None, help="seconds after the first sample")
    p.add_argument("--npy", metavar="DIR", default=None,
                   help="write arrays too large for a CSV cell (a Grid's data) to DIR/<field>_<row>.npy")
    p.add_argument("--allow-loss", action="store_true",
                   help="export what is readable even if damaged chunks held messages of the topic")
    p.set_defaults(func=run)


class ArrayTooLarge(ValueError):
    """An array field a CSV cannot hold (and no --npy)."""


def _row_length(value: Any) -> int | None:
    """N when ``value`` is a message whose top-level arrays share their first dimension N
    (at least two such arrays; empty ones, like an absent covariance, do not count)."""
    if not is_message(value):
        return None
    firsts = [v.shape[0] for f in dataclasses.fields(value)
              if isinstance(v := getattr(value, f.name), np.ndarray) and v.ndim >= 1 and v.size]
    if len(firsts) >= 2 and len(set(firsts)) == 1:
        return firsts[0]
    arrays = [v for f in dataclasses.fields(value)
              if isinstance(v := getattr(value, f.name), np.ndarray) and v.ndim >= 1]
    if len(arrays) >= 2 and not firsts and all(a.shape[0] == 0 for a in arrays):
        return 0  # no object at this time
    return None


def _cells(name: str, a: np.ndarray) -> Iterator[tuple[str, Any]]:
    """One column per value of a small array: name.i.j."""
    if a.ndim == 0:
        yield name, a.item()
        return
    for idx in np.ndindex(a.shape):
        yield f"{name}." + ".".join(map(str, idx)), a[idx].item()


def flatten(value: Any, prefix: str = "", npy: Any = None) -> Iterator[tuple[str, Any]]:
    """(column, scalar) pairs of a value (one row). ``npy(column, array) -> str`` stores a
    large array and returns the cell's text; without it a large array raises ArrayTooLarge."""
    name = prefix.rstrip(".") or "value"
    if is_message(value):
        for f in dataclasses.fields(value):
            yield from flatten(getattr(value, f.name), f"{prefix}{f.name}.", npy)
    elif isinstance(value, np.ndarray):
        if value.dtype.kind not in "biufcU?S" or value.dtype.kind == "c":
            raise ArrayTooLarge(f"field {name!r}: {value.dtype} values have no CSV form")
        if value.size <= SMALL_ARRAY:
            yield from _cells(name, value)
        elif npy is not None:
            yield name, npy(name, value)
        else:
            raise ArrayTooLarge(f"field {name!r} is a {'x'.join(map(str, value.shape))} array, too large for "
                                "CSV columns (use --npy DIR to write it as .npy files)")
    elif isinstance(value, (int, float, str, bool)) or (isinstance(value, np.generic)):
        yield name, value.item() if isinstance(value, np.generic) else value
    elif value is None:
        yield name, ""
    elif isinstance(value, (list, tuple)):
        yield from flatten(np.asarray(value), prefix, npy)
    else:
        raise ArrayTooLarge(f"field {name!r}: a {type(value).__name__} has no CSV form")


def rows(value: Any, npy: Any = None) -> list[dict[str, Any]]:
    """The CSV rows of one message: one, or one per object/pose (with ``index``). A field
    named ``t_ns`` (a Trajectory2D's pose times) is the column ``msg.t_ns``: ``t_ns`` is the
    sample's time."""
    return [{("msg.t_ns" if k == "t_ns" else k): v for k, v in row.items()} for row in _rows(value, npy)]


def _rows(value: Any, npy: Any = None) -> list[dict[str, Any]]:
    n = _row_length(value)
    if n is None:
        return [dict(flatten(value, npy=npy))]
    per_row, common = {}, {}
    for f in dataclasses.fields(value):
        v = getattr(value, f.name)
        if isinstance(v, np.ndarray) and v.ndim >= 1 and v.shape[0] == n and (v.size or n == 0):
            per_row[f.name] = v
        elif not (isinstance(v, np.ndarray) and v.size == 0):
            common.update(flatten(v, f"{f.name}.", npy))
    if n == 0:
        return [{"index": "", **common}]
    out = []
    for i in range(n):
        row: dict[str, Any] = {"index": i}
        for k, v in per_row.items():
            row.update(flatten(v[i], f"{k}.", npy))
        out.append({**row, **common})
    return out


def _check_args(args: argparse.Namespace) -> None:
    """Usage errors before the recording is read (exit 2, one line): no format or two, a window that is not
    finite seconds, outputs that cannot be written or would land on the recording."""
    if bool(args.csv) == bool(args.ros2):
        raise CommandError("export: give one output format, --csv (with --topic) or --ros2 OUT.mcap", EXIT_USAGE)
    if args.csv and not args.topic:
        raise CommandError("export --csv: --topic is required (the topic written as CSV)", EXIT_USAGE)
    if args.native and not args.ros2:
        raise CommandError("export: --native goes with --ros2", EXIT_USAGE)
    if args.ros2 and (args.output or args.npy):
        raise CommandError("export --ros2: -o and --npy are CSV options (the ROS 2 file is --ros2's)", EXIT_USAGE)
    for option, value in (("--start-s", args.start_s), ("--end-s", args.end_s)):
        if value is not None and not (math.isfinite(value) and 0 <= value <= MAX_SECONDS):
            raise CommandError(f"{option} {value}: expected finite seconds in [0, {MAX_SECONDS:.3g}]", EXIT_USAGE)
    if args.start_s is not None and args.end_s is not None and args.end_s <= args.start_s:
        raise CommandError(f"--end-s {args.end_s} <= --start-s {args.start_s}: nothing to export", EXIT_USAGE)
    inputs = [(args.file, "the recording")]
    if args.ros2:
        check_writable_file(args.ros2, "--ros2")
        clash = output_clash(args.ros2, inputs)
        if clash:
            raise CommandError(f"--ros2: {clash}", EXIT_USAGE)
    if args.output:
        check_writable_file(args.output, "-o")
        clash = output_clash(args.output, inputs)
        if clash:
            raise CommandError(f"-o: {clash}", EXIT_USAGE)
    if args.npy:
        why = not_writable(args.npy, "write_dir")
        clash = why or output_clash(args.npy, inputs + ([(args.output, "the -o file")] if args.output else []))
        if clash:
            raise CommandError(f"--npy {args.npy}: {clash}", EXIT_USAGE)


def run(args: argparse.Namespace) -> int:
    _check_args(args)
    if args.ros2:
        from ._export_ros2 import export_ros2

        return export_ros2(args)
    npy_dir = Path(args.npy) if args.npy else None
    try:
        with open_recording(args.file, codecs()) as r:
            if args.topic not in r.topics:
                raise CommandError(f"{args.file}: no topic {args.topic!r} (recorded: "
                                   f"{', '.join(sorted(r.topics))})", EXIT_USAGE)
            lo, hi = window(r, args)
            header: dict[str, None] = {}  # every column of every row, first seen first
            try:
                for m in r.messages([args.topic], lo, hi):
                    for row in rows(m.data, npy=(lambda name, a: "") if npy_dir else None):
                        header.update(dict.fromkeys(row))
            except ArrayTooLarge as e:
                raise CommandError(f"{args.file}: topic {args.topic!r}: {e}", EXIT_FAILED) from None
            loss = loss_line(r, args.topic)
            if loss and not args.allow_loss:
                raise CommandError(loss, EXIT_FAILED)
            n = _write(r, args, lo, hi, list(header), npy_dir)
    except RecordingError as e:
        raise CommandError(str(e), EXIT_FAILED) from None
    print(f"{args.topic}: {n} rows" + (f" ({loss.split(': ', 1)[1].split(';')[0]})" if loss else ""),
          file=sys.stderr)
    return 0


def _write(r: MissionReader, args: argparse.Namespace, lo: int | None, hi: int | None, header: list[str],
           npy_dir: Path | None) -> int:
    out = open(args.output, "w", newline="", encoding="utf-8") if args.output else sys.stdout
    k = 0

    def save(name: str, a: np.ndarray) -> str:
        assert npy_dir is not None
        npy_dir.mkdir(parents=True, exist_ok=True)
        file = f"{name.replace('.', '_')}_{k:06d}.npy"
        np.save(npy_dir / file, a, allow_pickle=False)
        return file

    try:
        writer = csv.writer(out)
        writer.writerow(["t_ns", *header])
        n = 0
        for k, m in enumerate(r.messages([args.topic], lo, hi)):  # noqa: B007 - k read by save()
            for row in rows(m.data, npy=save if npy_dir else None):
                writer.writerow([m.t_ns, *(row.get(c, "") for c in header)])
                n += 1
    finally:
        if out is not sys.stdout:
            out.close()
    return n
