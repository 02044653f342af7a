"""``impala-flow import ros2 BAG -o FILE.mcap``: a rosbag2 recording (MCAP, ROS 2 messages) into a mission file.

The radar plugin owns ``impala-flow import`` (its dataset formats); this plugin adds the format ``ros2`` to it (its
hook runs last), or makes the command with ``ros2`` alone when no other plugin has it. The bag is read by the
engine's ``io.Replayer`` through this plugin's channel adapters and recorded by ``io.Recorder``: the radar topic
as ``radar/beams``, the truth topic as ``truth/pose``, as the other formats' import writes them.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from impala_flow import output_clash
from impala_flow.cli import EXIT_FAILED, EXIT_USAGE, CommandError
from impala_flow.cli.helpers import check_writable_file, open_session, record_source

from . import msgdefs
from .read.params import PARAMS, check_params

__all__ = ["add_import_ros2", "import_ros2", "RADAR_TYPES", "TRUTH_TYPES"]

RADAR_TYPES = tuple(msgdefs.schema_name(n) for n in ("sensor_msgs/Image", "messages/RadarFftDataMessage"))
TRUTH_TYPES = tuple(msgdefs.schema_name(n) for n in ("nav_msgs/Odometry", "geometry_msgs/PoseStamped",
                                                     "geometry_msgs/TransformStamped", "sensor_msgs/NavSatFix"))
TOPICS = {"beams": "radar/beams", "truth": "truth/pose"}
HELP = ("ros2: a rosbag2 recording (one .mcap file, or a rosbag2 folder: metadata.yaml and its split .mcap files) "
        "of ROS 2 messages: the radar from Navtech B-scan images (sensor_msgs/Image 8UC1/mono8/mono16, height = "
        "azimuths, width = bins, one per turn stamped at its first azimuth: beams spread over the turn) or Navtech "
        "FFT-data messages (per-azimuth times), the geometry from Navtech's configuration message or --config; the "
        "truth from nav_msgs/Odometry, geometry_msgs/PoseStamped or TransformStamped, or sensor_msgs/NavSatFix "
        "(local east-north of the first fix).")
EXAMPLES = ("  impala-flow import ros2 run.mcap -o mission.mcap\n"
            "  impala-flow import ros2 rosbag2_2026_01_10/ --radar /radar_data/b_scan_image --truth /odom \\\n"
            "      --config range_resolution_m=0.0438 --config azimuth_offset_deg=-0.95 -o mission.mcap")


def _config_item(text: str) -> tuple[str, str]:
    key, sep, value = text.partition("=")
    if not sep or key.strip() not in PARAMS:
        raise argparse.ArgumentTypeError(f"{text!r}: expected KEY=VALUE with KEY one of {', '.join(PARAMS)}")
    return key.strip(), value.strip()


def _add_ros2_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("ros2 (impala-flow import ros2 BAG)")
    g.add_argument("--radar", metavar="TOPIC", default=None,
                   help="ros2: the radar topic (default: the bag's only B-scan image or Navtech FFT-data topic)")
    g.add_argument("--truth", metavar="TOPIC", default=None,
                   help="ros2: the truth topic (default: the bag's only Odometry/PoseStamped/TransformStamped/"
                   "NavSatFix topic, else none)")
    g.add_argument("--config", metavar="KEY=VALUE", type=_config_item, action="append", default=[],
                   help="ros2: radar geometry, repeatable; keys: "
                   + "; ".join(f"{k}: {v[3]}" for k, v in PARAMS.items()))


def add_import_ros2(sub: argparse._SubParsersAction) -> None:
    """Add ``ros2`` to ``impala-flow import`` (made here when no plugin made it)."""
    p = sub.choices.get("import")
    if p is None:
        p = sub.add_parser("import", help="import a rosbag2 recording into an MCAP mission file",
                           description="Turn a recording into a mission file. " + HELP,
                           epilog="examples:\n" + EXAMPLES, formatter_class=argparse.RawDescriptionHelpFormatter)
        p.add_argument("format", choices=("ros2",), help="recording format")
        p.add_argument("folder", help="the rosbag2 .mcap file or folder")
        p.add_argument("-o", "--output", required=True, help="mission file to write (.mcap)")
        p.add_argument("--overwrite", action="store_true", help="replace an existing output file")
        p.add_argument("--compression", default="zstd", choices=("zstd", "lz4", "none"))
        p.add_argument("--no-progress", action="store_true")
        _add_ros2_arguments(p)
        p.set_defaults(func=import_ros2)
        return
    fmt = next(a for a in p._actions if a.dest == "format")
    fmt.choices = (*tuple(fmt.choices or ()), "ros2")
    p.description = f"{p.description or ''} {HELP}"
    p.epilog = f"{p.epilog or ''}\n{EXAMPLES}"
    _add_ros2_arguments(p)
    other = p.get_default("func")

    def dispatch(args: argparse.Namespace) -> int:
        if args.format == "ros2":
            return import_ros2(args)
        for name in ("radar", "truth"):
            if getattr(args, name) is not None:
                raise CommandError(f"--{name}: ros2 only", EXIT_USAGE)
        if args.config:
            raise CommandError("--config: ros2 only", EXIT_USAGE)
        return other(args)

    p.set_defaults(func=dispatch)


def _pick(topics: dict[str, str], types: tuple[str, ...], asked: str | None, what: str, needed: bool) -> str | None:
    if asked is not None:
        if asked not in topics:
            raise CommandError(f"--{what}: no topic {asked!r} in the bag (topics: {', '.join(sorted(topics))})",
                               EXIT_USAGE)
        if topics[asked] not in types:
            raise CommandError(f"--{what} {asked}: its type {topics[asked]} is not one of {', '.join(types)}",
                               EXIT_USAGE)
        return asked
    found = sorted(t for t, s in topics.items() if s in types)
    if len(found) > 1:
        raise CommandError(f"several {what} topics ({', '.join(found)}): choose one with --{what}", EXIT_USAGE)
    if not found and needed:
        raise CommandError(f"no {what} topic in the bag (types {', '.join(types)}; topics: "
                           f"{', '.join(f'{t} ({s})' for t, s in sorted(topics.items()))})", EXIT_FAILED)
    return found[0] if found else None


def import_ros2(args: argparse.Namespace) -> int:
    from impala_flow.io import RecordingError, Replayer, open_recording, run_codecs

    bag, out = str(args.folder), str(args.output)
    if not os.path.exists(bag):
        raise CommandError(f"{bag}: no such file or folder", EXIT_USAGE)
    clash = output_clash(out, [(bag, "the bag")])
    if clash:
        raise CommandError(f"-o {clash}", EXIT_USAGE)
    check_writable_file(out, "-o")
    if os.path.exists(out) and not args.overwrite:
        raise CommandError(f"-o '{out}' exists: --overwrite replaces it", EXIT_USAGE)
    try:
        params = check_params(dict(args.config))
    except ValueError as e:
        raise CommandError(f"--config {e}", EXIT_USAGE) from None
    session = open_session()
    try:
        with open_recording(bag, run_codecs(session.registry), adapter_params=params) as r:
            topics = r.topics
    except RecordingError as e:
        raise CommandError(str(e), EXIT_FAILED) from None
    radar = _pick(topics, RADAR_TYPES, args.radar, "radar", True)
    truth = _pick(topics, TRUTH_TYPES, args.truth, "truth", False)
    assert radar is not None
    streams, rename = [radar], {radar: "beams"}
    if truth is not None:
        streams.append(truth)
        rename[truth] = "truth"
    src = Replayer("ros2", path=bag, streams=streams, rename=rename, adapter_params=params)
    ports = {p: t for p, t in TOPICS.items() if p in rename.values()}
    tmp = Path(out).with_name(f".{Path(out).name}.{os.getpid()}.part")
    try:
        code = record_source(session, src, str(tmp), ports, args.compression,
                             progress=False if args.no_progress else None, quiet=True)
        if code == 0:
            os.replace(tmp, out)
    finally:
        tmp.unlink(missing_ok=True)
    if code == 0:
        print("\n".join(_report(out, bag, radar, truth, topics, src.summary())))
    return code


def _report(out: str, bag: str, radar: str, truth: str | None, topics: dict[str, str], summary: dict) -> list[str]:
    from impala_flow.io import MissionReader

    with MissionReader(out) as r:
        counts = {c.topic: c.count for c in r.info().channels}
    lines = [f"imported:     {out}", f"bag:          {bag}", f"radar:        {radar} ({topics[radar]}): "
             f"{counts.get(TOPICS['beams'], 0)} beams on {TOPICS['beams']}"]
    lines.append(f"truth:        {truth} ({topics[truth]}): {counts.get(TOPICS['truth'], 0)} poses on "
                 f"{TOPICS['truth']}" if truth else "truth:        none (no --truth, no pose or fix topic)")
    for port, notes in summary.get("adapted", {}).items():
        lines += [f"{port + ':':13} {n}" for n in notes]
    others = sorted(set(topics) - {radar, truth})
    if others:
        lines.append(f"not imported: {', '.join(f'{t} ({topics[t]})' for t in others)}")
    for key, what in (("late", "samples dropped, later than the reordering window"),
                      ("lost", "messages lost in damaged chunks")):
        if summary.get(key):
            lines.append(f"{key + ':':13} " + ", ".join(f"{t}: {n}" for t, n in summary[key].items()) + f" ({what})")
    return lines
