"""Recording benchmark: impala-flow io vs the bare ``mcap`` library, in the same run.

    python bench/recording.py [--size-gb 1.0] [--array-mb 128] [--poses 100000]

1. write and read throughput (MB/s of payload) of 1 MiB float32 arrays and of small
   Pose2D messages, each as a ratio to the bare mcap library writing/reading the same
   payload bytes with the same chunk size and compression (target >= 0.8);
   Then the same for a file another tool wrote without chunks or summary (the forward-scan
   path of the reader: raw payloads, against the library's streaming reader);
2. seeking to the middle of a ``--size-gb`` recording (time to the first message, and
   its ratio to a full scan);
3. peak memory (RSS) of a process replaying that file through io.Replayer (target < 200 MB).

Prints figures; the last line is one JSON object.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from mcap.reader import NonSeekingReader, make_reader
from mcap.writer import CompressionType, IndexType, Writer

import impala_msgs
from impala_flow import msgs
from impala_flow.io import COMPRESSIONS, CodecRegistry, MissionReader, MissionWriter, run_codecs

MiB = 1 << 20
BARE = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}


def best_of(n: int, fn: Callable[[], None]) -> float:
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def bare_write(path: Path, payloads: list[bytes], schema: bytes, compression: str,
               chunk_size: int) -> None:
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=chunk_size, compression=BARE[compression])
        w.start()
        sid = w.register_schema("bench", "impala-flow/v1", schema)
        cid = w.register_channel("x", "impala-flow-bin", sid)
        for i, p in enumerate(payloads):
            w.add_message(cid, i * 1000, p, i * 1000, i)
        w.finish()


def ours_write(path: Path, values: list, t: type, reg: CodecRegistry, compression: str,
               chunk_size: int) -> None:
    with MissionWriter(path, codecs=reg, compression=compression, chunk_size=chunk_size,
                       foxglove=False, flush_period_s=None) as w:
        w.add_topic("x", t)
        for i, v in enumerate(values):
            w.write("x", i * 1000, v, i)


def bare_read(path: Path, validate_crcs: bool = False) -> int:
    n = 0
    with open(path, "rb") as f:
        for _, _, m in make_reader(f, validate_crcs=validate_crcs).iter_messages():
            n += len(m.data)
    return n


def ours_read(path: Path, reg: CodecRegistry) -> int:
    n = 0
    with MissionReader(path, reg) as r:
        for _ in r.messages():
            n += 1
    return n


def throughput(name: str, values: list, t: type, reg: CodecRegistry, tmp: Path,
               compression: str, chunk_size: int, reps: int) -> dict[str, float]:
    codec = reg.for_type(t)
    payloads = [codec.encode(v) for v in values]
    mb = sum(len(p) for p in payloads) / 1e6
    a, b = tmp / f"{name}-bare.mcap", tmp / f"{name}-ours.mcap"
    tw_bare = best_of(reps, lambda: bare_write(a, payloads, codec.schema_data(),
                                               compression, chunk_size))
    tw_ours = best_of(reps, lambda: ours_write(b, values, t, reg, compression, chunk_size))
    tr_bare = best_of(reps, lambda: bare_read(a))
    tr_bare_crc = best_of(reps, lambda: bare_read(a, True))
    tr_ours = best_of(reps, lambda: ours_read(b, reg))
    out = {
        f"{name}_write_MBps": mb / tw_ours, f"{name}_write_bare_MBps": mb / tw_bare,
        f"{name}_write_ratio_vs_mcap": tw_bare / tw_ours,
        f"{name}_read_MBps": mb / tr_ours, f"{name}_read_bare_MBps": mb / tr_bare,
        f"{name}_read_ratio_vs_mcap": tr_bare / tr_ours,
        f"{name}_read_ratio_vs_mcap_crc": tr_bare_crc / tr_ours,
    }
    print(f"{name:>6}: {len(values)} msgs, {mb:.1f} MB payload, {compression}")
    print(f"        write {mb / tw_ours:8.1f} MB/s  (bare mcap {mb / tw_bare:8.1f})  "
          f"ratio {tw_bare / tw_ours:.2f}")
    print(f"        read  {mb / tr_ours:8.1f} MB/s  (bare mcap {mb / tr_bare:8.1f}, with CRC "
          f"{mb / tr_bare_crc:8.1f})  ratio {tr_bare / tr_ours:.2f} / "
          f"{tr_bare_crc / tr_ours:.2f} (CRC-checked, like ours)")
    return out


def foreign(tmp: Path, n: int, reps: int) -> dict[str, float]:
    """An unchunked, unindexed file without summary (as some tools write): our forward scan
    (raw payloads) against the library's streaming reader."""
    path = tmp / "foreign.mcap"
    payload = bytes(64)
    with open(path, "wb") as f:
        w = Writer(f, use_chunking=False, index_types=IndexType.NONE, use_statistics=False,
                   use_summary_offsets=False, repeat_channels=False, repeat_schemas=False)
        w.start()
        cid = w.register_channel("x", "raw", w.register_schema("x", "raw", b""))
        for i in range(n):
            w.add_message(cid, i * 1000, payload, i * 1000, i)
        w.finish()
    mb = n * len(payload) / 1e6

    def ours() -> None:
        with MissionReader(path) as r:
            for _ in r.messages(raw=True):
                pass

    def bare() -> None:
        with open(path, "rb") as f:
            for _ in NonSeekingReader(f).iter_messages(log_time_order=False):
                pass

    t_ours, t_bare = best_of(reps, ours), best_of(reps, bare)
    print(f"foreign: {n} msgs unchunked, no summary: read {mb / t_ours:8.1f} MB/s (bare mcap streaming "
          f"{mb / t_bare:8.1f})  ratio {t_bare / t_ours:.2f}")
    return {"foreign_read_MBps": mb / t_ours, "foreign_read_bare_MBps": mb / t_bare,
            "foreign_read_ratio_vs_mcap": t_bare / t_ours}


