"""Real-time executor benchmark: latency source -> sink (not a timed test).

A live source stamps 8-byte payloads with the shared mission clock (``now_ns()``) at a
rate that does not saturate the machine; the sink measures ``now_ns() - t`` for every
sample. Reported: median and p99 latency for a direct source -> sink connection and for a
source -> 2 pass-through components -> sink chain, and the drop counters (zero: the
inputs use the default ``block`` policy).

    python bench/engine_realtime.py [--samples 20000] [--rate 4000]

The last line printed is one JSON object:
``{"rt_latency_median_us": ..., "rt_latency_p99_us": ..., "rt_dropped": ...}`` (direct
connection; the chain's figures are printed above it).

``--oxford MISSION`` (issue 26, item 4): the recording replayed live through graphs/oxford.yaml
(panoramic builder -> R-SLAM and FMT side by side, evaluators) on the real-time executor, the
replayer paced at ``--speeds`` (mission time runs N times faster than the wall clock). Per
speed: the CPU utilisation of the process (``process_time / wall``: 2.0 = both cores busy),
each component's CPU per call (``thread_time`` around ``process``: its own thread's CPU, so the
sum over components shows how much of the wall the stages used together), the latency from the
arrival of a turn's last beam to the arrival of R-SLAM's and FMT's pose for that turn (wall ms),
and the samples dropped. JSON keys ``rt_oxford_*`` (at the first speed) and
``rt_oxford_fastest_speed`` (the fastest speed tried with nothing dropped and p99 latency under
one turn period), ``peak_rss_mb``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from impala_flow import Component, Input, Network, Output, Param, RealTimeExecutor, Source

PAYLOAD = b"\x00" * 8


class LiveTicker(Source):
    """Live source: ``n`` 8-byte payloads at ``rate`` Hz, stamped with ``now_ns()``."""

    live = True
    out = Output(bytes)
    n = Param(int, default=20_000, ge=1)
    rate = Param(float, default=4000.0, gt=0)

    def generate(self) -> Iterator[tuple[int, str, Any]]:
        period = 1.0 / self.rate
        due = time.perf_counter()
        sleep, clock = time.sleep, time.perf_counter
        for _ in range(self.n):
            due += period
            ahead = due - clock()
            if ahead > 0:
                sleep(ahead)
            yield self.now_ns(), "out", PAYLOAD


class Pass(Component):
    x = Input(bytes)
    y = Output(bytes)

    def process(self, t: int) -> None:
        self.y.emit(t, self.x.take())


class LatencySink(Component):
    x = Input(bytes)

    def start(self) -> None:
        self.lat: list[int] = []

    def process(self, t: int) -> None:
        self.x.take()
        self.lat.append(self.now_ns() - t)


def run(n: int, rate: float, hops: int) -> tuple[np.ndarray, int, float]:
    net = Network(name=f"rt-latency-{hops}")
    src = net.add(LiveTicker("src", n=n, rate=rate))
    prev = src.outputs["out"]
    for i in range(hops):
        p = net.add(Pass(f"pass{i}"))
        net.connect(prev, p.inputs["x"])
        prev = p.outputs["y"]
    sink = net.add(LatencySink("sink"))
    net.connect(prev, sink.inputs["x"])
    summary = RealTimeExecutor(net).run()
    lat = np.asarray(sink.lat, dtype=np.int64)
    if len(lat) != n:
        raise SystemExit(f"expected {n} samples at the sink, got {len(lat)}")
    lost = sum(sum(v.values()) for v in summary.drops().values())
    return lat / 1e3, lost, summary.wall_s


class ScaledClock:
    """The mission clock running ``speed`` times faster than the monotonic clock."""

    def __init__(self, speed: float) -> None:
        self.speed = speed
        self.epoch_ns = time.time_ns()
        self._mono0 = time.monotonic_ns()

    def now_ns(self) -> int:
        return self.epoch_ns + int((time.monotonic_ns() - self._mono0) * self.speed)


class Arrivals(Component):
    """Records ``(sample time, mission clock at arrival)`` of every sample (``beams``: per
    turn, the arrival of its last beam and its time span)."""

    x = Input(object)
    beams = Param(bool, default=False)

    def start(self) -> None:
        self.seen: list[tuple[int, int]] = []
        self.turns: dict[int, list[int]] = {}  # turn -> [first t, last t, arrival of the last]

    def process(self, t: int) -> None:
        v = self.x.take()
        now = self.now_ns()
        if not self.beams:
            self.seen.append((t, now))
            return
        span = self.turns.get(v.turn)
        if span is None:
            self.turns[v.turn] = [t, t, now]
        else:
            span[1], span[2] = t, now


def _timed(comp: Component, cpu: dict[str, list[float]]) -> None:
    """Wrap ``comp.process`` to add its own thread's CPU seconds per call to ``cpu[name]``."""
    inner, acc = comp.process, cpu.setdefault(comp.name, [])
    clock = time.thread_time

    def process(t: int) -> None:
        c0 = clock()
        try:
            inner(t)
        finally:
            acc.append(clock() - c0)

    comp.process = process  # type: ignore[method-assign]


