"""The chain live against a Navtech radar emulator: latency, drops, live = replay (issue 27).

``impala-flow navtech-server`` serves real scans (by default the first 400 turns of the real
RADIATE drive, ``$IMPALA_FLOW_TEST_DATA/radiate-edinburgh-head``) over Navtech's protocol on
loopback, in its own process, as a radar would; ``graphs/live_navtech.yaml`` runs against it
with ``impala-flow run --duration`` (its own process too: the user's command), then its
recording is replayed through ``graphs/live_navtech_replay.yaml`` and the poses compared.

Per speed (the emulator's pace, x real time): turns received and lost, turns dropped at a
stage (R-SLAM's input holds two turn images: an older one waiting is dropped whole), each
stage's latency (from the arrival of the beam that completed a turn to the stage's output for
that turn: median, p99, max), the CPU utilisation of the graph's process (``2.0``: both
cores busy), and the live poses against the replayed ones (bit-identical count). The fastest
speed the chain keeps up with: the fastest of ``--speeds`` with no turn dropped or lost and
R-SLAM's p99 latency under one turn period at that pace.

    python bench/live.py [--source DIR|MISSION] [--seconds 30] [--speeds 1,2,3] [--cut-after 10] [--out DIR]

The last line printed is one JSON object with the keys ``live_seconds_s``, and at 1x (the first
speed) ``live_turns``, ``live_turns_lost``, ``live_turns_dropped``,
``live_slam_latency_median_ms``, ``live_slam_latency_p99_ms``, ``live_odometry_latency_median_ms``,
``live_odometry_latency_p99_ms``, ``live_panoramic_latency_p99_ms``, ``live_cpu_cores``,
``live_stale_twist`` (turns imaged before R-SLAM's twist of the previous turn was back: 1
offline, the bootstrap's second image),
``live_replay_identical_poses``, ``live_replay_poses``, then ``live_fastest_speed_x``, the run
with a connection cut every ``--cut-after`` seconds (``live_cut_every_s``, ``live_cut_reconnects``,
``live_cut_turns``, ``live_cut_turns_lost``, ``live_cut_turns_dropped``, ``live_cut_slam_poses``) and
``peak_rss_mb`` (the largest of the child processes: a graph's, the emulator's being smaller).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import re
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
GRAPH = ROOT / "graphs" / "live_navtech.yaml"
REPLAY = ROOT / "graphs" / "live_navtech_replay.yaml"
POSE_TOPICS = ("slam/pose", "odometry/pose")


def _cli() -> list[str]:
    return [sys.executable, "-m", "impala_flow"]


def start_server(source: str, speed: float, out: Path, tag: str,
                 extra: tuple[str, ...] = ()) -> tuple[subprocess.Popen, int]:
    """The emulator in its own process on a free loopback port (the port it prints)."""
    path = out / f"server-{tag}.log"
    log = open(path, "w")  # noqa: SIM115 - closed with the process
    proc = subprocess.Popen([*_cli(), "navtech-server", source, "--port", "0", "--speed", f"{speed:g}", "--loop",
                             *extra], stdout=log, stderr=subprocess.STDOUT, text=True)
    deadline = time.monotonic() + 120.0
    while time.monotonic() < deadline:
        m = re.search(r"listening:\s+[\d.]+:(\d+)", path.read_text())
        if m:
            return proc, int(m.group(1))
        if proc.poll() is not None:
            break
        time.sleep(0.2)
    proc.kill()
    raise SystemExit(f"bench/live.py: the emulator did not start: {path.read_text()}")


def run_live(source: str, speed: float, seconds: float, out: Path, offset: float,
             cut_after_s: float | None = None) -> dict[str, Any]:
    """One live run against the emulator at ``speed`` (cutting the connection every
    ``cut_after_s``); the summary (JSON) and the CPU it took."""
    tag = f"x{speed:g}" if cut_after_s is None else f"x{speed:g}-cut{cut_after_s:g}s"
    run_out = out / tag
    run_out.mkdir(parents=True, exist_ok=True)
    extra = () if cut_after_s is None else ("--drop-after", f"{cut_after_s:g}")
    server, port = start_server(source, speed, out, tag, extra)
    summary = run_out / "summary.json"
    cmd = [*_cli(), "run", str(GRAPH), "--var", f"port={port}", "--var", f"out={run_out}", "--var", "view_port=0",
           "--var", f"azimuth_offset_deg={offset}",
           "--duration", f"{seconds:g}", "--no-progress", "--summary-json", str(summary)]
    before = os.times()
    try:
        res = subprocess.run(cmd, capture_output=True, text=True)
    finally:
        server.terminate()
        server.wait(30)
    after = os.times()
    (run_out / "run.log").write_text(res.stdout + res.stderr)
    if res.returncode != 0:
        raise SystemExit(f"bench/live.py: the live run failed ({res.returncode}):\n{res.stdout}{res.stderr}")
    s = json.loads(summary.read_text())
    cpu_s = (after.children_user - before.children_user) + (after.children_system - before.children_system)
    s["_cpu_cores"] = cpu_s / max(s["wall_s"], 1e-9)
    s["_stdout"] = res.stdout
    return s


def replay(recording: Path, out: Path) -> Path:
    """The live recording through the offline chain; the replay's recording."""
    res = subprocess.run([*_cli(), "run", str(REPLAY), "--var", f"mission={recording}", "--var", f"out={out}",
                          "--no-progress"], capture_output=True, text=True)
    if res.returncode != 0:
        raise SystemExit(f"bench/live.py: the replay failed:\n{res.stdout}{res.stderr}")
    return out / "live_navtech_replay.mcap"


