"""Engine benchmark: the deterministic executor's throughput and per-hop cost.

    python bench/engine.py [--samples 200000] [--repeat 5]

Figures (medians over --repeat runs, machine noise in mind):
- chain_8B: source -> 3 pass-through components -> sink, 8-byte payloads, samples/s end to
  end, and the cost of one hop as a ratio to a plain Python function call doing the same
  pass-through work (a direct loop over the same 4 calls).
- chain_1MiB: the same chain with 1 MiB numpy arrays (zero copy: read-only fan-out).
- fanout4_1MiB: the same 1 MiB chain ending in 4 sinks instead of 1 (7 process calls per
  sample instead of 4, so the fair comparison is per process call: see the ratio printed).
- typed_check: the same 8-byte chain with every output declared ``Output(bytes)`` (the
  emitted type is checked, cached by class) against ``Output(object)`` (not checked), runs
  interleaved; the difference per hop as a share of a hop (target < 5 %), and the same
  figure from a direct timing of ``emit`` on a typed vs an untyped port (less noisy).
- dropped: drop counters of every run (zero: no overflow policy fires here).
The real-time latency figures are printed by bench/engine_realtime.py when present.
The last line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from impala_flow import Component, Input, Network, OfflineExecutor, Output, Param, Source


class Src(Source):
    out = Output(object)
    n = Param(int, default=1000)
    kind = Param(str, default="8B", choices=("8B", "1MiB"))

    def generate(self):
        payload = b"\x00" * 8 if self.kind == "8B" else np.zeros(1 << 18, dtype=np.float32)  # 1 MiB
        for i in range(self.n):
            yield i, "out", payload


class Pass(Component):
    x = Input(object)
    y = Output(object)

    def process(self, t):
        self.y.emit(t, self.x.take())


class TypedSrc(Src):
    out = Output(bytes)


class TypedPass(Pass):
    y = Output(bytes)


class Sink(Component):
    x = Input(object)

    def start(self):
        self.n = 0

    def process(self, t):
        self.x.take()
        self.n += 1


def chain(n: int, kind: str, hops: int = 3, sinks: int = 1, typed: bool = False) -> tuple[float, int, int]:
    net = Network(name="bench")
    prev = net.add((TypedSrc if typed else Src)("src", n=n, kind=kind)).outputs["out"]
    for i in range(hops):
        p = net.add((TypedPass if typed else Pass)(f"p{i}"))
        net.connect(prev, p.inputs["x"])
        prev = p.outputs["y"]
    ks = [net.add(Sink(f"k{i}")) for i in range(sinks)]
    for k in ks:
        net.connect(prev, k.inputs["x"])
    t0 = time.perf_counter()
    summary = OfflineExecutor(net).run()
    dt = time.perf_counter() - t0
    assert all(k.n == n for k in ks), "every sink must receive every sample"
    return n / dt, summary.total_lost, summary.events


def emit_check_s(repeat: int) -> float:
    """Seconds the type check adds to one ``emit`` (typed minus untyped port, best of runs)."""
    import timeit

    class Two(Component):
        loose = Output(object)
        typed = Output(bytes)

    c, d = Two("two"), b"\x00" * 8
    loose, typed = c.outputs["loose"], c.outputs["typed"]
    n = 200_000
    t_loose = min(timeit.repeat(lambda: loose.emit(1, d), number=n, repeat=repeat))
    t_typed = min(timeit.repeat(lambda: typed.emit(1, d), number=n, repeat=repeat))
    return (t_typed - t_loose) / n


def direct(n: int) -> float:
    """The same work as plain Python calls: 3 pass-throughs and a sink per sample."""

    def passthrough(x):
        return x

    count = 0

    def sink(x):
        nonlocal count
        count += 1

    payload = b"\x00" * 8
    t0 = time.perf_counter()
    for _ in range(n):
        sink(passthrough(passthrough(passthrough(payload))))
    return (time.perf_counter() - t0) / (4 * n)  # seconds per call


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--samples", type=int, default=200_000)
    ap.add_argument("--big-samples", type=int, default=20_000)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--no-realtime", action="store_true")
    a = ap.parse_args()

    rates, big, fan, drops, typed = [], [], [], 0, []
    for _ in range(a.repeat):
        r, d, events = chain(a.samples, "8B")
        rates.append(r)
        typed.append(chain(a.samples, "8B", typed=True)[0])
        drops += d
        r, d, _ = chain(a.big_samples, "1MiB")
        big.append(r)
        drops += d
        r, d, _ = chain(a.big_samples, "1MiB", hops=3, sinks=4)
        fan.append(r)
        drops += d
    call_s = statistics.median(direct(a.samples) for _ in range(a.repeat))
    rate = statistics.median(rates)
    hop_s = 1.0 / rate / 4  # 4 process calls per sample (3 pass-through + sink)
    res = {
        "chain_8B_samples_per_s": round(rate),
        "chain_1MiB_samples_per_s": round(statistics.median(big)),
        "fanout4_1MiB_samples_per_s": round(statistics.median(fan)),
        "chain_1MiB_ratio_to_8B": round(statistics.median(big) / rate, 3),
        "fanout4_1MiB_ratio_to_8B": round(statistics.median(fan) / rate, 3),
        "fanout4_1MiB_calls_ratio_to_8B": round(statistics.median(fan) * 7 / (rate * 4), 3),
        "hop_us": round(hop_s * 1e6, 3),
        "direct_call_us": round(call_s * 1e6, 4),
        "hop_cost_ratio_to_call": round(hop_s / call_s, 1),
        "chain_8B_typed_samples_per_s": round(statistics.median(typed)),
        # extra seconds per hop of the checked chain, as a share of one hop
        "type_check_share_of_hop": round((1 / statistics.median(typed) - 1 / rate) / 4 / hop_s, 4),
        "emit_check_ns": round(emit_check_s(a.repeat) * 1e9, 1),
        "emit_check_share_of_hop": round(emit_check_s(a.repeat) / hop_s, 4),
        "dropped": drops,
    }
    print(f"chain of 3 pass-through components, 8-byte payloads: {res['chain_8B_samples_per_s']:,} samples/s "
          f"(median of {a.repeat}; target >= 200,000)")
    print(f"  one hop: {res['hop_us']} us = {res['hop_cost_ratio_to_call']} x a plain Python call "
          f"({res['direct_call_us']} us)")
    print(f"chain with 1 MiB arrays: {res['chain_1MiB_samples_per_s']:,} samples/s "
          f"= {res['chain_1MiB_ratio_to_8B']:.0%} of the 8-byte rate (target >= 80%: zero copy)")
    print(f"chain ending in a fan-out to 4 sinks, 1 MiB arrays: {res['fanout4_1MiB_samples_per_s']:,} samples/s "
          f"= {res['fanout4_1MiB_ratio_to_8B']:.0%} of the 8-byte chain rate; per process call "
          f"{res['fanout4_1MiB_calls_ratio_to_8B']:.0%} (7 calls per sample instead of 4)")
    print(f"same chain with declared output types (checked, cached by class): "
          f"{res['chain_8B_typed_samples_per_s']:,} samples/s; the check costs "
          f"{res['type_check_share_of_hop']:.1%} of a hop (target < 5%); timed on emit alone: "
          f"{res['emit_check_ns']} ns = {res['emit_check_share_of_hop']:.1%} of a hop")
    print(f"samples dropped over all runs: {drops}")
    rt = Path(__file__).with_name("engine_realtime.py")
    if rt.exists() and not a.no_realtime:
        out = subprocess.run([sys.executable, str(rt)], capture_output=True, text=True, check=False)
        lines = out.stdout.strip().splitlines()
        for line in lines[:-1]:
            print(line)
        try:
            res.update(json.loads(lines[-1]))
        except (IndexError, json.JSONDecodeError):
            print(f"real-time benchmark failed: {out.stderr.strip()[-300:]}")
    print(json.dumps(res))


if __name__ == "__main__":
    main()