def run_oxford(mission: str, speed: float, end_s: float, out: str) -> dict[str, Any]:
    """One live run of graphs/oxford.yaml on ``mission`` paced at ``speed``: figures (see the doc)."""
    from impala_flow import Session

    graph = Path(__file__).resolve().parent.parent / "graphs" / "oxford.yaml"
    session = Session()
    spec = session.load(graph, variables={"mission": mission, "out": out, "end_s": end_s})
    net = session.build(spec)
    cpu: dict[str, list[float]] = {}
    for comp in list(net.components.values()):
        _timed(comp, cpu)
    beams = net.add(Arrivals("probe_beams", beams=True))
    net.connect(net.components["mission"].outputs["radar/beams"], beams.inputs["x"])
    poses = {}
    for name in ("slam", "fmt"):
        poses[name] = net.add(Arrivals(f"probe_{name}"))
        net.connect(net.components[name].outputs["pose"], poses[name].inputs["x"])
    c0, w0 = time.process_time(), time.perf_counter()
    summary = RealTimeExecutor(net, clock=ScaledClock(speed)).run()
    cpu_s, wall_s = time.process_time() - c0, time.perf_counter() - w0
    spans = sorted(beams.turns.values())
    starts = np.array([s[0] for s in spans], dtype=np.int64)
    lat = {}
    for name, probe in poses.items():
        ms = []
        for t, arrived in probe.seen:  # the turn whose beams' span holds the pose's time
            k = int(np.searchsorted(starts, t, side="right")) - 1
            if k >= 0 and t <= spans[k][1]:
                ms.append((arrived - spans[k][2]) / speed / 1e6)
        lat[name] = np.asarray(ms) if ms else np.full(1, np.nan)
    dropped = sum(sum(v.values()) for v in summary.drops().values())
    per_call = {n: (1e3 * float(np.median(v)), len(v), sum(v)) for n, v in cpu.items() if v}
    return {"speed": speed, "turns": len(spans), "wall_s": wall_s, "cpu_s": cpu_s, "util": cpu_s / wall_s,
            "lat": lat, "dropped": dropped, "per_call": per_call}


_NATIVE = ("cv2", "numpy", "ufunc", "pocketfft", "scipy", "ndarray", "zstd", "Zstd", "scan", "_ni_")


def gil_shares(mission: str, end_s: float, out: str) -> dict[str, tuple[float, float]]:
    """Per component of graphs/oxford.yaml run offline on ``mission`` (``end_s`` seconds), its CPU
    seconds in ``process`` and the share of it inside compiled calls of numpy, OpenCV, scipy
    (cProfile's own time of those built-ins: the time that *can* run without the GIL; small
    numpy calls keep it, so this bounds from above what a second thread can overlap)."""
    import cProfile
    import pstats

    from impala_flow import Session

    graph = Path(__file__).resolve().parent.parent / "graphs" / "oxford.yaml"
    session = Session()
    net = session.build(session.load(graph, variables={"mission": mission, "out": out, "end_s": end_s}))
    profs: dict[str, cProfile.Profile] = {}
    for comp in list(net.components.values()):
        inner, prof = comp.process, profs.setdefault(comp.name, cProfile.Profile(time.thread_time))

        def process(t: int, inner: Any = inner, prof: cProfile.Profile = prof) -> None:
            prof.enable()
            try:
                inner(t)
            finally:
                prof.disable()

        comp.process = process  # type: ignore[method-assign]
    session.run(net)
    out_shares = {}
    for name, prof in profs.items():
        try:
            st = pstats.Stats(prof).stats  # type: ignore[attr-defined]
        except TypeError:  # never called (a source)
            continue
        total = sum(v[2] for v in st.values())
        native = sum(v[2] for (f, _, fn), v in st.items() if f == "~" and any(k in fn for k in _NATIVE))
        if total > 0:
            out_shares[name] = (total, native / total)
    return out_shares