def compare_poses(live: Path, replayed: Path) -> dict[str, Any]:
    """Poses of the live run vs its replay, matched by time: identical ones, and the largest difference."""
    from impala_flow.io import MissionReader

    def poses(path: Path, topic: str) -> dict[int, tuple[float, float, float]]:
        with MissionReader(path) as r:
            if topic not in r.topics:
                return {}
            return {m.t_ns: (m.data.x_m, m.data.y_m, m.data.theta_rad) for m in r.messages([topic])}

    out: dict[str, Any] = {}
    for topic in POSE_TOPICS:
        a, b = poses(live, topic), poses(replayed, topic)
        common = sorted(set(a) & set(b))
        same = sum(a[t] == b[t] for t in common)
        diff = max((float(np.hypot(a[t][0] - b[t][0], a[t][1] - b[t][1])) for t in common), default=0.0)
        out[topic] = {"live": len(a), "replayed": len(b), "common": len(common), "identical": same,
                      "max_diff_m": diff}
    return out


def figures(s: dict[str, Any], speed: float) -> dict[str, Any]:
    """The figures of one live run out of its summary."""
    extra = s.get("extra", {})
    radar = extra.get("radar", {})
    lat = s.get("latency", {})
    drops = {k: v for k, v in s.get("inputs", {}).items() if k.startswith(("slam.", "odometry.", "panoramic."))}
    dropped = sum(v.get("dropped", 0) + v.get("dropped_maxbytes", 0) for v in drops.values())

    def ms(key: str, what: str) -> float:
        return float(lat.get(key, {}).get(what, float("nan")))

    return {"speed_x": speed, "turns": int(radar.get("turns", 0)), "turns_lost": int(radar.get("turns_lost", 0)),
            "turns_dropped": dropped, "reconnects": int(radar.get("reconnects", 0)),
            "slam_median_ms": ms("slam.pose", "median_ms"), "slam_p99_ms": ms("slam.pose", "p99_ms"),
            "slam_max_ms": ms("slam.pose", "max_ms"),
            "odometry_median_ms": ms("odometry.pose", "median_ms"), "odometry_p99_ms": ms("odometry.pose", "p99_ms"),
            "panoramic_median_ms": ms("panoramic.image", "median_ms"),
            "panoramic_p99_ms": ms("panoramic.image", "p99_ms"),
            "stale_twist": int(extra.get("panoramic", {}).get("stale_twist", 0)),
            "cpu_cores": s["_cpu_cores"], "wall_s": s["wall_s"]}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    data = os.environ.get("IMPALA_FLOW_TEST_DATA", str(ROOT.parent / "shared" / "data"))
    ap.add_argument("--source", default=str(Path(data) / "radiate-edinburgh-head"),
                    help="dataset folder or imported mission the emulator serves (default: the RADIATE drive's head)")
    ap.add_argument("--seconds", type=float, default=30.0, help="wall seconds of each live run (default 30)")
    ap.add_argument("--speeds", default="1,2,3", help="emulator paces tried, the first is the main one")
    ap.add_argument("--azimuth-offset-deg", type=float, default=-2.3,
                    help="the driver's azimuth offset (a dataset folder is served without it: RADIATE -2.3, "
                    "Oxford -0.95; default -2.3)")
    ap.add_argument("--cut-after", type=float, default=10.0,
                    help="one more run at the first speed with the emulator cutting the connection every S seconds "
                    "(a lost link: survived and reported; 0: none; default 10)")
    ap.add_argument("--out", default="out/bench-live", help="folder of the runs (recordings, summaries, logs)")
    args = ap.parse_args(argv)
    if not Path(args.source).exists():
        raise SystemExit(f"bench/live.py: no source at {args.source} (set IMPALA_FLOW_TEST_DATA or --source)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    speeds = [float(x) for x in args.speeds.split(",")]
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, Python "
          f"{platform.python_version()}; source {args.source}, {args.seconds:g} s per run")
    rows, first = [], None
    for speed in speeds:
        s = run_live(args.source, speed, args.seconds, out, args.azimuth_offset_deg)
        f = figures(s, speed)
        if first is None:
            first = (s, f)
        rows.append(f)
        print(f"x{speed:g}: {f['turns']} turns, lost {f['turns_lost']}, dropped {f['turns_dropped']}, "
              f"reconnects {f['reconnects']}; latency panoramic {f['panoramic_median_ms']:.1f} / "
              f"{f['panoramic_p99_ms']:.1f} ms, R-SLAM {f['slam_median_ms']:.1f} / {f['slam_p99_ms']:.1f} ms "
              f"(max {f['slam_max_ms']:.1f}), odometry {f['odometry_median_ms']:.1f} / {f['odometry_p99_ms']:.1f} ms "
              f"(median / p99); turns imaged with a stale twist {f['stale_twist']}; CPU {f['cpu_cores']:.2f} cores")
    period_ms = 250.0
    ok = [f["speed_x"] for f in rows if f["turns_dropped"] == 0 and f["turns_lost"] == 0 and f["turns"] > 0
          and f["slam_p99_ms"] < period_ms / f["speed_x"]]
    _, f1 = first
    rec = out / f"x{speeds[0]:g}" / "live.mcap"
    cmp = compare_poses(rec, replay(rec, out / f"x{speeds[0]:g}-replay"))
    for topic, c in cmp.items():
        print(f"live vs replay, {topic}: {c['identical']} of {c['common']} common poses identical "
              f"(live {c['live']}, replayed {c['replayed']}), largest difference {c['max_diff_m']:.3g} m")
    cut: dict[str, Any] = {}
    if args.cut_after > 0:
        s = run_live(args.source, speeds[0], args.seconds, out, args.azimuth_offset_deg, args.cut_after)
        f = figures(s, speeds[0])
        radar = s.get("extra", {}).get("radar", {})
        cut = {"live_cut_every_s": args.cut_after, "live_cut_reconnects": f["reconnects"],
               "live_cut_turns": f["turns"], "live_cut_turns_lost": f["turns_lost"],
               "live_cut_turns_dropped": f["turns_dropped"], "live_cut_slam_poses": s["emitted"].get("slam.pose", 0)}
        print(f"x{speeds[0]:g}, connection cut every {args.cut_after:g} s: exit 0, {f['reconnects']} reconnections, "
              f"{f['turns']} turns, lost {f['turns_lost']} (said: {radar.get('gaps', 'none')}), dropped "
              f"{f['turns_dropped']}, R-SLAM poses {cut['live_cut_slam_poses']}; R-SLAM latency "
              f"{f['slam_median_ms']:.1f} / {f['slam_p99_ms']:.1f} ms")
    rss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024  # the largest child: a graph, mostly
    result = {
        "live_seconds_s": args.seconds, "live_turns": f1["turns"], "live_turns_lost": f1["turns_lost"],
        "live_turns_dropped": f1["turns_dropped"], "live_slam_latency_median_ms": round(f1["slam_median_ms"], 2),
        "live_slam_latency_p99_ms": round(f1["slam_p99_ms"], 2),
        "live_odometry_latency_median_ms": round(f1["odometry_median_ms"], 2),
        "live_odometry_latency_p99_ms": round(f1["odometry_p99_ms"], 2),
        "live_panoramic_latency_p99_ms": round(f1["panoramic_p99_ms"], 2),
        "live_cpu_cores": round(f1["cpu_cores"], 2), "live_stale_twist": f1["stale_twist"],
        "live_replay_identical_poses": sum(c["identical"] for c in cmp.values()),
        "live_replay_poses": sum(c["common"] for c in cmp.values()),
        "live_fastest_speed_x": max(ok) if ok else 0.0,
        **cut,
        "peak_rss_mb": round(rss, 1),
    }
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
