"""A failing component is named with its input and sample time; every stop() still runs."""

from __future__ import annotations

import pytest

from impala_flow import ComponentError, Network, OfflineExecutor, Output, Source
from impala_flow.testing import CollectingSink, connect

from .components import Boom, Counter


def build(on_error="stop"):
    net = Network()
    src, boom, sink = Counter("src", n=6, period_ns=1_000), Boom("boom", at=3.0), CollectingSink("sink")
    net.add(src)
    net.add(boom, on_error=on_error)
    net.add(sink)
    connect(net, "src.out -> boom.x")
    connect(net, "boom.y -> sink.x")
    return net, boom, sink


def test_component_error_names_component_input_and_time_and_stops_everyone():
    net, boom, sink = build()
    with pytest.raises(ComponentError) as ei:
        OfflineExecutor(net).run()
    msg = str(ei.value)
    assert msg == "component 'boom', input 'x', sample t=3000 ns: ValueError: bad value 3.0"
    assert boom.stopped and sink.values() == [0.0, 1.0, 2.0]
    assert ei.value.summary.error == msg  # the partial summary travels with the error


def test_on_error_skip_counts_and_continues():
    net, boom, sink = build("skip")
    summary = OfflineExecutor(net).run()
    assert sink.values() == [0.0, 1.0, 2.0, 4.0, 5.0]
    assert summary.skipped == {"boom": 1}
    assert "1 skipped after errors" in summary.format()


def test_source_out_of_time_order_is_an_error():
    class Backwards(Source):
        out = Output(float)

        def generate(self):
            yield 10, "out", 1.0
            yield 5, "out", 2.0

    net = Network()
    net.add(Backwards("bw"))
    net.add(CollectingSink("sink"))
    connect(net, "bw.out -> sink.x")
    with pytest.raises(ComponentError, match="t=5 ns after t=10 ns"):
        OfflineExecutor(net).run()


def test_stop_event_interrupts_cleanly():
    import threading

    stop = threading.Event()

    class Endless(Source):
        out = Output(float)

        def generate(self):
            i = 0
            while True:
                if i == 5000:
                    stop.set()
                yield i, "out", 0.0
                i += 1

    net = Network()
    net.add(Endless("src"))
    sink = net.add(CollectingSink("sink"))
    connect(net, "src.out -> sink.x")
    summary = OfflineExecutor(net, stop_event=stop).run()
    assert summary.interrupted and 5000 <= len(sink.samples) < 6000
    assert "INTERRUPTED" in summary.format()


def test_a_source_clock_offset_is_applied_on_the_way_in():
    from impala_flow import Param

    class Gps(Source):
        out = Output(float)
        clock_offset_ns = Param(int, default=0)

        def generate(self):
            yield from ((t, "out", float(t)) for t in (0, 100, 200))

    net = Network()
    net.add(Gps("gps", clock_offset_ns=-50))
    sink = net.add(CollectingSink("sink"))
    connect(net, "gps.out -> sink.x")
    OfflineExecutor(net).run()
    assert sink.times() == [-50, 50, 150] and sink.values() == [0.0, 100.0, 200.0]


def test_flush_runs_once_at_the_end_and_may_emit():
    from impala_flow import Component, Input

    class Acc(Component):
        x = Input(float)
        total = Output(float)

        def start(self):
            self.sum = 0.0
            self.flushed = []

        def process(self, t):
            self.sum += self.x.take()

        def flush(self, t):
            self.flushed.append(t)
            self.total.emit(t, self.sum)

    net = Network()
    net.add(Counter("src", n=4, period_ns=10))
    acc = net.add(Acc("acc"))
    sink = net.add(CollectingSink("sink"))
    connect(net, "src.out -> acc.x")
    connect(net, "acc.total -> sink.x")
    OfflineExecutor(net).run()
    assert acc.flushed == [30] and sink.values() == [0.0 + 1.0 + 2.0 + 3.0] and sink.times() == [30]