def json_views(tmp: Path, n: int, reps: int, reg: CodecRegistry) -> dict[str, float]:
    """What the JSON views (generic decodability of every stream) cost: the same scalar and
    beam streams written with and without them (write time, file size)."""
    from impala_radar.simulator.presets import IMPALA  # the beams' config, as a simulated mission has it

    speeds = [impala_msgs.Speed(1.0 + 1e-3 * i, 0.01) for i in range(n)]
    rng = np.random.default_rng(2)  # spectra that differ, as real ones do (zstd finds no repeats)
    beams = [impala_msgs.RadarBeam(0.01 * i, i // 360, i % 360, rng.random(IMPALA.n_bins, dtype=np.float32),
                            rng.random(IMPALA.n_bins, dtype=np.float32), IMPALA) for i in range(n // 4)]
    out = {}
    for label, items, t in (("scalar", speeds, impala_msgs.Speed), ("beam", beams, impala_msgs.RadarBeam)):
        sizes, times = {}, {}
        for views in (False, True):
            path = tmp / f"views-{label}-{views}.mcap"

            def write(path: Path = path, views: bool = views, t: type = t, items: list = items) -> None:
                with MissionWriter(path, codecs=reg, json_views=views, flush_period_s=None) as w:
                    w.add_topic("x", t)
                    for i, m in enumerate(items):
                        w.write("x", i * 1000, m)

            times[views] = best_of(reps, write)
            sizes[views] = path.stat().st_size
        extra_us = (times[True] - times[False]) / len(items) * 1e6
        print(f"json views, {label} stream ({len(items)} msgs): write x{times[True] / times[False]:.2f} time "
              f"(+{extra_us:.1f} us per message), file x{sizes[True] / sizes[False]:.2f} size")
        out |= {f"json_views_{label}_write_time_ratio": times[True] / times[False],
                f"json_views_{label}_extra_us_per_msg": extra_us,
                f"json_views_{label}_size_ratio": sizes[True] / sizes[False]}
    return out


def make_big(path: Path, size_gb: float, reg: CodecRegistry) -> tuple[int, int]:
    """A mission of ~size_gb: a 1 MiB float32 image at 10 Hz, poses at 100 Hz."""
    rng = np.random.default_rng(0)
    pool = [rng.random(MiB // 4, dtype=np.float32) for _ in range(8)]  # chunks don't repeat
    n_images = max(4, int(size_gb * 1024))
    with MissionWriter(path, codecs=reg, compression="zstd", chunk_size=4 * MiB) as w:
        w.add_topic("radar/image", np.ndarray)
        w.add_topic("slam/pose", msgs.Pose2D)
        for k in range(n_images):
            t = k * 100_000_000
            w.write("radar/image", t, pool[k % len(pool)], k)
            for j in range(10):
                w.write("slam/pose", t + j * 10_000_000, msgs.Pose2D(k + j / 10, 0.0, 0.0), k)
    return 0, (n_images - 1) * 100_000_000


# VmHWM, not ru_maxrss: Linux keeps ru_maxrss across exec, i.e. the parent's peak
REPLAY_RSS = """
import sys
from impala_flow import Component, Input
from impala_flow.testing import run_components
from impala_flow.io import Replayer
class Null(Component):
    def process(self, t):
        for p in self.inputs.values():
            while len(p):
                p.take()
rep = Replayer("mission", path=sys.argv[1])
null = Null("null")
from impala_flow import InputPort
null.inputs = {k: InputPort(null, k, Input(object)) for k in rep.outputs}
run_components(rep, null, connections=[f"mission.{k} -> null.{k}" for k in rep.outputs])
hwm = [l for l in open("/proc/self/status") if l.startswith("VmHWM:")][0]
print(int(hwm.split()[1]) / 1024)
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size-gb", type=float, default=1.0, help="size of the seek/replay file")
    ap.add_argument("--array-mb", type=int, default=128, help="MiB of 1 MiB arrays to write")
    ap.add_argument("--poses", type=int, default=100_000, help="number of small pose messages")
    ap.add_argument("--compression", default="zstd", choices=sorted(COMPRESSIONS))
    ap.add_argument("--reps", type=int, default=3, help="repetitions (best time kept)")
    ap.add_argument("--dir", default=None, help="where to write the files (default: tmp)")
    args = ap.parse_args()
    reg = run_codecs()  # the run's codecs: standard types and the view plugin's mirrors
    result: dict[str, float] = {}
    with tempfile.TemporaryDirectory(dir=args.dir) as d:
        tmp = Path(d)
        rng = np.random.default_rng(1)
        arrays = [rng.random(MiB // 4, dtype=np.float32) for _ in range(args.array_mb)]
        result |= throughput("array", arrays, np.ndarray, reg, tmp, args.compression, MiB,
                             args.reps)
        del arrays
        poses = [msgs.Pose2D(i * 0.1, -i * 0.2, 0.001 * i) for i in range(args.poses)]
        result |= throughput("pose", poses, msgs.Pose2D, reg, tmp, args.compression, MiB,
                             args.reps)
        del poses
        result |= foreign(tmp, args.poses, args.reps)
        result |= json_views(tmp, args.poses // 4, args.reps, reg)

        big = tmp / "big.mcap"
        t0 = time.perf_counter()
        start_ns, end_ns = make_big(big, args.size_gb, reg)
        size_mb = big.stat().st_size / 1e6
        print(f"  big: {size_mb:.0f} MB written in {time.perf_counter() - t0:.1f} s")
        mid = (start_ns + end_ns) // 2

        def seek() -> None:
            with MissionReader(big, reg) as r:
                m = next(iter(r.messages(start_ns=mid)))
                assert m.t_ns >= mid

        def scan() -> None:
            with MissionReader(big, reg) as r:
                for _ in r.messages():
                    pass

        seek_s = best_of(args.reps, seek)
        scan_s = best_of(1, scan)
        print(f" seek: middle of {size_mb:.0f} MB in {seek_s * 1e3:.2f} ms, full scan "
              f"{scan_s:.2f} s, ratio {seek_s / scan_s:.5f}")
        env = dict(os.environ)
        here = Path(__file__).resolve().parents[1]
        env["PYTHONPATH"] = os.pathsep.join([str(here), str(here / "plugins"),
                                             env.get("PYTHONPATH", "")])
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "-c", REPLAY_RSS, str(big)], env=env,
                             capture_output=True, text=True, check=True)
        rss = float(out.stdout.strip().splitlines()[-1])
        print(f"  rss: replaying {size_mb:.0f} MB through io.Replayer: peak {rss:.0f} MB "
              f"({time.perf_counter() - t0:.1f} s)")
        result |= {"file_MB": size_mb, "seek_ms": seek_s * 1e3, "full_scan_s": scan_s,
                   "seek_ratio_vs_scan": seek_s / scan_s, "peak_rss_mb": rss}
    print(json.dumps({k: round(v, 5) for k, v in result.items()}))


if __name__ == "__main__":
    main()
