"""The radar plugin's subcommands: ``impala-flow simulate``, ``impala-flow import`` and
``impala-flow navtech-server``."""

from __future__ import annotations

import argparse
import os
import secrets
import stat
from collections.abc import Callable
from pathlib import Path

from impala_flow import Session, output_clash
from impala_flow.cli import EXIT_FAILED, EXIT_USAGE, CommandError
from impala_flow.cli.helpers import open_session, record_source

from .datasets.component import DATASET_SOURCES, DATASET_TOPICS
from .simulator.component import SIM_TOPICS, Simulator

__all__ = ["add_commands", "simulate_mission"]


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
    if not 0 < v <= 86_400.0:  # finite: a simulated mission of at most a day
        raise argparse.ArgumentTypeError(f"duration must be positive and at most a day: {text!r}")
    return v


def _output_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("-o", "--output", required=True, help="mission file to write (.mcap); written as a hidden "
                   "'.NAME.*.part' beside it and renamed when complete, so a failed or interrupted run leaves "
                   "nothing. Refused before any work: a path equal to, inside or over an input, an existing "
                   "folder, device or pipe, and an existing file unless --overwrite")
    p.add_argument("--overwrite", action="store_true",
                   help="replace an existing output file (only once the new one is complete)")


def check_output(output: str, inputs: list[tuple[str, str]], overwrite: bool) -> Path:
    """``output`` as a path, or a one-line :class:`CommandError` (exit 2) before any work: it
    is, lies inside or holds one of ``inputs`` (links resolved), it exists and is not a
    regular file (a folder, device, pipe, broken link: never replaced), it is an existing file
    and ``overwrite`` is not set, or its folder cannot be created."""
    if not output.strip():
        raise CommandError("-o: empty path", EXIT_USAGE)
    clash = output_clash(output, inputs)
    if clash:
        raise CommandError(f"-o {clash}", EXIT_USAGE)
    out = Path(output)
    try:
        st = out.stat() if os.path.lexists(out) else None
    except OSError as e:  # a link to nothing or into a folder we may not read
        raise CommandError(f"-o '{output}': {e.strerror or e} (a link to nothing?): not replaced", EXIT_USAGE) from None
    if st is not None:
        if stat.S_ISDIR(st.st_mode):
            raise CommandError(f"-o '{output}' is a folder: give a file name, e.g. '{out / 'mission.mcap'}'",
                               EXIT_USAGE)
        if not stat.S_ISREG(st.st_mode):
            raise CommandError(f"-o '{output}' exists and is not a regular file (device, pipe or socket): "
                               "never replaced; write elsewhere", EXIT_USAGE)
        if not overwrite:
            raise CommandError(f"-o '{output}' exists: --overwrite replaces it (once the new file is complete)",
                               EXIT_USAGE)
    parent = out.absolute().parent
    while not parent.exists() and parent != parent.parent:
        parent = parent.parent
    if not parent.is_dir():
        raise CommandError(f"-o '{output}': its folder cannot be created, '{parent}' is a file", EXIT_USAGE)
    if not os.access(parent, os.W_OK | os.X_OK):
        raise CommandError(f"-o '{output}': no permission to write in '{parent}'", EXIT_USAGE)
    try:
        name_max = os.pathconf(parent, "PC_NAME_MAX")
    except (OSError, ValueError):
        name_max = 255
    if len(os.fsencode(out.name)) > name_max:
        raise CommandError(f"-o: a file name of {len(os.fsencode(out.name))} bytes, longer than the file system "
                           f"allows ({name_max})", EXIT_USAGE)
    return out


def write_output(out: Path, overwrite: bool, write: Callable[[str], int]) -> int:
    """Run ``write(tmp)`` on a new hidden file beside ``out`` and rename it to ``out`` only when
    it returns 0; on any failure or interruption the file is removed, and so are the folders
    made for it (when still empty). Without ``overwrite`` the rename never replaces a file that
    appeared meanwhile. Returns ``write``'s exit code."""
    made: list[Path] = []
    d = out.absolute().parent
    while not d.exists():
        made.append(d)
        d = d.parent
    tmp: Path | None = None
    done = False
    try:
        for folder in reversed(made):
            folder.mkdir()
        tmp = out.with_name(f".{out.name[:100]}.{os.getpid()}.{secrets.token_hex(4)}.part")
        try:
            os.close(os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))  # ours alone, mode from the umask
        except OSError as e:
            tmp = None
            raise CommandError(f"-o '{out}': cannot create a file in '{out.parent}' ({e.strerror or e})",
                               EXIT_USAGE) from None
        code = write(str(tmp))
        if code == 0:
            _publish(tmp, out, overwrite)
            done = True
        return code
    finally:
        if not done:
            if tmp is not None:
                tmp.unlink(missing_ok=True)
            for folder in made:  # deepest first; never a folder that is not empty
                try:
                    folder.rmdir()
                except OSError:
                    break


