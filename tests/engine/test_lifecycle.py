"""The lifecycle both executors share (impala_flow._lifecycle): the same start and stop
order, the same error naming and the same counters, whichever executor runs the graph."""

from __future__ import annotations

import pytest

from impala_flow import Component, Input, Network, OfflineExecutor, Output, RealTimeExecutor, Source
from impala_flow.testing import connect


class Log(list):
    pass


class Src(Source):
    out = Output(float)

    def generate(self):
        for i in range(3):
            yield i * 1000, "out", float(i)


class Step(Component):
    x = Input(float)
    y = Output(float)

    def process(self, t):
        self.y.emit(t, self.x.take())


def _traced(cls, log, fail_start=False, fail_stop=False):
    class Traced(cls):
        def start(self):
            log.append(f"start {self.name}")
            if fail_start:
                raise OSError("no device")

        def stop(self):
            log.append(f"stop {self.name}")
            if fail_stop:
                raise RuntimeError("cannot close")

    Traced.__name__ = cls.__name__
    return Traced


def _net(log, **kw):
    # added in an order that is neither the graph order nor alphabetical
    comps = [_traced(Step, log, **kw.get("c", {}))(name="c"), _traced(Src, log)(name="src"),
             _traced(Step, log)(name="b"), _traced(Step, log, **kw.get("a", {}))(name="a")]
    net = Network(name="life")
    for c in comps:
        net.add(c)
    for spec in ("src.out -> b.x", "src.out -> a.x", "b.y -> c.x", "a.y -> c.x"):
        connect(net, spec)
    return net


def _run(executor, net):
    if executor == "offline":
        return OfflineExecutor(net).run()
    return RealTimeExecutor(net, drain_timeout_s=1.0, stop_timeout_s=2.0).run()


@pytest.mark.parametrize("executor", ["offline", "realtime"])
def test_components_start_and_stop_in_graph_order_ties_by_id(executor):
    log = Log()
    summary = _run(executor, _net(log))
    assert log == ["start src", "start a", "start b", "start c", "stop src", "stop a", "stop b", "stop c"]
    assert summary.processed == {"src": 0, "a": 3, "b": 3, "c": 6}
    assert summary.emitted == {"src.out": 3, "a.y": 3, "b.y": 3, "c.y": 6}


@pytest.mark.parametrize("executor", ["offline", "realtime"])
def test_a_failed_start_stops_what_started_and_later_failures_are_their_own_lines(executor):
    log = Log()
    with pytest.raises(Exception) as ei:
        _run(executor, _net(log, a={"fail_start": True}, c={}))
    assert str(ei.value) == "component 'a', in start(): OSError: no device"
    assert log == ["start src", "start a", "stop src", "stop a"]  # b and c never started
    log2 = Log()
    with pytest.raises(Exception) as ei2:
        _run(executor, _net(log2, a={"fail_start": True, "fail_stop": True}))
    assert str(ei2.value) == "component 'a', in start(): OSError: no device"
    assert ei2.value.summary.errors == ["component 'a', in stop(): RuntimeError: cannot close"]
