"""Simulator benchmark: Beynes world, IMPALA preset, one core, streamed.

Prints simulated turns per second, the ratio to real time (the radar turns once per
second), the split of the CPU time per turn by stage, and the peak resident memory; the last
line is one JSON object. It runs the simulator with 1 thread pinned to one core, then with 2
threads on two cores (``--threads``); the rates use the process's CPU time
(``time.process_time``, all threads), so other load on the machine does not distort them,
and the wall-clock ratio is printed beside (what two threads buy; meaningful on a quiet
machine only). The JSON's headline keys are the first run's (1 thread); the 2-thread figures
carry a ``_2threads`` suffix. ``--turns 662`` runs the whole Beynes mission, which must stay
memory-bounded (one turn in flight).

Stages (exclusive CPU time of the functions, by :class:`_Stages` wrappers, summed over the threads, ms per turn):
``scene`` the turn's scatterers (k-d tree query, clutter split, jitter, ghosts, azimuth
windows, shadow prefilter); ``pairs`` the blocks' candidates, their walls and discs, and the
(beam, scatterer) pairs in the beams' pattern (one compiled pass, with the discs near each block);
``echoes`` the pairs' geometry, pattern gain and radar equation (with threads, each run of blocks
has its pairs and echoes computed by the thread that took it); ``movers``; ``blocks`` the rest
of the turn's echoes (glue, joins); ``spread`` the NUFFT (each ramp's echoes prepared, spread
onto the grid, inverse FFT); ``noise`` thermal noise and the culling; ``fft`` the windowed
spectrum; ``phase_noise`` the skirts; ``adc`` the output stage; ``stream`` the rest (beam
messages, proprioceptive sensors, merge; with threads, also the glue the other threads run between
the wrapped functions). With 2 threads, turn k's synthesis (spread, fft, adc) runs on a thread of
its own while the caller computes turn k + 1's echoes. The first call compiles the numba loops once per
machine (cached on disk); the world build and that warm-up are outside the figures.

    python bench/simulator.py              # 20 turns, < 1 min
    python bench/simulator.py --turns 662  # the whole mission
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import resource
import threading
import time

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

STAGES = ("scene", "pairs", "echoes", "movers", "blocks", "spread", "noise", "fft", "phase_noise",
          "adc", "stream")


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # Linux: KiB


class _Stages:
    """Exclusive CPU time (``time.thread_time``) of wrapped functions, grouped by stage,
    summed over the threads that run them."""

    def __init__(self) -> None:
        self.s = dict.fromkeys(STAGES, 0.0)
        self._local = threading.local()
        self._lock = threading.Lock()
        self._undo: list[tuple[object, str, object]] = []

    def wrap(self, owner, name: str, stage: str) -> None:
        fn = owner.__dict__[name]
        local, acc, lock = self._local, self.s, self._lock

        @functools.wraps(fn)
        def timed(*args, **kwargs):
            stack = local.__dict__.setdefault("stack", [])
            t0 = time.thread_time()
            stack.append(0.0)
            try:
                return fn(*args, **kwargs)
            finally:
                dt = time.thread_time() - t0
                with lock:
                    acc[stage] += dt - stack.pop()
                if stack:
                    stack[-1] += dt

        setattr(owner, name, timed)
        self._undo.append((owner, name, fn))

    def restore(self) -> None:
        for owner, name, fn in reversed(self._undo):
            setattr(owner, name, fn)


def _instrument() -> _Stages:
    from impala_radar.simulator import core, kernels, spectra
    from impala_radar.simulator.world import World

    st = _Stages()
    for owner, name, stage in [
        (World, "query", "scene"), (core.RadarSimulator, "_scene", "scene"),
        (core.RadarSimulator, "_windows", "scene"), (core, "_maybe_behind", "scene"),
        (core.RadarSimulator, "_block_discs", "pairs"), (kernels, "block_pairs", "pairs"),
        (core.RadarSimulator, "_swept_mover_discs", "pairs"),
        (core.RadarSimulator, "_pair_echoes", "echoes"),
        (core.RadarSimulator, "_movers", "movers"),
        (core.RadarSimulator, "echo_parts", "blocks"), (core.RadarSimulator, "_static", "blocks"),
        (spectra.Synthesizer, "draw", "noise"), (spectra.Synthesizer, "_draws", "noise"),
        (spectra, "phase_noise_skirts", "phase_noise"),
        (spectra.Synthesizer, "synthesize", "spread"), (spectra.Synthesizer, "_prepare", "spread"),
        (spectra.Synthesizer, "_grid", "spread"),
        (spectra.Synthesizer, "_spectrum_of_grid", "fft"), (core, "adc_counts", "adc"),
    ]:
        st.wrap(owner, name, stage)
    return st


def bench_beynes(turns: int = 20, scenario: str = "beynes", seed: int | None = None, threads: int = 1) -> dict:
    """Simulate ``turns`` turns of ``scenario`` with ``threads`` threads; the figures as a dict
    (JSON keys with units). CPU time is the process's (all threads); wall time is what a
    user waits, meaningful on a quiet machine only."""
    from impala_radar.simulator.core import RadarSimulator, beam_times_ns
    from impala_radar.simulator.scenario import load_scenario

    t0 = time.perf_counter()
    sc = load_scenario(scenario, seed=seed, duration_s=float(turns))
    sc.threads = threads
    build_s = time.perf_counter() - t0
    c0 = time.process_time()  # warm-up: numba's compiled loops loaded (or compiled, once per machine)
    RadarSimulator(sc.world, sc.config, sc.params, threads=threads).turn(
        sc.trajectory, beam_times_ns(sc.start_t_ns, 0, sc.config)[:8], sc.acquisition_rng())
    warmup_s = time.process_time() - c0
    rss_world_mb = _rss_mb()
    stages = _instrument()
    turns_done = 0
    counts: dict[str, int] = {}
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        for _, port, msg in sc.simulate():  # streamed: nothing is kept
            counts[port] = counts.get(port, 0) + 1
            if port == "beams" and msg.index == 0:
                turns_done += 1
    finally:
        stages.restore()
    wall_s, sim_s = time.perf_counter() - t0, time.process_time() - c0
    stages.s["stream"] = max(0.0, sim_s - sum(v for k, v in stages.s.items() if k != "stream"))
    mission_s = sc.duration_ns * 1e-9
    per_turn_ms = {k: round(1e3 * v / max(turns_done, 1), 2) for k, v in stages.s.items()}
    return {
        "scenario": sc.name,
        "threads": threads,
        "turns": turns_done,
        "world_scatterers": len(sc.world),
        "world_build_s": round(build_s, 3),
        "warmup_cpu_s": round(warmup_s, 3),
        "sim_cpu_s": round(sim_s, 3),
        "sim_wall_s": round(wall_s, 3),
        "wall_x_realtime": round(mission_s / wall_s, 3),
        "sim_turns_per_s": round(turns_done / sim_s, 3),
        "simulator_beynes_x_realtime": round(mission_s / sim_s, 3),
        "simulator_ms_per_turn": round(1e3 * sim_s / max(turns_done, 1), 2),
        **{f"{k}_ms_per_turn": v for k, v in per_turn_ms.items()},
        "messages": counts,
        "rss_after_world_mb": round(rss_world_mb, 1),
        "peak_rss_mb": round(_rss_mb(), 1),
    }


def _report(r: dict) -> None:
    mission_s = r["turns"] / max(r["sim_turns_per_s"], 1e-9) * r["simulator_beynes_x_realtime"]
    print(f"{r['threads']} thread(s): {r['turns']} turns ({mission_s:.1f} s of mission) in {r['sim_cpu_s']:.2f} s CPU: "
          f"{r['sim_turns_per_s']:.2f} turns/s, {r['simulator_beynes_x_realtime']:.2f}x real time (CPU); "
          f"wall {r['sim_wall_s']:.2f} s, {r['wall_x_realtime']:.2f}x real time (wall)")
    print(f"  per turn {r['simulator_ms_per_turn']:.1f} ms CPU = "
          + " + ".join(f"{k} {r[f'{k}_ms_per_turn']:.1f}" for k in STAGES))


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--turns", type=int, default=20, help="antenna turns to simulate")
    ap.add_argument("--scenario", default="beynes")
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--threads", default="1,2", help="comma-separated thread counts to run (the first is the "
                    "JSON's headline; 1 = one core)")
    args = ap.parse_args(argv)
    cores = sorted(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else None
    runs = []
    for threads in (int(t) for t in args.threads.split(",")):
        if cores:  # one thread: pinned to one core; n threads: n cores
            os.sched_setaffinity(0, set(cores[:max(1, threads)]))
        runs.append(bench_beynes(args.turns, args.scenario, args.seed, threads))
    r = runs[0]
    print(f"scenario {r['scenario']}: {r['world_scatterers']} scatterers, world built in {r['world_build_s']:.2f} s; "
          f"warm-up (numba loops loaded) {r['warmup_cpu_s']:.2f} s CPU")
    for x in runs:
        _report(x)
    print("messages: " + ", ".join(f"{k} {v}" for k, v in sorted(r["messages"].items())))
    print(f"peak RSS {max(x['peak_rss_mb'] for x in runs):.0f} MB (after the world: {r['rss_after_world_mb']:.0f} MB)")
    for x in runs[1:]:
        for key in ("simulator_ms_per_turn", "simulator_beynes_x_realtime", "wall_x_realtime", "sim_wall_s"):
            r[f"{key}_{x['threads']}threads"] = x[key]
    r["peak_rss_mb"] = max(x["peak_rss_mb"] for x in runs)
    print(json.dumps(r))
    return r


if __name__ == "__main__":
    main()
