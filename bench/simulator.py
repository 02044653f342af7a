"""Simulator benchmark: Beynes world, IMPALA preset, one core, streamed.

Prints simulated turns per second, the ratio to real time (the radar turns once per
second) and the peak resident memory; the last line is one JSON object. The process is
pinned to one core and the rates use its CPU time (``time.process_time``), so other load
on the machine does not distort them; the wall-clock ratio is printed beside. ``--turns 662``
runs the whole Beynes mission, which must stay memory-bounded (one turn in flight).

    python bench/simulator.py              # 20 turns, < 1 min
    python bench/simulator.py --turns 662  # the whole mission
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import time

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--turns", type=int, default=20, help="antenna turns to simulate")
    ap.add_argument("--scenario", default="beynes")
    ap.add_argument("--seed", type=int, default=None)
    args = ap.parse_args(argv)
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})  # one core

    from impala_radar.simulator.scenario import load_scenario

    t0 = time.perf_counter()
    sc = load_scenario(args.scenario, seed=args.seed, duration_s=float(args.turns))
    build_s = time.perf_counter() - t0
    rss_world_mb = _rss_mb()
    turns = 0
    counts: dict[str, int] = {}
    t0, c0 = time.perf_counter(), time.process_time()
    for _, port, msg in sc.simulate():  # streamed: nothing is kept
        counts[port] = counts.get(port, 0) + 1
        if port == "beams" and msg.index == 0:
            turns += 1
    wall_s, sim_s = time.perf_counter() - t0, time.process_time() - c0
    mission_s = sc.duration_ns * 1e-9
    result = {
        "scenario": sc.name,
        "turns": turns,
        "world_scatterers": len(sc.world),
        "world_build_s": round(build_s, 3),
        "sim_cpu_s": round(sim_s, 3),
        "sim_wall_s": round(wall_s, 3),
        "wall_x_realtime": round(mission_s / wall_s, 3),
        "sim_turns_per_s": round(turns / sim_s, 3),
        "sim_x_realtime": round(mission_s / sim_s, 3),
        "rss_after_world_mb": round(rss_world_mb, 1),
        "peak_rss_mb": round(_rss_mb(), 1),
    }
    print(f"scenario {sc.name}: {len(sc.world)} scatterers, world built in {build_s:.2f} s")
    print(f"{turns} turns ({mission_s:.1f} s of mission) simulated in {sim_s:.2f} s CPU "
          f"(one core): {result['sim_turns_per_s']:.2f} turns/s, "
          f"{result['sim_x_realtime']:.2f}x real time; wall {wall_s:.2f} s, "
          f"{result['wall_x_realtime']:.2f}x")
    print("messages: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    print(f"peak RSS {result['peak_rss_mb']:.0f} MB (after the world: "
          f"{result['rss_after_world_mb']:.0f} MB)")
    print(json.dumps(result))
    return result


if __name__ == "__main__":
    main()
