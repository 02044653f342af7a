"""Inputs bounded in bytes, not only in count (issue 24: "bounded by construction").

A producer of 1 MiB arrays feeds a consumer that does not keep up (a sync group whose
partner stopped offline, a slow or gated consumer in real time): the bytes an input holds
never exceed its ``maxbytes``, the overflow policy applies to bytes as to counts, every drop
is counted and printed, and offline runs stay deterministic.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from typing import Any

import numpy as np
import pytest

from impala_flow import Component, Input, OutOfHistory, Output, Param, Source
from impala_flow._network import Network
from impala_flow._offline import OfflineExecutor
from impala_flow._ports import DEFAULT_MAXBYTES, data_nbytes
from impala_flow._summary import ComponentError, RunSummary
from impala_flow.testing import CollectingSink, connect

from .test_runtime import HANG_S, run_rt

MIB = 1 << 20
MS = 1_000_000
N_MIB = MIB // 8  # float64 elements of a 1 MiB array


def mib_array(i: int) -> np.ndarray:
    return np.full(N_MIB, float(i))


class Arrays(Source):
    """``n`` arrays of 1 MiB (all values ``i``) on ``a`` every 100 ms; on ``b`` only the first ``b_n``."""

    a = Output(np.ndarray)
    b = Output(np.ndarray)
    n = Param(int, default=20)
    b_n = Param(int, default=2)

    def generate(self):
        for i in range(self.n):
            yield i * 100 * MS, "a", mib_array(i)
            if i < self.b_n:
                yield i * 100 * MS, "b", np.zeros(4)


class Pair(Component):
    """Sync group of ``a`` and ``b``, ``a`` bounded at ``maxbytes`` with ``overflow``."""

    out = Output(object)
    maxbytes = Param(int, default=4 * MIB)
    overflow = Param(str, default="drop_oldest")

    @classmethod
    def declare_ports(cls, params: dict[str, Any]) -> tuple[dict[str, Input], dict[str, Output]]:
        return ({"a": Input(np.ndarray, sync="ab", maxbytes=params["maxbytes"], overflow=params["overflow"]),
                 "b": Input(np.ndarray, sync="ab")}, {"out": Output(object)})

    def process(self, t: int) -> None:
        self.out.emit(t, float(self.a.take()[0]))
        self.b.take()


def net_of(*comps: Component, connections: list[str]) -> Network:
    net = Network(name="bytes")
    for c in comps:
        net.add(c)
    for spec in connections:
        connect(net, spec)
    return net


def run_pair(overflow: str) -> tuple[RunSummary, list[Any]]:
    sink = CollectingSink("sink")
    net = net_of(Arrays("src"), Pair("pair", overflow=overflow), sink,
                 connections=["src.a -> pair.a", "src.b -> pair.b", "pair.out -> sink.x"])
    return OfflineExecutor(net).run(), sink.values()


# --- offline ----------------------------------------------------------------------------------
def test_offline_sync_partner_stopped_drop_oldest_keeps_the_bytes_bounded_and_counts_drops() -> None:
    summary, values = run_pair("drop_oldest")
    assert values == [0.0, 1.0]  # a0-b0, a1-b1 matched; then b stopped
    st = summary.inputs["pair.a"]
    # a2..a19 wait for b: 4 arrays of 1 MiB fit in 4 MiB, each later one pushes the oldest out
    assert st["high_water_bytes"] == 4 * MIB
    assert st["dropped_maxbytes"] == 18 - 4
    assert st["unmatched"] == 4 and st["dropped"] == 0  # a16..a19 left at the end
    assert summary.drops()["pair.a"] == {"dropped_maxbytes": 14, "unmatched": 4}
    assert "  LOST at pair.a: 14 dropped (the input held its maxbytes), 4 unmatched" in summary.format().splitlines()
    again, values2 = run_pair("drop_oldest")  # deterministic: the same drops, the same outputs
    assert values2 == values and again.inputs == summary.inputs


def test_offline_drop_newest_by_bytes() -> None:
    summary, _ = run_pair("drop_newest")
    st = summary.inputs["pair.a"]
    assert st["high_water_bytes"] == 4 * MIB and st["dropped_maxbytes"] == 14 and st["unmatched"] == 4


def test_offline_block_refuses_to_grow_past_maxbytes_with_one_line() -> None:
    with pytest.raises(ComponentError) as ei:
        run_pair("block")
    msg = str(ei.value)
    assert "\n" not in msg
    # a2..a5 (4 MiB) wait; a6, at 600 ms, would take the input over its 4 MiB
    assert msg.startswith(f"component 'pair', input 'a', sample t={600 * MS} ns: BufferError: 4 samples (4.0 MiB) "
                          "wait at this input, the next would take it over its maxbytes 4.0 MiB")
    assert ei.value.summary.inputs["pair.a"]["high_water_bytes"] == 4 * MIB  # type: ignore[attr-defined]


class Each(Component):
    """Reactive input bounded at ``maxbytes``; keeps the first value of every array it takes."""

    x = Input(np.ndarray, maxbytes=1000)

    def start(self) -> None:
        self.got: list[float] = []

    def process(self, t: int) -> None:
        self.got.append(float(self.x.take()[0]))


def test_a_sample_larger_than_maxbytes_alone_is_still_delivered() -> None:
    each = Each("each")
    summary = OfflineExecutor(net_of(Arrays("src", n=5, b_n=0), each, connections=["src.a -> each.x"])).run()
    assert each.got == [0.0, 1.0, 2.0, 3.0, 4.0] and summary.total_lost == 0


class Recall(Component):
    """History of 1 MiB arrays bounded at 3 MiB; at ``q`` looks values up at 850 and 650 ms."""

    arr = Input(np.ndarray, policy="sampling", history=10.0, maxbytes=3 * MIB)
    q = Input(float)

    def start(self) -> None:
        self.found: dict[int, Any] = {}

    def process(self, t: int) -> None:
        self.q.take()
        for t_ms in (850, 650):
            try:
                self.found[t_ms] = self.arr.at(t_ms * MS)
            except OutOfHistory as e:
                self.found[t_ms] = e


class Query(Source):
    q = Output(float)

    def generate(self):
        yield 1000 * MS, "q", 0.0


def test_history_is_trimmed_by_bytes_and_still_interpolates() -> None:
    recall = Recall("recall")
    summary = OfflineExecutor(net_of(Arrays("src", n=10, b_n=0), Query("query"), recall,
                                     connections=["src.a -> recall.arr", "query.q -> recall.q"])).run()
    # 10 s of history would keep all 10 arrays (10 MiB); 3 MiB keeps the last 3 (i = 7, 8, 9)
    assert summary.inputs["recall.arr"]["history_trimmed"] == 7
    np.testing.assert_array_equal(recall.found[850], np.full(N_MIB, 8.5))  # linear between i=8 and i=9
    assert isinstance(recall.found[650], OutOfHistory)  # before the samples kept: said, never extrapolated
    assert "  TRIMMED at recall.arr: 7 history samples trimmed before their time (the history buffer held its " \
           "maxbytes)" in summary.format().splitlines()


# --- real time --------------------------------------------------------------------------------
class Burst(Source):
    """Non-live: ``n`` arrays of 1 MiB 1 µs apart (released at once); sets ``sent`` after the last."""

    out = Output(np.ndarray)
    n = Param(int, default=10)

    def __init__(self, name: str, **kw: Any) -> None:
        super().__init__(name, **kw)
        self.sent = threading.Event()

    def generate(self):
        for i in range(self.n):
            yield i * 1000, "out", mib_array(i)
        self.sent.set()


class Slow(Component):
    """Input bounded at 3 MiB with ``overflow``; waits for ``gate`` (or sleeps) before each take."""

    overflow = Param(str, default="block")
    sleep_s = Param(float, default=0.0)
    gate: threading.Event | None = None

    @classmethod
    def declare_ports(cls, params: dict[str, Any]) -> tuple[dict[str, Input], dict[str, Output]]:
        return {"x": Input(np.ndarray, maxbytes=3 * MIB, overflow=params["overflow"])}, {}

    def start(self) -> None:
        self.got: list[float] = []

    def process(self, t: int) -> None:
        if self.gate is not None:
            assert self.gate.wait(HANG_S)
        time.sleep(self.sleep_s)
        self.got.append(float(self.x.take()[0]))


def test_real_time_block_by_bytes_makes_the_producer_wait_and_loses_nothing() -> None:
    slow = Slow("slow", overflow="block", sleep_s=0.005)
    summary = run_rt(net_of(Burst("src"), slow, connections=["src.out -> slow.x"]))
    assert slow.got == [float(i) for i in range(10)] and summary.total_lost == 0
    st = summary.inputs["slow.x"]
    assert 0 < st["high_water_bytes"] <= 3 * MIB and st["high_water"] <= 3  # 1024 by count, 3 by bytes
    assert st["blocked"] >= 1
    assert any(line.startswith("  BACKPRESSURE at slow.x: ") for line in summary.format().splitlines())


@pytest.mark.parametrize(("overflow", "kept"), [("drop_newest", [0.0, 1.0, 2.0]), ("drop_oldest", [7.0, 8.0, 9.0])])
def test_real_time_drop_policies_by_bytes_count_exactly(overflow: str, kept: list[float]) -> None:
    src = Burst("src")
    slow = Slow("slow", overflow=overflow)
    slow.gate = src.sent  # nothing is taken before the producer has pushed all 10
    summary = run_rt(net_of(src, slow, connections=["src.out -> slow.x"]))
    assert slow.got == kept
    st = summary.inputs["slow.x"]
    assert st["dropped_maxbytes"] == 7 and st["dropped"] == 0 and st["high_water_bytes"] == 3 * MIB
    assert "  LOST at slow.x: 7 dropped (the input held its maxbytes)" in summary.format().splitlines()


# --- sizes ------------------------------------------------------------------------------------
@dataclasses.dataclass
class Blob:
    image: np.ndarray
    name: str
    raw: bytes
    scale: float
    parts: list


def test_data_nbytes_sums_arrays_fields_and_containers() -> None:
    img = np.zeros((480, 640), np.uint8)
    parts = [np.zeros(1000, np.float32) for _ in range(200)]  # more than are measured: extrapolated
    blob = Blob(img, "cam0", b"\x00" * 300, 1.0, parts)
    assert data_nbytes(blob) == 480 * 640 + 4 + 300 + 8 + 200 * 4000
    assert data_nbytes({"a": np.zeros(10)}) == 1 + 80
    assert DEFAULT_MAXBYTES == 64 * MIB
    with pytest.raises(ValueError, match="maxbytes must be an int >= 1"):
        Input(float, maxbytes=0)


# --- the command a user runs ------------------------------------------------------------------
GRAPH = """
name: bytes-cli
clock: {{mode: replay, speed: max}}
components:
  src: {{type: t.Arrays}}
  pair: {{type: t.Pair, params: {{overflow: {overflow}}}}}
  sink: {{type: t.CollectingSink}}