def main_oxford(args: argparse.Namespace) -> int:
    gil: dict[str, tuple[float, float]] = {}
    if args.gil:
        gil = gil_shares(args.oxford, args.end_s, args.out + "-gil")
        total = sum(v[0] for v in gil.values())
        held = sum(v[0] * (1 - v[1]) for v in gil.values())
        print("offline, profiled (thread CPU inside process; share in compiled numpy/OpenCV/scipy calls): " + ", ".join(
            f"{n} {v[0]:.1f} s {v[1]:.0%}" for n, v in sorted(gil.items(), key=lambda kv: -kv[1][0]) if v[0] > 0.05))
        print(f"  GIL held {held:.1f} s of {total:.1f} s: threads can keep at most {total / held:.2f} cores busy "
              f"(Amdahl on the GIL-held share; a process per stage would lift that bound)")
    rows = []
    for speed in args.speeds:
        r = run_oxford(args.oxford, speed, args.end_s, args.out)
        rows.append(r)
        comps = sum(v[2] for v in r["per_call"].values())
        print(f"speed {speed:g}x: {r['turns']} turns in {r['wall_s']:.1f} s wall, CPU {r['cpu_s']:.1f} s = "
              f"{r['util']:.2f} cores (components' own threads {comps:.1f} s); dropped {r['dropped']}")
        for name, lat in r["lat"].items():
            med, p99 = np.nanmedian(lat), np.nanpercentile(lat, 99)
            print(f"  last beam -> {name}.pose: median {med:7.1f} ms  p99 {p99:7.1f} ms  ({len(lat)} turns)")
        top = sorted(r["per_call"].items(), key=lambda kv: -kv[1][2])[:6]
        print("  CPU per call (median ms, calls, share of the components' CPU): " + ", ".join(
            f"{n} {ms:.2f} x{k} {tot / comps:.0%}" for n, (ms, k, tot) in top))
    first = rows[0]
    p99 = max(float(np.nanpercentile(v, 99)) for v in first["lat"].values())
    med = max(float(np.nanmedian(v)) for v in first["lat"].values())
    ok = [r["speed"] for r in rows if r["dropped"] == 0
          and max(float(np.nanpercentile(v, 99)) for v in r["lat"].values()) < 250.0 / r["speed"]]
    print(json.dumps({"rt_oxford_speed": first["speed"], "rt_oxford_cpu_utilisation": round(first["util"], 3),
                      "rt_oxford_latency_p99_ms": round(p99, 1),
                      "rt_oxford_latency_median_ms": round(med, 1),
                      "rt_oxford_dropped": first["dropped"],
                      "rt_oxford_fastest_speed": max(ok) if ok else 0.0,
                      "rt_oxford_utilisation_by_speed": {f"{r['speed']:g}": round(r["util"], 3) for r in rows},
                      **({"rt_oxford_gil_held_share": round(sum(v[0] * (1 - v[1]) for v in gil.values())
                                                            / sum(v[0] for v in gil.values()), 3),
                          "rt_oxford_thread_cores_max": round(sum(v[0] for v in gil.values())
                                                              / sum(v[0] * (1 - v[1]) for v in gil.values()), 2)}
                         if gil else {}),
                      "load_average": round(os.getloadavg()[0], 2),
                      "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)}))
    return 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=20_000)
    ap.add_argument("--rate", type=float, default=4000.0, help="source rate, Hz (default 4000)")
    ap.add_argument("--oxford", metavar="MISSION", help="replay MISSION live through graphs/oxford.yaml instead")
    ap.add_argument("--speeds", type=lambda s: [float(x) for x in s.split(",")], default=[1.0, 2.0],
                    help="replay speeds for --oxford (comma-separated; default 1,2)")
    ap.add_argument("--end-s", type=float, default=20.0, help="seconds of the mission for --oxford (default 20)")
    ap.add_argument("--out", default="out/bench-rt-oxford", help="reports of the --oxford runs")
    ap.add_argument("--gil", action="store_true", help="with --oxford: also profile each stage offline for the "
                                                       "share of its CPU spent outside the GIL")
    args = ap.parse_args(argv)
    if args.oxford:
        return main_oxford(args)
    print(f"python {platform.python_version()} on {platform.machine()}, {args.samples} samples at "
          f"{args.rate:.0f} Hz, 8-byte payloads; load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs "
          "(other processes inflate the tail)")
    run(min(2000, args.samples), args.rate, 0)  # warm-up
    results = {}
    for hops in (0, 2):
        lat, dropped, wall = run(args.samples, args.rate, hops)
        med, p99 = float(np.median(lat)), float(np.percentile(lat, 99))
        results[hops] = (med, p99, dropped)
        label = "source -> sink" if hops == 0 else f"source -> {hops} pass-through -> sink"
        print(f"{label:38s} median {med:8.1f} us   p99 {p99:8.1f} us   max {lat.max():9.1f} us   "
              f"dropped {dropped}   ({wall:.1f} s wall)")
    med, p99, dropped = results[0]
    print("target: median <= 100 us source -> sink:", "met" if med <= 100 else "NOT met")
    print(json.dumps({"rt_latency_median_us": round(med, 1), "rt_latency_p99_us": round(p99, 1),
                      "rt_dropped": dropped}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
