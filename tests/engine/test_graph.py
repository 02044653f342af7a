"""YAML graphs: include, variables, --set, every problem at once with file:line:col."""

from __future__ import annotations

import re
import textwrap

import pytest

from impala_flow import Component, Input, Output
from impala_flow._build import to_dot
from impala_flow._session import Session
from impala_flow._spec import GraphError
from impala_flow.testing import CollectingSink, plugin_of

from .components import Boom, Counter, Scale


class Adder(Component):
    a = Input(float)
    b = Input(float, required=False, policy="sampling")
    y = Output(float)

    def process(self, t):
        self.y.emit(t, self.a.take() + self.b.get(0.0))


class Text(Component):
    s = Input(str)


@pytest.fixture
def session():
    return Session(extra_plugins={"t": plugin_of(Counter, Scale, Boom, Adder, Text, CollectingSink)})


def write(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


def test_graph_runs_with_include_variables_and_overrides(tmp_path, session):
    write(tmp_path, "base.yaml", """
        variables: {n: 4, gain: 2.0}
        components:
          src: {type: t.Counter, params: {n: "${n}", period_ns: 1000}}
          scale: {type: t.Scale, params: {gain: "${gain}"}}
        connections:
          - src.out -> scale.x
    """)
    main = write(tmp_path, "main.yaml", """
        name: main
        include: base.yaml
        variables: {gain: 10.0}
        components:
          scale: {params: {gain: "${gain}"}}   # refine the included component
          sink: t.CollectingSink
        connections:
          - scale.y -> sink.x
    """)
    spec = session.load(main, overrides=["src.n=3"])
    assert spec.components["src"].params == {"n": 3, "period_ns": 1000}
    assert spec.components["scale"].params["gain"] == 10.0
    net = session.build(spec)
    session.run(net)
    assert net.components["sink"].values() == [0.0, 10.0, 20.0]
    assert spec.resolved()["connections"] == ["src.out -> scale.x", "scale.y -> sink.x"]


def test_every_problem_is_reported_at_once_with_locations(tmp_path, session):
    p = write(tmp_path, "bad.yaml", """\
        name: bad
        conection: []
        clock: {mode: replay, sped: 2}
        components:
          src: {type: t.Countr}
          scale: {type: t.Scale, params: {gain: -1, gian: 3}}
          add: {type: t.Adder}
          txt: {type: t.Text}
        connections:
          - src.out -> scale.x
          - scale.y -> add.c
          - scale.y -> txt.s
          - scale.nope -> add.a
          - not a connection
    """)
    with pytest.raises(GraphError) as ei:
        session.load(p)
    lines = [str(x) for x in ei.value.problems]
    f = str(p)
    expected = [
        f"{f}:2:1: unknown key 'conection' in graph (did you mean 'connections'?)",
        f"{f}:3:23: unknown key 'sped' in clock (did you mean 'speed'?)",
        f"{f}:14:5: cannot read connection 'not a connection': expected 'component.output -> component.input'",
        f"{f}:5:9: component 'src': unknown type 't.Countr' (closest installed: t.Counter",
        f"{f}:6:35: component 'scale' (t.Scale): parameter 'gain': -1.0 must be >= 0.0",
        f"{f}:6:45: component 'scale' (t.Scale): parameter 'gian': unknown parameter (did you mean 'gain'?)",
        f"{f}:11:5: connection 'scale.y -> add.c': 'add' (t.Adder) has no input 'c'",
        f"{f}:12:5: connection 'scale.y -> txt.s': output type float does not fit input type str",
        f"{f}:13:5: connection 'scale.nope -> add.a': 'scale' (t.Scale) has no output 'nope'",
        f"{f}:7:9: component 'add': required input 'a' is not connected",
    ]
    for e in expected:
        assert any(line.startswith(e) for line in lines), f"missing: {e}\n got:\n" + "\n".join(lines)
    assert len(lines) == len(expected)
    assert str(ei.value).startswith("10 problems in graph:")


def test_cycle_without_delay_is_rejected_and_with_delay_runs(tmp_path, session):
    text = """
        components:
          src: {type: t.Counter, params: {n: 3, period_ns: 10}}
          add: {type: t.Adder}
          scale: {type: t.Scale, params: {gain: 0.5}}
          sink: t.CollectingSink
        connections:
          - src.out -> add.a
          - add.y -> scale.x
          - scale.y -> add.b{delay}
          - add.y -> sink.x
    """
    p = write(tmp_path, "cyc.yaml", text.replace("{delay}", ""))
    with pytest.raises(GraphError, match=r"cyc.yaml:\d+:\d+: cycle without a delay: .*add.*scale"):
        session.load(p)
    p = write(tmp_path, "cyc2.yaml", text.replace("{delay}", " [delay]"))
    spec = session.load(p)
    net = session.build(spec)
    session.run(net)
    # y_k = k + 0.5 * y_(k-1) (feedback arrives after the same-time events, used at the next sample)
    assert net.components["sink"].values() == [0.0, 1.0, 2.5]


def test_safe_loader_refuses_python_tags(tmp_path, session):
    p = write(tmp_path, "evil.yaml", """
        components:
          src: !!python/object/apply:os.system ["echo pwned"]
    """)
    with pytest.raises(GraphError, match=r"evil.yaml:3:\d+: invalid YAML"):
        session.load(p)


def test_missing_include_undefined_variable_and_bad_set(tmp_path, session):
    p = write(tmp_path, "m.yaml", """
        include: [nothere.yaml]
        components:
          src: {type: t.Counter, params: {n: "${count}"}}
    """)
    with pytest.raises(GraphError) as ei:
        session.load(p, overrides=["srcc.n=3", "nodot=1"])
    text = str(ei.value)
    assert "included file not found: nothere.yaml" in text
    assert "undefined variable '${count}'" in text
    assert "--set srcc.n=3: no component 'srcc' (did you mean 'src'?)" in text
    assert "--set 'nodot=1': expected COMPONENT.PARAM=VALUE" in text


def test_the_engines_recorder_cannot_be_blocked(tmp_path, monkeypatch):
    """io.Recorder and io.Replayer are the engine's own: IMPALA_FLOW_DISABLE_PLUGINS=io leaves them
    (and only them: the other plugins listed are blocked), and a record: section still records."""
    monkeypatch.setenv("IMPALA_FLOW_DISABLE_PLUGINS", "io,radar")
    session = Session(extra_plugins={"t": plugin_of(Counter, CollectingSink)})
    assert {"io.Recorder", "io.Replayer"} <= set(session.registry.components)
    assert not any(n.startswith("radar.") for n in session.registry.components)
    p = write(tmp_path, "r.yaml", """
        components:
          src: {type: t.Counter, params: {n: 3}}
          sink: t.CollectingSink
        connections: [src.out -> sink.x]
        record: {path: out.mcap, streams: ["src.*"]}
    """)
    net = session.build(session.load(p))
    assert type(net.components["record"]).type_name == "io.Recorder"
    session.run(net)
    from impala_flow.io import MissionReader

    with MissionReader(tmp_path / "out.mcap") as r:
        assert [m.data for m in r.messages(["src/out"])] == [0, 1, 2]


def test_a_record_section_without_the_recorder_is_refused(tmp_path):
    """A registry not built by impala_flow.plugins (no engine components) cannot record: one line says why."""
    from impala_flow._load import read_graph
    from impala_flow._validate import validate
    from impala_flow.plugins import Registry

    p = write(tmp_path, "r.yaml", """
        components:
          src: {type: t.Counter}
        record: {path: out.mcap, streams: ["src.*"]}
    """)
    spec, problems = read_graph(p)
    problems += validate(spec, Registry())
    assert any("needs the 'io.Recorder' component (the engine's own" in pr.message for pr in problems), problems


def test_dot_export_lists_components_and_connections(tmp_path, session):
    p = write(tmp_path, "d.yaml", """
        components:
          src: {type: t.Counter}
          sink: t.CollectingSink
        connections: [src.out -> sink.x]
    """)
    dot = to_dot(session.build(session.load(p)))
    assert dot.startswith('digraph "d" {') and dot.rstrip().endswith("}")
    assert re.search(r'"src"(:\w+)*\s*->\s*"sink"(:\w+)*', dot) and "t.Counter" in dot


def test_floats_in_exponent_notation_are_numbers(tmp_path, session):
    p = write(tmp_path, "f.yaml", """
        components:
          src: {type: t.Counter, params: {n: 2, period_ns: 1000}}
          scale: {type: t.Scale, params: {gain: 1e-3}}
          sink: t.CollectingSink
        connections: [src.out -> scale.x, scale.y -> sink.x]
    """)
    assert session.load(p).components["scale"].params["gain"] == 0.001
    assert session.load(p, overrides=["scale.gain=2.5E+2"]).components["scale"].params["gain"] == 250.0
