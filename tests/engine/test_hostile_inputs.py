"""Graph loading, parameters, timers and output paths under careless or hostile input (issue 24, item 12).

Each test writes the graph a user could write and checks the one located problem it must
give (file:line:col computed here from the text written), or the firings a timer must make
(counted here from its period and the samples' times).
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from impala_flow import Component, Input, Output, Param, Periodic, Source
from impala_flow._network import Network
from impala_flow._offline import IDLE_TIMER_FIRINGS, MAX_TIMER_FIRINGS, OfflineExecutor
from impala_flow._session import Session
from impala_flow._spec import GraphError
from impala_flow._summary import ComponentError
from impala_flow.testing import CollectingSink, ScriptedSource, plugin_of

from .components import Counter, Scale

ROOT = Path(__file__).resolve().parents[2]
SECRET = "$6$abcdefgh$SECRETHASHSECRETHASH"


class Ticking(Component):
    """Counts its timer's firings; ``x`` is optional."""

    x = Input(float, required=False)
    out = Output(float)
    period_s = Param(float, default=0.5, gt=0, doc="timer period")
    tick = Periodic("period_s")

    def start(self) -> None:
        self.fired: list[int] = []

    def process(self, t: int) -> None:
        if self.trigger == "tick":
            self.fired.append(t)
        else:
            self.x.take()


class Sink(Component):
    """Writes what it received to ``path`` when it stops."""

    x = Input(float)
    path = Param(str, path="write", doc="file written")
    report = Param(str, default="", path="write_dir", doc="folder written")

    def process(self, t: int) -> None:
        self.x.take()

    def stop(self) -> None:
        Path(self.path).write_text("done\n")


@pytest.fixture
def session() -> Session:
    return Session(extra_plugins={"t": plugin_of(Counter, Scale, CollectingSink, Ticking, Sink)})


def write(folder: Path, name: str, text: str) -> Path:
    p = folder / name
    p.write_text(textwrap.dedent(text), encoding="utf-8")
    return p


def loc_of(path: Path, needle: str) -> str:
    """``file:line:col`` of the first ``needle`` in ``path``."""
    for n, line in enumerate(path.read_text().splitlines(), 1):
        if needle in line:
            return f"{path}:{n}:{line.index(needle) + 1}"
    raise AssertionError(f"{needle!r} not in {path}")


def problems_of(session: Session, path: Path, **kw) -> list[str]:
    with pytest.raises(GraphError) as ei:
        session.load(path, **kw)
    return [str(p) for p in ei.value.problems]


CHAIN = """\
    components:
      src: {type: t.Counter, params: {n: 3, period_ns: 1000}}
      gain: {type: t.Scale, params: {gain: 2.0}}
    connections:
      - src.out -> gain.x
"""


# --- foreign files are never echoed ------------------------------------------------------------

def test_an_included_shadow_file_is_one_line_without_its_contents(tmp_path, session):
    shadow = tmp_path / "shadow"
    shadow.write_text("".join(f"user{i}:{SECRET}{i}:19000:0:99999:7:::\n" for i in range(30)))
    g = write(tmp_path, "g.yaml", "include: shadow\n" + textwrap.dedent(CHAIN))
    probs = problems_of(session, g)
    assert probs == [f"{shadow}:1:1: not a graph file: none of its 30 keys is a graph key (name, description, "
                     "include, variables, clock, components, connections, record)"]


def test_unknown_keys_are_one_problem_per_mapping_shown_short_and_escaped(tmp_path, session):
    junk = "".join(f"  k{i}_{'x' * 200}: 1\n" for i in range(50))
    g = write(tmp_path, "g.yaml", textwrap.dedent(CHAIN) + "clock:\n  mode: replay\n  \"\\e[2Jbad\": 1\n" + junk)
    probs = problems_of(session, g)
    assert len(probs) == 1, probs
    assert probs[0] == (f"{g}:8:3: unknown key '\\x1b[2Jbad' in clock (and 50 more unknown keys); "
                        "expected one of mode, speed")
    long_key = problems_of(session, write(tmp_path, "h.yaml", textwrap.dedent(CHAIN) + f"{'y' * 500}: 1\n"))
    assert long_key == [f"{tmp_path / 'h.yaml'}:6:1: unknown key '{'y' * 40}...(500 chars)' in graph; expected one of "
                        "name, description, include, variables, clock, components, connections, record"]


