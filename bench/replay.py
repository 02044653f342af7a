"""Engine cost around the components: replaying a recording, and importing a dataset.

    python bench/replay.py [--mission out/radiate-head.mcap] [--end-s 0] [--radiate FOLDER]

- replay: ``io.Replayer`` (``radar/beams`` only) -> a sink that takes every beam, run by the
  offline executor as a graph runs, single thread. CPU time (``time.process_time``), so other
  jobs on the machine do not count. Split (profile-derived, one cProfile pass on a share of
  the beams, scaled to the measured total): read (chunk decompression, record scan), decode
  (payload -> RadarBeam), freeze, validity check (``invalid_reason`` on the input), executor
  (heap, ports, process calls: the rest).
- import: ``impala-flow import radiate FOLDER -o X.mcap`` in a subprocess; scans/s on CPU
  time (the child's user + system) and on wall time (the chunk compression runs on a second
  thread), and whether the file is byte-identical to a second import.

The last line is one JSON object (keys with units). The lead's summary bench imports
:func:`bench_replay` and :func:`bench_import_radiate`.
"""

from __future__ import annotations

import argparse
import cProfile
import json
import os
import pstats
import resource
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from impala_flow import Component, Input, Network, OfflineExecutor
from impala_flow.io import Replayer

ROOT = Path(__file__).resolve().parent.parent


class TakeAll(Component):
    """Takes every beam and counts it (the cheapest consumer a graph can have)."""

    x = Input(object)

    def start(self) -> None:
        self.n = 0

    def process(self, t: int) -> None:
        self.x.take()
        self.n += 1


def _replay_net(path: str, end_s: float) -> tuple[Network, TakeAll]:
    net = Network(name="replay")
    src = net.add(Replayer("mission", path=path, streams=["radar/beams"], end_s=end_s))
    sink = net.add(TakeAll("sink"))
    net.connect(src.outputs["radar/beams"], sink.inputs["x"])
    return net, sink


def _run_once(path: str, end_s: float) -> tuple[int, float]:
    net, sink = _replay_net(path, end_s)
    c0 = time.process_time()
    OfflineExecutor(net).run()
    return sink.n, time.process_time() - c0


_STAGES = {  # (file suffix, function) -> stage; the rest of the run is the executor's
    "read": [("io/_reader.py", "_chunk_messages"), ("io/_reader.py", "_load")],
    "decode": [("io/_reader.py", "_emit"), (">", "decode_from")],  # a generated decoder: "<decoder of RadarBeam>"
    "freeze": [("msgs/_base.py", "freeze_fields"), ("msgs/_base.py", "freeze")],
    "validity": [("sensors.py", "invalid_reason")],
}


def _split(path: str, end_s: float) -> dict[str, float]:
    """Share of each stage in one profiled replay (cumulative time of its entry points)."""
    net, _ = _replay_net(path, end_s)
    prof = cProfile.Profile()
    prof.enable()
    OfflineExecutor(net).run()
    prof.disable()
    stats = pstats.Stats(prof).stats  # type: ignore[attr-defined]
    total = 0.0
    cum: dict[str, float] = dict.fromkeys(_STAGES, 0.0)
    for (file, _, func), (_, _, _, ct, _) in stats.items():
        if func == "run" and file.endswith("_offline.py"):
            total = max(total, ct)
        for stage, entries in _STAGES.items():
            if any(file.endswith(suf) and func == fn for suf, fn in entries):
                cum[stage] = max(cum[stage], ct)  # recursive entries: the outermost call
    shares = {k: v / total for k, v in cum.items()} if total else dict.fromkeys(cum, 0.0)
    shares["executor"] = max(0.0, 1.0 - sum(shares.values()))
    return shares


def bench_replay(mission_path: str, end_s: float = 0.0, repeat: int = 3) -> dict[str, Any]:
    """Beams per second (CPU) replaying ``mission_path``'s ``radar/beams`` into a sink that
    takes them; best of ``repeat``; with the per-stage split in microseconds per beam."""
    best_s, n = float("inf"), 0
    for _ in range(repeat):
        n, dt = _run_once(mission_path, end_s)
        best_s = min(best_s, dt)
    if n == 0:
        raise SystemExit(f"{mission_path}: no radar/beams replayed")
    us = best_s / n * 1e6
    split = _split(mission_path, min(end_s, 10.0) if end_s else 10.0)
    return {"replay_beams_per_s": round(n / best_s), "replay_us_per_beam": round(us, 2),
            "replay_beams": n, **{f"replay_{k}_us_per_beam": round(v * us, 2) for k, v in split.items()}}


def _import_once(folder: str, out: Path, tree: Path) -> tuple[float, float]:
    env = dict(os.environ, OMP_NUM_THREADS="1",
               PYTHONPATH=os.pathsep.join([str(tree), str(tree / "plugins"), os.environ.get("PYTHONPATH", "")]))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "impala_flow", "import", "radiate", folder, "-o", str(out), "--overwrite",
                    "--no-progress"], check=True, env=env, capture_output=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, wall


def bench_import_radiate(folder: str, out_dir: str, tree: str | None = None) -> dict[str, Any]:
    """``impala-flow import radiate folder`` twice (CPU and wall scans/s of the faster run, and
    whether both files are byte-identical). ``tree``: the checkout to run (default: this one)."""
    root = Path(tree) if tree else ROOT
    scans = len(list((Path(folder) / "Navtech_Polar").glob("*.png")))
    outs = [Path(out_dir) / f"radiate-import-{i}.mcap" for i in range(2)]
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    runs = [_import_once(folder, o, root) for o in outs]
    cpu = min(r[0] for r in runs)
    wall = min(r[1] for r in runs)
    same = outs[0].read_bytes() == outs[1].read_bytes()
    return {"import_radiate_scans": scans, "import_radiate_scans_per_s": round(scans / wall, 1),
            "import_radiate_cpu_scans_per_s": round(scans / cpu, 1), "import_radiate_cpu_s": round(cpu, 2),
            "import_radiate_wall_s": round(wall, 2), "import_radiate_repeatable": same}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--mission", default="out/radiate-head.mcap", help="recording with radar/beams")
    ap.add_argument("--end-s", type=float, default=0.0, help="replay this many seconds (0 = all)")
    ap.add_argument("--radiate", default="../shared/data/radiate-edinburgh-head", help="RADIATE folder to import")
    ap.add_argument("--out", default="out/bench-replay", help="scratch folder for the imports")
    ap.add_argument("--no-import", action="store_true")
    a = ap.parse_args(argv)
    res = bench_replay(a.mission, a.end_s)
    split = " + ".join(f"{k} {res[f'replay_{k}_us_per_beam']}" for k in (*_STAGES, "executor"))
    print(f"replay {a.mission}: {res['replay_beams']} beams, {res['replay_beams_per_s']:,} beams/s on one core, "
          f"{res['replay_us_per_beam']} us per beam = {split} us "
          f"({res['replay_us_per_beam'] * 0.4:.1f} ms per 400-beam turn)")
    if not a.no_import and Path(a.radiate).is_dir():
        res.update(bench_import_radiate(a.radiate, a.out))
        print(f"import radiate ({res['import_radiate_scans']} scans): {res['import_radiate_scans_per_s']} scans/s "
              f"wall, {res['import_radiate_cpu_scans_per_s']} scans/s of CPU ({res['import_radiate_cpu_s']} s); "
              f"two imports byte-identical: {res['import_radiate_repeatable']} (target >= 50 scans/s)")
    res["peak_rss_mb"] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)
    print(f"peak RSS {res['peak_rss_mb']} MB")
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
