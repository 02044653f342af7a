"""Engine cost around the components: replaying a recording, and importing a dataset.

    python bench/replay.py [--mission out/radiate-head.mcap] [--end-s 0] [--radiate FOLDER]

- replay: ``io.Replayer`` (``radar/beams`` only) -> a sink that takes every beam, run by the
  offline executor as a graph runs, single thread. CPU time (``time.process_time``), so other
  jobs on the machine do not count. Split (profile-derived, one cProfile pass on a share of
  the beams, scaled to the measured total): read (chunk decompression, record scan), decode
  (payload -> RadarBeam), freeze, validity check (``invalid_reason`` on the input), executor
  (heap, ports, process calls: the rest).
- import: ``impala-flow import radiate FOLDER -o X.mcap`` in a subprocess; scans/s on CPU
  time (the child's user + system) and on wall time (start-up included; PNGs are read on a
  read-ahead thread, chunks compressed and written on the writer's thread), the CPU of each of
  those threads and of the main one, its peak RSS, and whether the file is byte-identical to a
  second import.
- import split (:func:`import_split`, in this process, ms of CPU per scan on the first scans):
  the read-ahead thread (PNG inflation, counts to power), on the main thread the beams and truth
  made by the reader, the writer's encode (native payload), mirror (the JSON view) and chunk
  (records into the chunk) shares (profile-derived, scaled to the measured total), and the
  writer thread's compression and writing; the rest of the import's CPU is start-up and the
  engine (delivery, validity, freeze, executor, the recorder component).

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


def import_split(folder: str, out_dir: str, scans: int = 100) -> dict[str, float]:
    """CPU ms per scan of the import's stages on the first ``scans`` scans of ``folder`` (module doc)."""
    import itertools

    import impala_msgs
    from impala_flow import msgs
    from impala_flow.io import MissionWriter, run_codecs
    from impala_radar.datasets.common import ImportReport, iter_mission
    from impala_radar.datasets.component import RadiateScans

    src = RadiateScans("radiate", folder=folder)
    src.open()
    beams = scans * src.dataset.config.beams_per_turn
    c0, p0 = time.thread_time(), time.process_time()
    items = list(itertools.islice(iter_mission(src.dataset, ImportReport(), db_per_count=src.db_per_count), beams))
    source = time.thread_time() - c0
    read = time.process_time() - p0 - source  # the read-ahead thread's
    n = sum(1 for _, stream, _ in items if stream == "beams") / src.dataset.config.beams_per_turn
    codecs = run_codecs()

    def write(profile: cProfile.Profile | None = None) -> tuple[float, float]:
        w = MissionWriter(Path(out_dir) / "split.mcap", codecs=codecs, json_views=True, flush_period_s=None)
        w.add_topic("radiate/beams", impala_msgs.RadarBeam)
        w.add_topic("radiate/truth", msgs.Pose2D)
        c = time.thread_time()
        if profile is not None:
            profile.enable()
        for t_ns, stream, m in items:
            w.write("radiate/" + stream, t_ns, m)
        w.close()
        if profile is not None:
            profile.disable()
        return time.thread_time() - c, w.thread_cpu_s

    Path(out_dir).mkdir(parents=True, exist_ok=True)
    main_s, thread_s = min(write() for _ in range(3))
    prof = cProfile.Profile()
    write(prof)
    stats = pstats.Stats(prof).stats  # type: ignore[attr-defined]
    cum = {"encode": 0.0, "mirror": 0.0, "total": 0.0}
    for (file, _, func), (_, _, _, ct, _) in stats.items():
        if file.endswith("io/_writer.py") and func == "write":
            cum["total"] = max(cum["total"], ct)
        elif file.endswith("io/_codec.py") and func in ("encode_parts", "encode"):
            cum["encode"] = max(cum["encode"], ct)
        elif func == "convert" or func.endswith("_json_convert"):
            cum["mirror"] = max(cum["mirror"], ct)
    total = cum["total"] or 1.0
    enc, mir = cum["encode"] / total * main_s, cum["mirror"] / total * main_s
    per = 1e3 / n
    return {"import_split_scans": round(n), "import_read_thread_ms_per_scan": round(read * per, 2),
            "import_source_ms_per_scan": round(source * per, 2),
            "import_writer_encode_ms_per_scan": round(enc * per, 2),
            "import_writer_mirror_ms_per_scan": round(mir * per, 2),
            "import_writer_chunk_ms_per_scan": round((main_s - enc - mir) * per, 2),
            "import_writer_thread_ms_per_scan": round(thread_s * per, 2)}