def test_a_misspelt_graph_key_is_still_reported_as_such(tmp_path, session):
    g = write(tmp_path, "g.yaml", textwrap.dedent(CHAIN).replace("components:", "compnents:"))
    assert f"{g}:1:1: unknown key 'compnents' in graph (did you mean 'components'?)" in problems_of(session, g)


# --- graph files that are not regular files ---------------------------------------------------

def _load_in_subprocess(path: Path) -> subprocess.CompletedProcess[str]:
    code = ("import sys\nfrom impala_flow._load import read_graph\nfrom impala_flow._spec import GraphError\n"
            "try:\n    read_graph(sys.argv[1])\nexcept GraphError as e:\n    print(e)\n")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-c", code, str(path)], capture_output=True, text=True, timeout=60,
                          env=env, check=False)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes")
def test_a_named_pipe_as_graph_or_include_is_refused_without_waiting(tmp_path):
    fifo = tmp_path / "pipe.yaml"
    os.mkfifo(fifo)
    try:
        r = _load_in_subprocess(fifo)  # opening it for reading would wait for a writer forever
    except subprocess.TimeoutExpired:
        pytest.fail("loading a named pipe as a graph waits for a writer")
    assert r.stdout == f"{fifo}: is a named pipe, not a graph file\n", r.stderr
    g = write(tmp_path, "g.yaml", "include: pipe.yaml\n" + textwrap.dedent(CHAIN))
    try:
        r = _load_in_subprocess(g)
    except subprocess.TimeoutExpired:
        pytest.fail("an included named pipe waits for a writer")
    assert r.stdout == f"{fifo}: is a named pipe, not a graph file\n", r.stderr


def test_a_device_or_a_folder_as_graph_is_one_line(tmp_path, session):
    if os.path.exists("/dev/zero"):
        assert problems_of(session, Path("/dev/zero")) == ["/dev/zero: is a device, not a graph file"]
    assert problems_of(session, tmp_path) == [f"{tmp_path}: is a folder, not a graph file"]


# --- parameters: finite, times within int64, --set located ------------------------------------

@pytest.mark.parametrize("value", [".inf", "-.inf", ".nan"])
def test_a_non_finite_float_parameter_is_refused_at_its_line(tmp_path, session, value):
    g = write(tmp_path, "g.yaml", textwrap.dedent(CHAIN).replace("gain: 2.0", f"gain: {value}"))
    probs = problems_of(session, g)
    # Scale.gain is declared ge=0: -inf breaks that bound first; +inf passes it and is not finite
    why = {".nan": "NaN is not allowed", "-.inf": "-inf must be >= 0.0",
           ".inf": "inf is not allowed: a finite number is expected"}[value]
    assert probs == [f"{loc_of(g, f'gain: {value}')}: component 'gain' (t.Scale): parameter 'gain': {why}"]


def test_a_set_value_is_located_at_the_set_option(tmp_path, session):
    g = write(tmp_path, "g.yaml", textwrap.dedent(CHAIN))
    assert problems_of(session, g, overrides=["gain.gain=.inf"]) == [
        "--set gain.gain=.inf: component 'gain' (t.Scale): parameter 'gain': inf is not allowed: a finite number "
        "is expected"]
    assert problems_of(session, g, overrides=["gain.gain=abc"]) == [
        "--set gain.gain=abc: component 'gain' (t.Scale): parameter 'gain': expected float, got str 'abc'"]


