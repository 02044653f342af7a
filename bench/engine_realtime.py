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
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from collections.abc import Iterator
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


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--samples", type=int, default=20_000)
    ap.add_argument("--rate", type=float, default=4000.0, help="source rate, Hz (default 4000)")
    args = ap.parse_args(argv)
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