#: runs ``impala-flow ARGS`` in this interpreter and prints, last on stderr, the CPU seconds of each thread
_THREAD_CPU = """
import json, sys, threading, time
cpu = {}
_run = threading.Thread.run
def run(self):
    try:
        _run(self)
    finally:
        cpu[self.name] = cpu.get(self.name, 0.0) + time.thread_time()
threading.Thread.run = run
from impala_flow.cli import main
code = main(sys.argv[1:])
cpu["main"] = time.thread_time()
print(json.dumps({"thread_cpu_s": cpu}), file=sys.stderr)
sys.exit(code)
"""
_THREAD_KEYS = {"main": "main", "impala-read-ahead": "read", "impala-mcap-writer": "writer"}


def _import_once(folder: str, out: Path, tree: Path) -> tuple[float, float, dict[str, float]]:
    env = dict(os.environ, OMP_NUM_THREADS="1",
               PYTHONPATH=os.pathsep.join([str(tree), str(tree / "plugins"), os.environ.get("PYTHONPATH", "")]))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    run = subprocess.run([sys.executable, "-c", _THREAD_CPU, "import", "radiate", folder, "-o", str(out),
                          "--overwrite", "--no-progress"], check=True, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    threads = json.loads(run.stderr.strip().splitlines()[-1])["thread_cpu_s"]
    return cpu, wall, {_THREAD_KEYS.get(k, k): v for k, v in threads.items()}


def bench_import_radiate(folder: str, out_dir: str, tree: str | None = None) -> dict[str, Any]:
    """``impala-flow import radiate folder`` twice (CPU and wall scans/s of the faster run, each thread's CPU
    in it: main, read-ahead, writer; and whether both files are byte-identical). ``tree``: the checkout to run
    (default: this one)."""
    root = Path(tree) if tree else ROOT
    scans = len(list((Path(folder) / "Navtech_Polar").glob("*.png")))
    outs = [Path(out_dir) / f"radiate-import-{i}.mcap" for i in range(2)]
    Path(out_dir).mkdir(parents=True, exist_ok=True)
    runs = [_import_once(folder, o, root) for o in outs]
    cpu = min(r[0] for r in runs)
    fastest = min(runs, key=lambda r: r[1])
    wall = fastest[1]
    same = outs[0].read_bytes() == outs[1].read_bytes()
    return {"import_radiate_scans": scans, "import_radiate_scans_per_s": round(scans / wall, 1),
            "import_radiate_cpu_scans_per_s": round(scans / cpu, 1), "import_radiate_cpu_s": round(cpu, 2),
            "import_radiate_wall_s": round(wall, 2), "import_radiate_repeatable": same,
            **{f"import_{k}_thread_cpu_s": round(v, 2) for k, v in sorted(fastest[2].items())},
            "import_peak_rss_mb": round(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024, 1)}


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
              f"two imports byte-identical: {res['import_radiate_repeatable']} (target >= 50 scans/s); "
              f"peak RSS {res['import_peak_rss_mb']} MB")
        print("import radiate, CPU s by thread (the faster run): " + ", ".join(
            f"{k[len('import_'):-len('_thread_cpu_s')]} {v}" for k, v in res.items() if k.endswith("_thread_cpu_s")))
        res.update(import_split(a.radiate, a.out))
        print(f"import split, CPU ms per scan (first {res['import_split_scans']} scans): read-ahead thread "
              f"{res['import_read_thread_ms_per_scan']}; main thread: reader's beams {res['import_source_ms_per_scan']}"
              f" + writer encode {res['import_writer_encode_ms_per_scan']} + mirror "
              f"{res['import_writer_mirror_ms_per_scan']} + chunk {res['import_writer_chunk_ms_per_scan']}; writer "
              f"thread (compress, write) {res['import_writer_thread_ms_per_scan']}; the rest of "
              f"{1e3 * res['import_radiate_cpu_s'] / res['import_radiate_scans']:.1f} ms per scan of the import's "
              "CPU: start-up and the engine")
    res["peak_rss_mb"] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)
    print(f"peak RSS {res['peak_rss_mb']} MB")
    print(json.dumps(res))
    return 0


if __name__ == "__main__":
    sys.exit(main())