def test_times_in_seconds_beyond_int64_nanoseconds_are_refused(tmp_path, session):
    g = write(tmp_path, "g.yaml", """
        components:
          src: {type: t.Counter, params: {n: 3, period_ns: 1000}}
          tick: {type: t.Ticking}
        connections:
          - src.out -> tick.x
    """)
    assert problems_of(session, g, overrides=["tick.period_s=1e308"]) == [
        "--set tick.period_s=1e308: component 'tick' (t.Ticking): parameter 'period_s': 1e+308 s is out of range: "
        "a time in seconds must be within +-9.2e+09 s (int64 nanoseconds)"]
    assert problems_of(session, g, overrides=["tick.period_s=1e-9"]) == [
        "--set tick.period_s=1e-9: component 'tick' (t.Ticking): parameter 'period_s': timer 'tick': period 1e-09 s "
        "must be within [1e-06, 9.2e+09] s"]
    assert problems_of(session, g, overrides=["src.period_ns=1e30"]) == [
        "--set src.period_ns=1e30: component 'src' (t.Counter): parameter 'period_ns': expected int, got float 1e+30"]
    assert problems_of(session, g, overrides=[f"src.t0_ns={1 << 63}"]) == [
        f"--set src.t0_ns={1 << 63}: component 'src' (t.Counter): parameter 't0_ns': {1 << 63} ns is outside the "
        "int64 range of times"]


# --- periodic timers: bounded over the mission's span, idle gaps skipped ----------------------

def _ticking(samples: list[tuple[int, str, float]], period_s: float) -> tuple[Network, Ticking]:
    net = Network("timers")
    src = net.add(ScriptedSource("src", samples))
    tick = net.add(Ticking("tick", period_s=period_s))
    net.connect(src.outputs["out"], tick.inputs["x"])
    return net, tick


def test_an_idle_timer_skips_an_empty_gap_and_counts_what_it_skipped():
    p_ns, gap_ns = 10_000_000, 10_000 * 10**9  # 10 ms timer, samples 10 000 s apart: 10^6 firings unbounded
    net, tick = _ticking([(0, "out", 1.0), (gap_ns, "out", 2.0)], p_ns / 1e9)
    summary = OfflineExecutor(net).run()
    # fires at 0 (a sample arrived), then IDLE_TIMER_FIRINGS idle firings, then at the next sample's time
    expected = [0] + [k * p_ns for k in range(1, IDLE_TIMER_FIRINGS + 1)] + [gap_ns]
    assert tick.fired == expected
    assert summary.extra["tick"]["timer_firings_skipped"] == gap_ns // p_ns - IDLE_TIMER_FIRINGS - 1
    assert summary.processed["tick"] == len(expected) + 2  # and the two samples


def test_a_timer_that_fires_on_busy_inputs_is_not_skipped():
    p_ns = 10_000_000
    samples = [(k * 25_000_000, "out", float(k)) for k in range(200)]  # a sample every 25 ms
    net, tick = _ticking(samples, p_ns / 1e9)
    summary = OfflineExecutor(net).run()
    assert tick.fired == list(range(0, samples[-1][0] + 1, p_ns))
    assert "tick" not in summary.extra


def test_a_timer_that_would_fire_too_often_over_the_mission_is_refused_before_start():
    span_ns = 10**6 * 10**9  # 11.6 days of mission, a 10 ms timer: 10^8 firings
    net, tick = _ticking([(0, "out", 1.0), (span_ns, "out", 2.0)], 0.01)
    with pytest.raises(ComponentError) as ei:
        OfflineExecutor(net).run()
    firings = span_ns // 10_000_000 + 1
    assert firings > MAX_TIMER_FIRINGS
    assert str(ei.value) == (
        "component 'tick', in start(): ValueError: parameter 'period_s' = 0.01 s: timer 'tick' would fire 1e+08 "
        "times over the mission's 1e+06 s, more than 1e+07: raise the period, or check the mission's times")
    assert not hasattr(tick, "fired")  # nothing started


# --- output paths checked before any work -----------------------------------------------------

def _sink_graph(tmp_path: Path, path: str, report: str = "") -> Path:
    return write(tmp_path, "g.yaml", f"""
        components:
          src: {{type: t.Counter, params: {{n: 3, period_ns: 1000}}}}
          sink: {{type: t.Sink, params: {{path: "{path}", report: "{report}"}}}}
        connections:
          - src.out -> sink.x
    """)


