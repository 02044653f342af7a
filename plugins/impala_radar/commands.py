"""The radar plugin's subcommands: ``impala-flow simulate`` and ``impala-flow import``."""

from __future__ import annotations

import argparse
from pathlib import Path

from impala_flow.cli import EXIT_USAGE, CommandError
from impala_flow.cli._common import open_session, record_source

from .sources import OXFORD_TOPICS, SIM_TOPICS, OxfordScans, Simulator

__all__ = ["add_commands"]


def _duration_s(text: str) -> float:
    """'60', '60s', '2min', '1.5h' -> seconds."""
    t = text.strip().lower()
    for suffix, k in (("min", 60.0), ("ms", 1e-3), ("h", 3600.0), ("s", 1.0)):
        if t.endswith(suffix):
            t, scale = t[: -len(suffix)], k
            break
    else:
        scale = 1.0
    try:
        v = float(t) * scale
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a duration: {text!r} (e.g. 60s, 2min)") from None
    if v <= 0:
        raise argparse.ArgumentTypeError(f"duration must be positive: {text!r}")
    return v


def add_commands(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate", help="simulate a radar mission into an MCAP file",
        description="Simulate a scenario (radar beams with speckle, clutter, Doppler and motion distortion, "
        "odometer, gyro, RTK-GPS truth, truth of movers) and record it as a mission file that "
        "'impala-flow replay' and the io.Replayer play back. Topics: " + ", ".join(SIM_TOPICS.values()) + ".",
        epilog="examples:\n  impala-flow simulate beynes -o beynes.mcap --duration 60s\n"
        "  impala-flow simulate graphs/scenarios/datmo.yaml -o datmo.mcap --seed 3",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("scenario", help="scenario name (beynes, campus-open, campus-loop, semi-urban, datmo) or YAML file")
    p.add_argument("-o", "--output", required=True, help="mission file to write (.mcap)")
    p.add_argument("--duration", type=_duration_s, default=None, help="mission length, e.g. 60s, 5min "
                   "(default: the scenario's full length)")
    p.add_argument("--seed", type=int, default=None, help="seed of the world and the sensor noise")
    p.add_argument("--compression", default="zstd", choices=("zstd", "lz4", "none"))
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=_simulate)

    p = sub.add_parser(
        "import", help="import recorded real radar data into an MCAP mission file",
        description="Turn a dataset folder into a mission file with the same beam messages the simulator "
        "produces (power only, no Doppler; per-beam timestamps and azimuths from the files) and a truth "
        "pose stream. Formats: oxford (Navtech polar PNGs of the Oxford Radar RobotCar dataset, also "
        "MulRan and Boreas, with gt/radar_odometry.csv).",
        epilog="example:\n  impala-flow import oxford data/oxford-radar-robotcar-sample -o oxford.mcap",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("format", choices=("oxford",), help="dataset format")
    p.add_argument("folder", help="dataset folder (holding radar/ and gt/)")
    p.add_argument("-o", "--output", required=True, help="mission file to write (.mcap)")
    p.add_argument("--compression", default="zstd", choices=("zstd", "lz4", "none"))
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=_import)


def _simulate(args: argparse.Namespace) -> int:
    session = open_session()
    params: dict = {"scenario": args.scenario}
    if args.seed is not None:
        params["seed"] = args.seed
    if args.duration is not None:
        params["duration_s"] = float(args.duration)
    try:
        sim = Simulator("sim", **params)
        sim.start()  # loads and checks the scenario now, for a one-line usage error
    except (FileNotFoundError, ValueError, KeyError) as e:
        raise CommandError(f"scenario {args.scenario!r}: {e}", EXIT_USAGE) from None
    return record_source(session, sim, args.output, SIM_TOPICS, args.compression,
                         progress=False if args.no_progress else None)


def _import(args: argparse.Namespace) -> int:
    session = open_session()
    folder = Path(args.folder)
    if not (folder / "radar").is_dir():
        raise CommandError(f"{folder}: no radar/ folder of Navtech PNG scans", EXIT_USAGE)
    src = OxfordScans("oxford", folder=str(folder))
    return record_source(session, src, args.output, OXFORD_TOPICS, args.compression,
                         progress=False if args.no_progress else None)
