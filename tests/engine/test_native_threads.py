"""A run limits the BLAS libraries' own threads (impala_flow._native): 1 by default from the
components' start() to their stop(), the libraries' previous counts given back after, both
executors; ``blas_threads=None`` leaves them alone. The counts are read from the libraries
themselves by threadpoolctl (an independent view of the same setting)."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from impala_flow import Component, Input, Network, OfflineExecutor, Output, RealTimeExecutor, Source
from impala_flow.testing import connect

ROOT = Path(__file__).resolve().parents[2]


def _blas() -> dict[str, int]:
    return {i["filepath"]: i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}


class Ticks(Source):
    out = Output(float)

    def generate(self):
        for i in range(4):
            yield i * 1_000_000, "out", float(i)


class Probe(Component):
    """Reads the BLAS libraries' thread counts in start() and in every process()."""

    x = Input(float)
    y = Output(float)

    def start(self) -> None:
        self.seen = [_blas()]

    def process(self, t: int) -> None:
        v = self.x.take()
        a = np.full((64, 64), v)
        self.seen.append(_blas())
        self.y.emit(t, float((a @ a)[0, 0]))


def _net() -> Network:
    net = Network(name="blas")
    net.add(Ticks("src"))
    net.add(Probe("probe"))
    connect(net, "src.out -> probe.x")
    return net


@pytest.fixture
def two_blas_threads():
    """Every BLAS library at 2 threads before the run (whatever this machine's core count)."""
    with threadpool_limits(limits=2, user_api="blas"):
        yield _blas()


@pytest.mark.parametrize("executor", ["offline", "realtime"])
def test_a_run_holds_blas_at_one_thread_and_gives_the_count_back(executor: str, two_blas_threads: dict) -> None:
    assert two_blas_threads and set(two_blas_threads.values()) == {2}
    net = _net()
    run = OfflineExecutor(net) if executor == "offline" else RealTimeExecutor(net)
    summary = run.run()
    seen = net.components["probe"].seen
    assert len(seen) == 5 and summary.processed["probe"] == 4
    assert all(set(s.values()) == {1} for s in seen), seen
    assert summary.blas_threads == 1 and summary.to_json()["blas_threads"] == 1
    assert _blas() == two_blas_threads  # after the run: the libraries' own counts again


def test_blas_threads_none_leaves_the_libraries_alone(two_blas_threads: dict) -> None:
    net = _net()
    summary = OfflineExecutor(net, blas_threads=None).run()
    assert all(s == two_blas_threads for s in net.components["probe"].seen)
    assert summary.blas_threads is None and _blas() == two_blas_threads


def test_the_count_comes_back_when_a_component_fails(two_blas_threads: dict) -> None:
    class Failing(Probe):
        def process(self, t: int) -> None:
            raise ValueError("bad sample")

    net = Network(name="blas")
    net.add(Ticks("src"))
    net.add(Failing("probe"))
    connect(net, "src.out -> probe.x")
    with pytest.raises(Exception, match="probe"):
        OfflineExecutor(net, blas_threads=3).run()
    assert _blas() == two_blas_threads


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2"])
def test_a_bad_count_is_refused_naming_it(bad: object) -> None:
    with pytest.raises(ValueError, match="blas_threads"):
        OfflineExecutor(_net(), blas_threads=bad)  # type: ignore[arg-type]


SCRIPT = """
import json, numpy as np
from threadpoolctl import threadpool_info
from impala_flow import Component, Input, Network, OfflineExecutor, Output, Source
from impala_flow.testing import connect

def blas():
    return sorted((i["filepath"], i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas")

class Src(Source):
    out = Output(float)
    def generate(self):
        yield 0, "out", 1.0

class LoadsScipy(Component):
    x = Input(float)
    def start(self):
        self.before = blas()
        import scipy.linalg  # SciPy's own OpenBLAS, loaded here, after the run's limit was set
        self.loaded = blas()
    def process(self, t):
        self.x.take()
        self.during = blas()

net = Network(name="late")
net.add(Src("src")); net.add(LoadsScipy("c")); connect(net, "src.out -> c.x")
OfflineExecutor(net).run()
c = net.components["c"]
print(json.dumps({"before": c.before, "loaded": c.loaded, "during": c.during, "after": blas()}))
"""


def test_a_blas_library_loaded_in_start_is_limited_too() -> None:
    import json

    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(ROOT / "plugins")]),
               OPENBLAS_NUM_THREADS="2")  # the libraries' own count, the same on any machine
    env.pop("OMP_NUM_THREADS", None)
    r = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    late = {f for f, _ in d["loaded"]} - {f for f, _ in d["before"]}
    assert late and all(n == 1 for _, n in d["before"])  # SciPy's library, loaded by start() at its own count
    assert all(n == 2 for f, n in d["loaded"] if f in late), d
    assert [f for f, _ in d["during"]] == [f for f, _ in d["loaded"]] and all(n == 1 for _, n in d["during"]), d
    assert all(n == 2 for _, n in d["after"]), d


def test_a_live_run_from_another_thread_restores_too(two_blas_threads: dict) -> None:
    """A run started from a thread of the program (a GUI, a notebook) gives the counts back the same."""
    out: list = []
    th = threading.Thread(target=lambda: out.append(RealTimeExecutor(_net()).run()))
    th.start()
    th.join(60)
    assert out and out[0].blas_threads == 1 and _blas() == two_blas_threads