def test_an_output_name_too_long_is_refused_at_validation(tmp_path, session):
    name = "r" * 300 + ".txt"
    g = _sink_graph(tmp_path, f"out/{name}")
    probs = problems_of(session, g)
    where = loc_of(g, 'path: "out/')
    assert probs == [f"{where}: component 'sink' (t.Sink) parameter 'path': cannot write '{tmp_path}/out/{name}': "
                     f"the name '{'r' * 24}...' is 304 bytes long, more than the 255 the file system takes"]
    deep = "/".join(["d" * 200] * 25)
    probs = problems_of(session, _sink_graph(tmp_path, f"{deep}/x.txt"))
    assert len(probs) == 1 and "bytes long, more than the 4095 the file system takes" in probs[0]


class TextSource(Source):
    """One sample per number in the text file ``path``."""

    out = Output(float)
    path = Param(str, path="read", doc="text file")

    def generate(self):
        for i, word in enumerate(Path(self.path).read_text().split()):
            yield i, "out", float(word)


def test_a_report_folder_that_holds_an_input_is_refused_and_one_beside_it_is_not(tmp_path):
    session = Session(extra_plugins={"t": plugin_of(TextSource, Sink)})
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "in.txt").write_text("1 2 3\n")
    text = """
        components:
          src: {type: t.TextSource, params: {path: data/in.txt}}
          sink: {type: t.Sink, params: {path: data/out.txt, report: REPORT}}
        connections:
          - src.out -> sink.x
    """
    for report in (".", "data"):
        g = write(tmp_path, "g.yaml", text.replace("REPORT", report))
        folder = os.path.normpath(tmp_path / report)
        assert problems_of(session, g) == [
            f"{loc_of(g, 'report:')}: component 'sink' (t.Sink) parameter 'report': '{folder}' contains the input of "
            f"component 'src' (t.TextSource) parameter 'path' (at {loc_of(g, 'path: data/in')}) "
            f"'{tmp_path / 'data' / 'in.txt'}': write elsewhere"]
    g = write(tmp_path, "g.yaml", text.replace("REPORT", "data/report"))  # beside the input, in its folder: fine
    session.run(session.load(g))
    assert (tmp_path / "data" / "out.txt").read_text() == "done\n"


def test_record_parameters_are_checked_at_validation_not_at_build(tmp_path, session):
    g = write(tmp_path, "g.yaml", textwrap.dedent(CHAIN) + "record: {path: r.mcap, chunk_size: 1099511627776, "
              "flush_period_s: .inf}\n")
    where = loc_of(g, "path: r.mcap")
    where = where.rsplit(":", 1)[0] + ":9"  # the record mapping itself
    assert problems_of(session, g) == [
        f"{where}: record: 'chunk_size': 1099511627776 must be <= 268435456",
        f"{where}: record: 'flush_period_s': inf is not allowed: a finite number is expected"]
    assert not (tmp_path / "r.mcap").exists()


def test_a_file_full_of_errors_lists_twenty_then_counts_the_rest(tmp_path, session):
    comps = "".join(f"  c{i}: {{type: t.Nothing{i}}}\n" for i in range(100))
    g = write(tmp_path, "g.yaml", "components:\n" + comps)
    probs = problems_of(session, g)
    assert len(probs) == 21
    assert [p.split(": ", 2)[:2] for p in probs[:20]] == [[loc_of(g, f"type: t.Nothing{i}}}"),
                                                          f"component 'c{i}'"] for i in range(20)]
    assert probs[-1] == f"{g}: and 80 more problems"


def test_a_long_wrong_value_is_quoted_short(tmp_path, session):
    values = list(range(5000))
    g = write(tmp_path, "g.yaml", textwrap.dedent(CHAIN).replace("gain: 2.0", f"gain: {values}")
              .replace("components:", f"clock: {{mode: {'m' * 3000}}}\ncomponents:"))
    probs = problems_of(session, g)
    text = repr(values)
    assert probs == [
        f"{loc_of(g, 'm' * 3000)}: clock mode must be 'replay' or 'realtime', got '{'m' * 59}...(3002 chars)",
        f"{loc_of(g, 'gain: [')}: component 'gain' (t.Scale): parameter 'gain': expected float, got list "
        f"{text[:60]}...({len(text)} chars)"]
