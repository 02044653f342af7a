"""The view plugin's subcommand ``impala-flow view``: stream a recording to Foxglove live."""

from __future__ import annotations

import argparse
import sys

from impala_flow import ComponentError, Network
from impala_flow.cli import EXIT_FAILED, EXIT_INTERRUPTED, EXIT_OK, EXIT_USAGE, CommandError
from impala_flow.cli.helpers import Progress, check_speed, open_session
from impala_flow.io import TIME_JUMP, RecordingError, Replayer

from .bridge import MIN_BACKLOG, FoxgloveBridge

__all__ = ["add_commands"]


def add_commands(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "view", help="stream a recording to Foxglove over WebSocket (live view)",
        description="Replay FILE.mcap at --speed through view.FoxgloveBridge: open Foxglove, "
        "'Open connection' > 'Foxglove WebSocket', ws://HOST:PORT. Poses, trajectories, grids, point sets and "
        "object states come in Foxglove's schemas (3D panel), every other stream as JSON (Plot panel). "
        "Listens on 127.0.0.1 unless --host says otherwise. A client that reads slowly costs at most --client-mb "
        "(messages over --max-message-mb are not sent; nothing is sent while more than --max-clients are "
        "connected); every drop is counted in the summary. "
        "Ctrl-C stops. The same bridge works in any graph: add a component of type view.FoxgloveBridge.",
        epilog="example: impala-flow view out/beynes.mcap --speed 2 --loop",
    )
    p.add_argument("file", help="recording (MCAP)")
    p.add_argument("--port", default="8765", help="TCP port (default 8765; 0: any free port)")
    p.add_argument("--host", default="127.0.0.1", help="interface (default 127.0.0.1; 0.0.0.0: every interface)")
    p.add_argument("--speed", default="1", help="replay speed factor, or 'max' (default 1: real time)")
    p.add_argument("--loop", action="store_true", help="replay forever (mission time keeps increasing)")
    p.add_argument("--client-mb", default="128",
                   help="MiB of messages kept for a slow client; the oldest are dropped beyond (default 128)")
    p.add_argument("--max-message-mb", default="8",
                   help="largest message sent, MiB; larger ones are dropped and counted (default 8)")
    p.add_argument("--max-clients", default="4",
                   help="while more clients are connected, nothing is sent (default 4)")
    p.add_argument("--streams", nargs="*", default=[], metavar="PATTERN", help="topics to show (globs; default all)")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=run_view)


def _int(text: str, option: str, lo: int, hi: int) -> int:
    try:
        value = int(text)
    except ValueError:
        raise CommandError(f"{option} {text!r}: not an integer", EXIT_USAGE) from None
    if not lo <= value <= hi:
        raise CommandError(f"{option} {value}: must be in [{lo}, {hi}]", EXIT_USAGE)
    return value


def _mib(text: str, option: str) -> int:
    """A size in MiB (finite, > 0, at most 1 TiB) as bytes."""
    try:
        mib = float(text)
    except ValueError:
        raise CommandError(f"{option} {text!r}: not a number of MiB", EXIT_USAGE) from None
    if not 0 < mib <= 1 << 20:  # also refuses nan and inf
        raise CommandError(f"{option} {text}: must be > 0 and at most 1048576 MiB", EXIT_USAGE)
    return int(mib * (1 << 20))


def run_view(args: argparse.Namespace) -> int:
    check_speed(args.speed)
    port = _int(args.port, "--port", 0, 65535)
    max_clients = _int(args.max_clients, "--max-clients", 1, 1 << 16)
    client_bytes, max_message_bytes = _mib(args.client_mb, "--client-mb"), _mib(args.max_message_mb, "--max-message-mb")
    if max_message_bytes < 1024:
        raise CommandError(f"--max-message-mb {args.max_message_mb}: must be at least 1 KiB", EXIT_USAGE)
    held = FoxgloveBridge("view", client_bytes=client_bytes, max_message_bytes=max_message_bytes).backlog
    if held < MIN_BACKLOG:
        raise CommandError(f"--client-mb {args.client_mb}: holds {held} message(s) of --max-message-mb "
                           f"{args.max_message_mb}; at least {MIN_BACKLOG} are needed", EXIT_USAGE)
    session = open_session()
    try:
        rep = Replayer("mission", path=args.file, streams=list(args.streams), loops=0 if args.loop else 1)
    except (OSError, ValueError, RecordingError) as e:
        raise CommandError(str(e), EXIT_FAILED) from None
    topics = {port: f"mission.{port}" for port in rep.outputs if port != TIME_JUMP}
    bridge = FoxgloveBridge("view", topics=topics, host=args.host, port=port, announce=True,
                            client_bytes=client_bytes, max_message_bytes=max_message_bytes,
                            max_clients=max_clients)
    net = Network(name="view")
    net.add(rep)
    net.add(bridge)
    rep.registry = bridge.registry = session.registry
    for port in topics:
        net.connect(rep.outputs[port], bridge.inputs[port])
    speed = "max" if args.speed == "max" else float(args.speed)
    bar = Progress(net, enabled=False if args.no_progress else None, desc="view")
    try:
        summary = session.run(net, speed=speed, mode="replay", progress=bar)
    except ComponentError as e:
        raise CommandError(str(e), EXIT_FAILED) from None
    finally:
        bar.close()
    print(summary.format(), file=sys.stderr)
    return EXIT_INTERRUPTED if summary.interrupted else EXIT_OK