def _publish(tmp: Path, out: Path, overwrite: bool) -> None:
    if overwrite:
        st = os.lstat(out) if os.path.lexists(out) else None
        if st is not None and not (stat.S_ISREG(st.st_mode) or stat.S_ISLNK(st.st_mode)):
            raise CommandError(f"-o '{out}' became a folder or a device during the run: not replaced")
        os.replace(tmp, out)
        return
    try:
        os.link(tmp, out)  # atomic, and fails if out exists
    except FileExistsError:
        raise CommandError(f"-o '{out}' was created by something else during the run: not overwritten "
                           "(--overwrite replaces it)") from None
    except OSError:  # no hard links on this file system
        if os.path.lexists(out):
            raise CommandError(f"-o '{out}' was created by something else during the run: not overwritten "
                               "(--overwrite replaces it)") from None
        os.replace(tmp, out)
        return
    tmp.unlink()


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
    p.add_argument("scenario", help="scenario name (beynes, campus-open, campus-loop, semi-urban, datmo, urban) "
                   "or YAML file")
    _output_arguments(p)
    p.add_argument("--duration", type=_duration_s, default=None, help="mission length, e.g. 60s, 5min "
                   "(default: the scenario's full length)")
    p.add_argument("--seed", type=int, default=None, help="seed of the world and the sensor noise")
    p.add_argument("--epoch-utc", default=None, metavar="DATE",
                   help="UTC date and time the mission starts at (default 2026-01-01T00:00:00Z; '' for t = 0)")
    p.add_argument("--compression", default="zstd", choices=("zstd", "lz4", "none"))
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=_simulate)

    p = sub.add_parser(
        "import", help="import recorded real radar data (Oxford, Boreas, RADIATE) into an MCAP mission file",
        description="Turn a dataset folder into a mission file with the same beam messages the simulator "
        "produces (power only, no Doppler), each with its own timestamp and azimuth (counter-clockwise, "
        "0 = forward) in acquisition order, and the dataset's truth poses on truth/pose. The sensor's "
        "numbers (bins, range per bin, range of bin 0, beams per turn, rotation rate) come from the "
        "dataset and travel with every beam. Formats: oxford (Oxford Radar RobotCar: radar/<us>.png, "
        "gt/radar_odometry.csv), boreas (Boreas: radar/<us>.png, applanix/radar_poses.csv), radiate "
        "(RADIATE: Navtech_Polar/, Navtech_Polar.txt, GPS_IMU_Twist/). Real logs are read as recorded: "
        "times going back or repeated, gaps, late frame stamps, GPS fixes written twice or stale, a GPS "
        "clock stepping back, missing GPS files are dropped or fixed and said, one line each, in the "
        "printed block (and the file's metadata), with what the truth is. Bad input stops the import "
        "with one line naming the file and the row or scan, and leaves no output file.",
        epilog="examples:\n  impala-flow import oxford data/oxford-radar-robotcar-sample -o oxford.mcap\n"
        "  impala-flow import boreas data/boreas-2021-09-02-11-42 -o boreas.mcap\n"
        "  impala-flow import radiate data/fog_6_0 -o fog.mcap",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("format", choices=tuple(DATASET_SOURCES), help="dataset format")
    p.add_argument("folder", help="dataset folder (oxford/boreas: holding radar/; radiate: holding Navtech_Polar/)")
    _output_arguments(p)
    p.add_argument("--range-resolution-m", type=float, default=None, metavar="M",
                   help="range per bin (default: oxford 0.0438, measured on the sample's ground truth where the "
                   "dataset's README says 0.0432; boreas by date, 0.0596 before 2021-09-21 and 0.04381 after; "
                   "radiate 0.17361)")
    p.add_argument("--azimuth-offset-deg", type=float, default=None, metavar="DEG",
                   help="constant added to every azimuth, counter-clockwise positive (default: the format's, "
                   "measured: oxford -0.95, radiate -2.3, boreas 0)")
    p.add_argument("--db-per-count", type=float, default=0.5, metavar="DB",
                   help="log scale of the pixels: beams carry linear power 10^(count x DB / 10) (default 0.5)")
    p.add_argument("--range-offset-bins", type=float, default=None, metavar="BINS",
                   help="range of bin 0 in bins (default: oxford and radiate 0.5, bin centres as their SDKs "
                   "draw them; boreas -0.31 m, the offset its documentation gives)")
    p.add_argument("--keep-frame-stamps", action="store_true",
                   help="radiate: beam times from the frame stamps as written (default: frames stamped late, "
                   "when the logger fell behind, are put back on the radar's turn clock)")
    p.add_argument("--gps-offset-s", type=float, default=None, metavar="S",
                   help="radiate: the GPS's stamps are this late against the radar's clock, a fix stamped t is "
                   "taken at t - S (default 1.55, measured on the Edinburgh sequence; 0: as stamped)")
    p.add_argument("--skip-bad-scans", action="store_true",
                   help="skip unreadable scans (counted and reported with their reason) instead of failing")
    p.add_argument("--compression", default="zstd", choices=("zstd", "lz4", "none"))
    p.add_argument("--no-progress", action="store_true")
    p.set_defaults(func=_import)
    _add_navtech_server(sub)


def _add_navtech_server(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "navtech-server", help="emulate a Navtech radar: serve a dataset folder or a mission over TCP",
        description="Serve recorded radar scans over Navtech's Colossus TCP protocol, as a Navtech radar "
        "would: the configuration on connection, keep-alives to an idle client, and, once the client asks "
        "for FFT data, one FFT message per azimuth at the recorded pace (x --speed) with the recorded device "
        "times. A client that reconnects gets the beams of the time it comes back at (those due meanwhile are "
        "not sent, and counted). SOURCE is a dataset folder (oxford, boreas, radiate; detected, or --format) "
        "or an imported mission (.mcap with radar/beams). The graph side is radar.NavtechRadar "
        "(docs/live.md). Prints the port it listens on, then, at the end (end of the recording without "
        "--loop, or Ctrl-C), what it sent.",
        epilog="examples:\n"
        "  impala-flow navtech-server data/oxford-radar-robotcar-sample\n"
        "  impala-flow navtech-server data/radiate-edinburgh-head --loop --jitter-ms 20\n"
        "  impala-flow navtech-server mission.mcap --port 0 --drop-after 5   # a free port; cut every 5 s",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("source", help="dataset folder (oxford, boreas, radiate) or imported mission (.mcap)")
    p.add_argument("--format", default=None, choices=tuple(DATASET_SOURCES),
                   help="dataset format of a folder (default: detected: Navtech_Polar/ = radiate, radar/ with "
                   "applanix/ = boreas, radar/ = oxford)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1: this machine "
                   "only; 0.0.0.0 serves the network)")
    p.add_argument("--port", type=int, default=6317, help="TCP port (default 6317, Navtech's; 0: a free port, "
                   "printed)")
    p.add_argument("--speed", type=float, default=1.0,
                   help="pace as a multiple of real time (default 1): a radar turning X times faster, its clock at "
                   "real time (device times compressed by X, rotation rate x X)")
    p.add_argument("--loop", action="store_true", help="restart the recording at its end (device times run on)")
    p.add_argument("--jitter-ms", type=float, default=0.0, metavar="J",
                   help="delay each send by a random 0..J ms (network jitter; the device stamps are unchanged)")
    p.add_argument("--drop-after", type=float, default=None, metavar="S",
                   help="cut each client's connection after S seconds (a lost link; the next connection is "
                   "served from the time it comes at)")
    p.add_argument("--high-precision", action="store_true",
                   help="send 16-bit FFT data (type 31) instead of 8-bit (type 30)")
    p.add_argument("--azimuth-offset-deg", type=float, default=0.0, metavar="DEG",
                   help="a mission's beams: the azimuth offset its import added, removed to get the encoder "
                   "counts back (default 0: the recorded azimuths; dataset folders are read without offset)")
    p.add_argument("--db-per-count", type=float, default=0.5, metavar="DB",
                   help="log scale of the samples: a beam's linear power P is sent as the count "
                   "10 log10(P) / DB (default 0.5, Navtech's)")
    p.add_argument("--seed", type=int, default=0, help="seed of the jitter (default 0)")
    p.set_defaults(func=_navtech_server)


def _navtech_server(args: argparse.Namespace) -> int:
    from .navtech.server import serve_command

    return serve_command(args)


def _simulate(args: argparse.Namespace) -> int:
    from .simulator.scenario import ScenarioError, scenario_path

    try:
        inputs = [(str(scenario_path(args.scenario)), "the scenario file")]
    except ScenarioError:
        inputs = []  # reported below, with the valid names
    out = check_output(args.output, inputs, args.overwrite)
    session = open_session()
    sim = _simulator(args.scenario, args.seed, args.duration, args.epoch_utc)
    code = write_output(out, args.overwrite, lambda tmp: record_source(
        session, sim, tmp, SIM_TOPICS, args.compression, progress=False if args.no_progress else None))
    if code == 0:
        print(f"simulated:    {out} (recorded as the summary's .part file, renamed when complete)")
    return code


def _simulator(scenario: str, seed: int | None = None, duration_s: float | None = None,
               epoch_utc: str | None = None) -> Simulator:
    """The simulator of ``scenario``, started (the scenario loaded and checked now, for a
    one-line usage error, exit 2)."""
    params: dict = {"scenario": scenario}
    if seed is not None:
        params["seed"] = seed
    if duration_s is not None:
        params["duration_s"] = float(duration_s)
    if epoch_utc is not None:
        params["epoch_utc"] = epoch_utc
    try:
        sim = Simulator("sim", **params)
        sim.start()
    except (FileNotFoundError, ValueError, KeyError) as e:
        raise CommandError(f"scenario {scenario!r}: {e}", EXIT_USAGE) from None
    return sim


def simulate_mission(session: Session, scenario: str, path: str, *, seed: int | None = None,
                     duration_s: float | None = None) -> None:
    """The mission source ``simulate`` (``registry.mission_sources``): record ``scenario``
    simulated with ``seed`` for ``duration_s`` into ``path``, the same code and so the same
    bytes as ``impala-flow simulate SCENARIO -o PATH --seed N --duration Xs``. Raises
    :class:`CommandError` (one line) when the scenario is bad or the recording fails."""
    code = record_source(session, _simulator(scenario, seed, duration_s), path, SIM_TOPICS, "zstd", progress=False)
    if code != 0:
        raise CommandError(f"recording {path}: interrupted", code)


def _dataset_error(e: BaseException) -> BaseException | None:
    """The DatasetError behind a recording failure (component error chain), if any."""
    from .datasets.common import DatasetError

    while e is not None:
        if isinstance(e, DatasetError):
            return e
        e = e.__cause__
    return None


def _import(args: argparse.Namespace) -> int:
    from .datasets.common import DatasetError

    out = check_output(args.output, [(args.folder, "the dataset folder")], args.overwrite)
    session = open_session()
    params: dict = {"folder": str(Path(args.folder)), "skip_bad_scans": args.skip_bad_scans}
    if args.range_offset_bins is not None:
        params["range_offset_bins"] = args.range_offset_bins
    if args.azimuth_offset_deg is not None:
        params["azimuth_offset_deg"] = args.azimuth_offset_deg
    if args.keep_frame_stamps:
        if args.format != "radiate":
            raise CommandError("--keep-frame-stamps: radiate only (the other formats stamp every row)", EXIT_USAGE)
        params["retime"] = False
    if args.gps_offset_s is not None:
        if args.format != "radiate":
            raise CommandError("--gps-offset-s: radiate only (the other formats' truth is on the sensor's clock)",
                               EXIT_USAGE)
        params["gps_offset_s"] = args.gps_offset_s
    params["db_per_count"] = args.db_per_count
    if args.range_resolution_m is not None:
        params["range_resolution_m"] = args.range_resolution_m
    # every numeric option finite and within the source's bounds, named as the user typed it
    _, problems = DATASET_SOURCES[args.format].validate_params(params)
    for name, msg in problems.items():
        raise CommandError(f"--{name.replace('_', '-')}: {msg}", EXIT_USAGE)
    src = DATASET_SOURCES[args.format](args.format, **params)
    try:
        src.open()  # the folder and its first scan, before anything is written
    except DatasetError as e:
        raise CommandError(str(e), EXIT_FAILED) from None

    def record(tmp: str) -> int:
        try:
            return record_source(session, src, tmp, DATASET_TOPICS, args.compression,
                                 progress=False if args.no_progress else None, quiet=True)
        except CommandError as e:
            bad = _dataset_error(e)
            raise CommandError(str(bad) if bad is not None else str(e), e.code) from None

    code = write_output(out, args.overwrite, record)
    if code == 0:
        print("\n".join([f"imported:     {out}", *src.report.lines()]))
    return code
