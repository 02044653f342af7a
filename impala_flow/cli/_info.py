"""``impala-flow info FILE``: what a recording holds, and whether it is complete."""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
from dataclasses import asdict

from ..io import CodecRegistry, RecordingError, RecordingInfo, open_recording
from . import EXIT_FAILED, CommandError


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "info", help="describe a recording (MCAP)",
        description="Channels with schemas, counts and rates; start, end, duration, "
        "compression; whether the file is truncated (and how many messages were recovered) "
        "and any corrupt chunk or damaged record; attachments; how the recording was made (its "
        "metadata). --verify reads every chunk and checks every CRC and every index against the "
        "data; the counts are then the messages actually readable. Exit 1 on a damaged file (with "
        "--verify: on any problem, truncation included).",
        epilog="example: impala-flow info missions/beynes.mcap --verify",
    )
    p.add_argument("file", metavar="FILE", help="MCAP recording")
    p.add_argument("--verify", action="store_true",
                   help="read every chunk; check every CRC, chunk index, message index and the statistics")
    p.add_argument("--metadata", action="store_true", help="print the metadata records in full")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=run)


#: metadata records a source writes about what it read (e.g. an imported dataset), printed in full
SOURCE_METADATA = "impala_flow.source"


def codecs() -> CodecRegistry:
    """Standard types plus what the installed plugins register (standard only on failure)."""
    try:
        from ..plugins import load_registry

        return CodecRegistry.from_plugins(load_registry())
    except Exception:  # noqa: BLE001 - a broken plugin must not hide a file's description
        return CodecRegistry.with_standard_types()


#: stamps past 1990 are read as UNIX times (dated missions) and shown with their UTC date
_DATED_NS = 631_152_000 * 10**9


def _t(t_ns: int | None) -> str:
    if t_ns is None:
        return "-"
    s, ns = divmod(int(t_ns), 10**9)
    text = f"{s}.{ns:09d} s"
    if t_ns >= _DATED_NS:
        d = datetime.datetime.fromtimestamp(s, tz=datetime.UTC)
        text += f" ({d:%Y-%m-%d %H:%M:%S}.{ns // 1000:06d} UTC)"
    return text


def format_info(info: RecordingInfo, metadata: bool = False) -> str:
    state = "complete, verified" if info.verified else "complete"
    if info.truncated:
        state = f"TRUNCATED - {info.recovered_count} messages recovered"
        if info.mirror_count:
            state += f" (+ {info.mirror_count} Foxglove mirror copies)"
    elif info.problems or info.corrupt_chunks:
        state = f"DAMAGED - {len(info.problems)} problem{'s' if len(info.problems) != 1 else ''}"
    counts = "readable messages" if info.verified else "messages"
    lines = [
        f"file:         {info.path} ({info.size_bytes / 1e6:.1f} MB, {state})",
        f"start:        {_t(info.start_ns)}",
        f"end:          {_t(info.end_ns)}",
        f"duration:     {info.duration_s:.3f} s",
        f"{counts + ':':<14}{info.message_count} in {info.chunk_count} chunks, "
        f"compression {info.compression}"
        + (f" ({info.mirror_count} of them Foxglove mirror copies)" if info.mirror_count else ""),
        "channels:",
    ]
    width = max((len(c.topic) for c in info.channels), default=5)
    for c in info.channels:
        view = "ROS 2" if c.message_encoding == "cdr" else "Foxglove"  # cdr: the ros2 plugin's output format
        note = f" ({view} view of {c.mirror_of})" if c.mirror_of else (
            "" if c.decodable else " (no codec installed for this schema)")
        lines.append(f"  {c.topic:<{width}}  {c.count:>9}  {c.rate_hz:>9.2f} Hz  "
                     f"{c.schema} [{c.schema_encoding}]{note}")
    if info.corrupt_chunks:
        lines.append(f"corrupt chunks: {info.corrupt_chunks} (skipped)")
    lines += [f"problem: {p}" for p in info.problems]
    for name, media, n in info.attachments:
        lines.append(f"attachment {name}: {media or 'no media type'}, {n} bytes")
    for name, rec in info.metadata.items():
        if metadata or name.startswith(SOURCE_METADATA):  # what a source read: short, always in full
            lines.append(f"metadata {name}:")
            lines += [f"  {k}: {v}" for k, v in rec.items()]
        else:
            lines.append(f"metadata {name}: {', '.join(rec) or '(empty)'}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    try:
        with open_recording(args.file, codecs()) as r:
            if args.verify:
                problems = r.verify()
                info = dataclasses.replace(r.info(), problems=tuple(problems))
            else:
                info = r.info()
    except RecordingError as e:
        raise CommandError(str(e), EXIT_FAILED) from None
    if args.json:
        d = asdict(info)
        d["duration_ns"] = info.duration_ns
        print(json.dumps(d, default=str))
    else:
        print(format_info(info, args.metadata))
    if args.verify:  # anything short of a whole, sound file
        return 0 if info.complete else EXIT_FAILED
    return EXIT_FAILED if info.problems or info.corrupt_chunks else 0  # a cut file is described
