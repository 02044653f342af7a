"""``impala-flow export FILE --ros2 OUT.mcap``: a recording as standard ROS 2 messages.

Every recorded topic (or ``--topic``) is written again through the ``ros2`` output format (the ros2 plugin's
:class:`~impala_flow.io.ForeignWriter`), alone (a file ``ros2 bag play`` plays as it is, header profile
``ros2``) or, with ``--native``, beside the native channels. The frame tree is rebuilt as the recorder builds
it: the first recorded of :data:`~impala_flow.io.VEHICLE_POSES` places ``vehicle`` (and ``radar`` on it, at the
vehicle's origin: the recorder's default mount), every other pose topic a frame of its own name. The file is
written as ``OUT.part`` and renamed when complete. Damaged chunks that held messages of the exported topics stop
the export (exit 1, no OUT written) unless ``--allow-loss``.
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Any

from ..io import VEHICLE_POSES, CodecError, MissionReader, MissionWriter, RecordingError
from ..msgs import Pose2D
from . import EXIT_FAILED, EXIT_USAGE, CommandError
from ._info import codecs
from .helpers import loss_line, window

__all__ = ["export_ros2", "frame_children"]


def frame_children(pose_topics: list[str]) -> dict[str, str]:
    """Pose topic -> the frame it places on /tf (the recorder's rule)."""
    vehicle = next((t for t in VEHICLE_POSES if t in pose_topics), None)
    return {t: ("vehicle" if t == vehicle else t) for t in pose_topics}


def export_ros2(args: argparse.Namespace) -> int:
    reg = codecs()
    part = f"{args.ros2}.part"  # renamed to OUT when complete: a failed export leaves no OUT behind
    try:
        with MissionReader(args.file, reg) as r:
            if args.topic and args.topic not in r.topics:
                raise CommandError(f"{args.file}: no topic {args.topic!r} (recorded: "
                                   f"{', '.join(sorted(r.topics))})", EXIT_USAGE)
            topics = [args.topic] if args.topic else sorted(r.topics)
            try:
                writer = MissionWriter(part, codecs=reg, foreign=("ros2",), native=args.native,
                                       foxglove=args.native, metadata=r.metadata() if args.native else None,
                                       flush_period_s=None)
            except CodecError as e:
                raise CommandError(f"export --ros2: {e}", EXIT_FAILED) from None
            with writer:
                n = _copy(r, writer, topics, *window(r, args))
            summary = writer.foreign_summary()["ros2"]
            losses = [line for t in topics if (line := loss_line(r, t))]
            if losses and not args.allow_loss:
                raise CommandError(losses[0].replace("nothing exported", "nothing written"), EXIT_FAILED)
        os.replace(part, args.ros2)
    except RecordingError as e:
        raise CommandError(str(e), EXIT_FAILED) from None
    finally:
        if os.path.exists(part):
            os.unlink(part)
    _print_summary(args, n, summary, losses)
    return 0


def _copy(r: MissionReader, writer: MissionWriter, topics: list[str], lo: int | None, hi: int | None) -> int:
    """Every sample of ``topics`` in [lo, hi] through ``writer``, with the recorder's frame tree; their count."""
    types = {t: r.topic_type(t) for t in topics}
    frames = frame_children([t for t in topics if types[t] is Pose2D])
    for t in topics:
        writer.add_topic(t, types[t], frames.get(t, ""))
    n = 0
    for m in r.messages(topics, lo, hi):
        writer.write(m.topic, m.t_ns, m.data, m.seq)
        n += 1
        child = frames.get(m.topic)
        if child is not None and isinstance(m.data, Pose2D):
            p = m.data
            tf: list[Any] = [(p.frame, child, p.x_m, p.y_m, 0.0, p.theta_rad)]
            if child == "vehicle":
                tf.append(("vehicle", "radar", 0.0, 0.0, 0.0, 0.0))
            writer.write_transforms(m.t_ns, tf)
    return n


def _print_summary(args: argparse.Namespace, n: int, summary: dict[str, Any], losses: list[str]) -> None:
    written = summary.get("messages", {})
    print(f"{args.ros2}: {sum(written.values())} ROS 2 messages from {n} samples"
          + (" (beside the native channels)" if args.native else ""), file=sys.stderr)
    for topic, count in written.items():
        print(f"  {topic}: {count}", file=sys.stderr)
    for what, value in summary.items():
        if what != "messages":
            print(f"  {what}: {value}", file=sys.stderr)
    for line in losses:
        print(f"  {line.split(': ', 1)[1].split(';')[0]}", file=sys.stderr)
