"""A real multi-process Dask cluster on the loopback interface: `dask scheduler` and two
`dask worker` processes, and `impala-flow sweep --scheduler tcp://127.0.0.1:PORT` against it."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from .conftest import GRAPH, ROOT, assert_row_is_the_plain_run, env_without_plugin_blocks, plain_run, read_rows

DASK = Path(sys.executable).parent / "dask"
METRICS = ["eval.ate_rmse_m", "eval.drift_pct"]


def _stop(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
    for p in procs:
        try:
            p.wait(timeout=20)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()


@pytest.fixture
def cluster(tmp_path: Path) -> Iterator[tuple[str, list[subprocess.Popen]]]:
    """(scheduler address, [scheduler, worker, worker]), stopped afterwards."""
    file = tmp_path / "scheduler.json"
    env = env_without_plugin_blocks()
    logs = tmp_path / "dask-logs"
    logs.mkdir()
    procs: list[subprocess.Popen] = []

    def start(name: str, *args: str) -> None:
        out = open(logs / f"{name}.log", "w")  # noqa: SIM115 - closed with the process
        procs.append(subprocess.Popen([str(DASK), *args], stdout=out, stderr=subprocess.STDOUT, env=env,
                                      cwd=tmp_path))
        out.close()

    try:
        start("scheduler", "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
              "--scheduler-file", str(file))
        deadline = time.monotonic() + 60
        while not file.exists() and time.monotonic() < deadline:
            assert procs[0].poll() is None, (logs / "scheduler.log").read_text()
            time.sleep(0.1)
        address = json.loads(file.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        for i in (1, 2):
            start(f"worker{i}", "worker", address, "--host", "127.0.0.1", "--nthreads", "1", "--nworkers", "1",
                  "--no-dashboard", "--name", f"w{i}", "--local-directory", str(tmp_path / f"w{i}"))
        while time.monotonic() < deadline:  # both workers registered
            n = sum("Registered to:" in (logs / f"worker{i}.log").read_text() for i in (1, 2))
            if n == 2:
                break
            for p in procs:
                assert p.poll() is None, [(f.name, f.read_text()[-2000:]) for f in logs.iterdir()]
            time.sleep(0.2)
        else:
            pytest.fail("the workers did not register in 60 s")
        yield address, procs
    finally:
        _stop(procs[1:])
        _stop(procs[:1])


def test_a_sweep_on_a_scheduler_and_two_worker_processes(cluster: tuple[str, list[subprocess.Popen]],
                                                          missions: list[Path], tmp_path: Path,
                                                          write_sweep: Callable[..., Path]) -> None:
    address, procs = cluster
    sweep = write_sweep(f"""\
graph: {GRAPH}
missions: {{files: ["{missions[0]}", "{missions[1]}"]}}
grid: {{slam.search_m: [1.0, 2.0]}}
metrics: [{", ".join(METRICS)}]
""")
    out = tmp_path / "out"
    run = subprocess.run([sys.executable, "-m", "impala_flow", "sweep", str(sweep), "-o", str(out),
                          "--scheduler", address], capture_output=True, text=True, timeout=300, cwd=ROOT,
                         env=env_without_plugin_blocks())
    assert run.returncode == 0, run.stderr
    assert f"on a scheduler {address}" in run.stderr
    rows = read_rows(out)
    assert len(rows) == 4 and {r["status"] for r in rows} == {"ok"}
    # the two `dask worker` processes ran them, none the client
    worker_pids = {int(r["worker"].rsplit(":", 1)[1]) for r in rows}
    assert len(worker_pids) == 2 and run.returncode == 0
    assert all(os.path.exists(f"/proc/{pid}") for pid in worker_pids)  # still running: the cluster's workers
    for r in rows[:2]:  # the figures of the same graph run alone
        mission = next(m for m in missions if str(m.resolve()) == r["mission"])
        assert_row_is_the_plain_run(r, plain_run(mission, tmp_path / f"plain-{r['task']}",
                                                 f"slam.search_m={r['slam.search_m']}"), METRICS)
    assert all(p.poll() is None for p in procs)  # the sweep leaves the cluster running