connections:
  - src.a -> pair.a
  - src.b -> pair.b
  - pair.out -> sink.x
"""


@pytest.mark.parametrize("overflow", ["drop_oldest", "block"])
def test_impala_flow_run_prints_the_byte_drops_or_refuses_in_one_line(
        tmp_path, monkeypatch, capsys, overflow: str) -> None:
    import impala_flow.cli
    import impala_flow.cli._run
    from impala_flow._session import Session
    from impala_flow.testing import plugin_of

    monkeypatch.setattr(impala_flow.cli._run, "open_session", lambda: Session(
        extra_plugins={"t": plugin_of(Arrays, Pair, CollectingSink)}, entrypoints=False))
    graph = tmp_path / "g.yaml"
    graph.write_text(GRAPH.format(overflow=overflow))
    try:
        rc = impala_flow.cli.main(["run", str(graph), "--no-progress"])
    except SystemExit as e:
        rc = e.code
    err = capsys.readouterr().err
    assert "Traceback" not in err
    if overflow == "drop_oldest":
        assert not rc, err
        assert "  LOST at pair.a: 14 dropped (the input held its maxbytes), 4 unmatched" in err.splitlines()
    else:
        assert rc, err
        lines = [ln for ln in err.splitlines() if ln.startswith("impala-flow run: error:")]
        assert lines == [f"impala-flow run: error: component 'pair', input 'a', sample t={600 * MS} ns: BufferError: "
                         "4 samples (4.0 MiB) wait at this input, the next would take it over its maxbytes 4.0 MiB: "
                         "its consumer does not take them (a sync partner that stopped?); offline a 'block' input "
                         "never drops: give it more maxbytes or a drop policy"], err
