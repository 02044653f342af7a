"""Samples, components, parameters, read-only fan-out."""

from __future__ import annotations

import numpy as np
import pytest

from impala_flow import Component, Input, Output, Param, ParamError, Sample
from impala_flow.testing import CollectingSink, ScriptedSource, run_components

from .components import ArraySource, Scale


def test_sample_carries_integer_nanoseconds():
    s = Sample(1_500_000_000, 3.0, seq=2, origin="a.out")
    assert s.t_ns == 1_500_000_000 and isinstance(s.timestamp, int)


class Typed(Component):
    mode = Param(str, default="fast", choices=("fast", "exact"))
    n = Param(int, default=3, ge=1, le=10)
    gain = Param(float, gt=0.0)          # required: no default
    flags = Param(list, default=[])


@pytest.mark.parametrize(
    "params, problem",
    [
        ({}, "required"),
        ({"gain": 1.0, "mode": "slow"}, "not one of"),
        ({"gain": 1.0, "n": 0}, ">= 1"),
        ({"gain": 1.0, "n": 11}, "<= 10"),
        ({"gain": 1.0, "n": 2.5}, "expected int"),
        ({"gain": 1.0, "n": True}, "expected int"),
        ({"gain": 0.0}, "> 0.0"),
        ({"gain": "1"}, "expected float"),
        ({"gain": float("nan")}, "NaN"),
        ({"gain": 1.0, "gian": 2}, "did you mean 'gain'"),
    ],
)
def test_parameters_are_validated_before_anything_runs(params, problem):
    with pytest.raises(ParamError, match=problem):
        Typed("t", **params)


def test_parameter_conversion_and_defaults():
    t = Typed("t", gain=2)
    assert t.gain == 2.0 and isinstance(t.gain, float)
    assert t.mode == "fast" and t.n == 3 and t.flags == []


def test_emitted_arrays_are_read_only_and_shared_by_every_input():
    src = ArraySource("src", n=3)
    a, b = CollectingSink("a"), CollectingSink("b")
    run_components(src, a, b, connections=["src.out -> a.x", "src.out -> b.x"])
    assert len(a.samples) == 3
    for sa, sb in zip(a.samples, b.samples, strict=True):
        assert sa.data is sb.data  # fan-out without a copy
        assert not sa.data.flags.writeable
        with pytest.raises(ValueError):
            sa.data[0] = 1.0


def test_timestamps_must_be_integers():
    class FloatTime(Component):
        x = Input(float)
        y = Output(float)

        def process(self, t):
            self.y.emit(t / 1e9, 1.0)

    from impala_flow import ComponentError

    src = ScriptedSource("src", [(0, "out", 1.0)])
    with pytest.raises(ComponentError, match="int nanoseconds"):
        run_components(src, FloatTime("f"), connections=["src.out -> f.x"])


def test_lifecycle_order_start_process_stop():
    calls = []

    class Life(Component):
        x = Input(float)

        def start(self):
            calls.append("start")

        def process(self, t):
            calls.append(("process", t, self.x.take()))

        def stop(self):
            calls.append("stop")

    src = ScriptedSource("src", [(5, "out", 1.0), (7, "out", 2.0)])
    run_components(src, Life("l"), connections=["src.out -> l.x"])
    assert calls == ["start", ("process", 5, 1.0), ("process", 7, 2.0), "stop"]


def test_scale_end_to_end_with_testing_helpers():
    src = ScriptedSource("src", [(0, "out", 1.0), (10, "out", 2.5)])
    sink = CollectingSink("sink")
    run_components(src, Scale("s", gain=4.0), sink, connections=["src.out -> s.x", "s.y -> sink.x"])
    assert sink.values() == [4.0, 10.0] and sink.times() == [0, 10]
    assert np.all(np.diff(sink.times()) > 0)


def test_a_port_and_a_parameter_may_not_share_a_name():
    """self.<name> would be the port or the parameter depending on the order of set-up."""

    class Dynamic(Component):
        gain = Param(float, default=1.0)

        @classmethod
        def declare_ports(cls, params):
            return {"gain": Input(float)}, {"y": Output(float)}

    with pytest.raises(TypeError, match="component 'c' \\(Dynamic\\): 'gain' names two things"):
        Dynamic("c")

    class Static(Component):
        x = Input(float)

    with pytest.raises(TypeError, match="Both: 'x' names two things"):
        class Both(Static):  # noqa: F841
            x = Param(float, default=0.0)
