"""Graph loading and validation hardened (issue 11, items 1, 2, 3, 9, 10, 11, 12, 13, 14).

Each test builds the bad graph a user could write and checks the one located problem it
must give (file:line:col computed here from the text written), or the value the graph must
hold (computed here, not read back from the code).
"""

from __future__ import annotations

import ast
import os
import textwrap
import tracemalloc
from pathlib import Path

import pytest
from mcap.reader import make_reader

from impala_flow import Component, Input, Output, Param, Source
from impala_flow._session import Session
from impala_flow._spec import GraphError
from impala_flow.testing import CollectingSink, plugin_of

from .components import Counter, Scale

ENGINE = Path(__file__).resolve().parents[2] / "impala_flow"


class FileSource(Source):
    """Emits one sample per line of the text file ``path``."""

    out = Output(float)
    path = Param(str, path="read", doc="text file, one number a line")

    def generate(self):
        for i, line in enumerate(Path(self.path).read_text().split()):
            yield i * 1000, "out", float(line)


class FileSink(Component):
    """Writes the values it received, one a line, to ``path`` when it stops."""

    x = Input(float)
    path = Param(str, path="write", doc="text file written")

    def start(self):
        self.values = []

    def process(self, t):
        self.values.append(self.x.take())

    def stop(self):
        Path(self.path).parent.mkdir(parents=True, exist_ok=True)
        Path(self.path).write_text("".join(f"{v}\n" for v in self.values))


class Scenario(Source):
    out = Output(float)
    scenario = Param(str, default="beynes", path="read_or_name")


class LiveTicker(Source):
    live = True
    out = Output(float)


@pytest.fixture
def session():
    return Session(extra_plugins={"t": plugin_of(Counter, Scale, CollectingSink, FileSource, FileSink, Scenario,
                                                 LiveTicker)})


def write(folder: Path, name: str, text: str) -> Path:
    p = folder / name
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(textwrap.dedent(text), encoding="utf-8")
    return p


def problems_of(session: Session, path: Path, **kw) -> list[str]:
    with pytest.raises(GraphError) as ei:
        session.load(path, **kw)
    return [str(p) for p in ei.value.problems]


def loc_of(path: Path, needle: str, occurrence: int = 1) -> str:
    """``file:line:col`` of the ``occurrence``-th ``needle`` in ``path`` (1-based)."""
    k = 0
    for n, line in enumerate(path.read_text().splitlines(), 1):
        col = line.find(needle)
        while col >= 0:
            k += 1
            if k == occurrence:
                return f"{path}:{n}:{col + 1}"
            col = line.find(needle, col + 1)
    raise AssertionError(f"{needle!r} not in {path}")


# --- item 1: an output over an input ------------------------------------------------------

def _mission(folder: Path, session: Session, n: int = 40) -> Path:
    g = write(folder, "make.yaml", f"""
        components:
          src: {{type: t.Counter, params: {{n: {n}, period_ns: 1000}}}}
        record: {{path: mission.mcap, streams: ["src.*"]}}
    """)
    session.run(session.load(g))
    return folder / "mission.mcap"


def _count(path: Path) -> int:
    """Recorded messages (the /foxglove/ views of each apart)."""
    with open(path, "rb") as f:
        return sum(1 for _, ch, _ in make_reader(f).iter_messages() if not ch.topic.startswith("/foxglove/"))


def test_recording_over_the_replayed_file_is_refused_and_the_file_survives(tmp_path, session):
    mission = _mission(tmp_path, session)
    assert _count(mission) == 40  # the official reader
    before = mission.read_bytes()
    (tmp_path / "link.mcap").symlink_to(mission)
    for target in ("mission.mcap", "./sub/../mission.mcap", "link.mcap", str(mission)):
        g = write(tmp_path, "clobber.yaml", f"""
            components:
              mission: {{type: io.Replayer, params: {{path: mission.mcap}}}}
              scale: {{type: t.Scale}}
            connections: [mission.src/out -> scale.x]
            record: {{path: "{target}", streams: ["scale.*"]}}
        """)
        (tmp_path / "sub").mkdir(exist_ok=True)
        lines = problems_of(session, g)
        assert len(lines) == 1, lines
        record_at = loc_of(g, '{path: "')
        assert lines[0].startswith(f"{record_at}: record writes '")
        assert f"the file component 'mission' (io.Replayer) parameter 'path' reads (at {loc_of(g, 'path: mission')})" \
            in lines[0] and "would be overwritten" in lines[0]
    assert mission.read_bytes() == before and _count(mission) == 40


def test_two_recorders_on_one_path_are_refused(tmp_path, session):
    g = write(tmp_path, "two.yaml", """
        components:
          src: {type: t.Counter}
          rec: {type: io.Recorder, params: {path: out/run.mcap, topics: {a: src.out}}}
        connections: [src.out -> rec.a]
        record: {path: out/../out/run.mcap, streams: ["src.*"]}
    """)
    lines = problems_of(session, g)
    assert len(lines) == 1, lines
    assert lines[0].startswith(f"{loc_of(g, '{path: out/..')}: record writes '{tmp_path / 'out/run.mcap'}'")
    assert f"as component 'rec' (io.Recorder) parameter 'path' does (at {loc_of(g, 'path: out/run')})" in lines[0]


# --- item 2: alias bombs and deep nesting ---------------------------------------------------

def test_an_alias_bomb_is_refused_at_its_first_oversized_level_in_bounded_memory(tmp_path, session):
    levels = ["  a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    names = "abcdefghi"
    for prev, name in zip(names, names[1:], strict=False):
        levels.append(f"  {name}: &{name} [" + ", ".join([f"*{prev}"] * 9) + "]")
    g = tmp_path / "lol.yaml"
    g.write_text("variables:\n" + "\n".join(levels) + "\ncomponents: {src: t.Counter}\n")
    tracemalloc.start()
    try:
        lines = problems_of(session, g)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    # the k-th list (a: k=1) expands to 1 + 9 * (the (k-1)-th) = sum(9**i, i=0..k) values:
    # d (k=4) to 7 381, e (k=5) to 66 430: e, on line 6 (its anchor at column 6), is the first
    # past the bound of 50 000
    assert sum(9 ** i for i in range(5)) <= 50_000 < sum(9 ** i for i in range(6))
    assert lines == [f"{g}:6:6: invalid YAML: expands to more than 50000 values (aliases repeated inside aliases?)"]
    assert peak < 20e6  # nothing was expanded


# levels: the root mapping is 1, each value or key one more. "{a: [[[": the 63rd bracket (column
# 16 + 62) is level 65. Block keys: the mapping holding k_i (line i + 1, column 2 i + 2) is level
# i + 1, its key k_i level i + 2: k63 is level 65.
@pytest.mark.parametrize(("text", "where", "what"), [
    ("variables: {a: &a [1, *a]}\n", (1, 16), "recursive alias"),
    ("variables: {a: " + "[" * 3000 + "]" * 3000 + "}\n", (1, 78), "nested more than 64 levels deep"),
    ("variables:\n" + "".join("  " * i + f" k{i}:\n" for i in range(1, 80)), (64, 128), "nested more than 64"),
])
def test_recursive_aliases_and_deep_nesting_are_one_located_line(tmp_path, session, text, where, what):
    g = tmp_path / "deep.yaml"
    g.write_text(text)
    lines = problems_of(session, g)
    assert len(lines) == 1 and lines[0].startswith(f"{g}:{where[0]}:{where[1]}: invalid YAML: ") and what in lines[0]


def test_an_alias_is_shared_and_its_values_reach_every_use(tmp_path, session):
    g = write(tmp_path, "alias.yaml", """
        variables: {base: &p {n: 3, period_ns: 1000}}
        components:
          a: {type: t.Counter, params: *p}
          b: {type: t.Counter, params: *p}
    """)
    spec = session.load(g)
    assert spec.components["a"].params == spec.components["b"].params == {"n": 3, "period_ns": 1000}


# --- item 3: duplicate connections and redefined components --------------------------------

def test_a_connection_written_twice_is_an_error_naming_both_places(tmp_path, session):
    write(tmp_path, "base.yaml", """
        components:
          src: {type: t.Counter, params: {n: 3}}
          sink: t.CollectingSink
        connections: [src.out -> sink.x]
    """)
    g = write(tmp_path, "main.yaml", """
        include: base.yaml
        connections:
          - src.out -> sink.x
          - {from: src.out, to: sink.x}
    """)
    lines = problems_of(session, g)
    first = loc_of(tmp_path / "base.yaml", "src.out")
    assert lines == [
        f"{loc_of(g, 'src.out')}: duplicate connection 'src.out -> sink.x': already written at {first} "
        "(every sample would be delivered twice)",
        f"{loc_of(g, '{from')}: duplicate connection 'src.out -> sink.x': already written at {first} "
        "(every sample would be delivered twice)",
    ]


def test_redefining_an_included_component_needs_override(tmp_path, session):
    base = write(tmp_path, "base.yaml", """
        components:
          src: {type: t.Counter, params: {n: 3, period_ns: 1000}}
          scale: {type: t.Scale, params: {gain: 2.0}}
          sink: t.CollectingSink
        connections: [src.out -> scale.x, scale.y -> sink.x]
    """)
    g = write(tmp_path, "main.yaml", """
        include: base.yaml
        components:
          scale: {type: t.Scale, params: {gain: 5.0}}
    """)
    assert problems_of(session, g) == [
        f"{loc_of(g, 'scale')}: component 'scale' is already defined at {loc_of(base, 'scale:')}: write "
        "'override: true' to replace it, or leave out 'type' to refine its params"]
    g = write(tmp_path, "main.yaml", """
        include: base.yaml
        components:
          scale: {type: t.Scale, override: true, params: {gain: 5.0}}
    """)
    net = session.build(session.load(g))
    session.run(net)
    assert net.components["sink"].values() == [0.0, 5.0, 10.0]
    g = write(tmp_path, "lone.yaml", """
        components:
          scale: {type: t.Scale, override: true}
    """)
    assert problems_of(session, g)[0] == (f"{loc_of(g, 'true')}: component 'scale': override: true, but no "
                                          "included file defines a component 'scale'")


def test_a_file_included_twice_through_two_files_is_merged_once(tmp_path, session):
    write(tmp_path, "common.yaml", """
        components: {src: {type: t.Counter, params: {n: 2, period_ns: 1000}}, sink: t.CollectingSink}
        connections: [src.out -> sink.x]
    """)
    write(tmp_path, "a.yaml", "include: common.yaml\n")
    write(tmp_path, "b.yaml", "include: common.yaml\n")
    net = session.build(session.load(write(tmp_path, "main.yaml", "include: [a.yaml, b.yaml]\n")))
    session.run(net)
    assert net.components["sink"].values() == [0.0, 1.0]  # delivered once each


# --- item 9: variables ----------------------------------------------------------------------

def test_an_unknown_var_is_an_error_with_the_closest_names(tmp_path, session):
    g = write(tmp_path, "v.yaml", """
        variables: {mission: m.txt, out_dir: out}
        components:
          src: {type: t.FileSource, params: {path: "${mission}"}}
    """)
    assert problems_of(session, g, variables={"misson": "x.txt"}) == [
        "--var misson: the graph has no variable 'misson' (closest: mission)"]


def test_variables_inside_variables_are_substituted_and_cycles_reported(tmp_path, session):
    g = write(tmp_path, "v.yaml", """
        variables: {sec: 30, name: "run-${sec}s", out: "res/${name}.txt"}
        components:
          src: {type: t.Counter, params: {n: 2, period_ns: 1000}}
          sink: {type: t.FileSink, params: {path: "${out}"}}
        connections: [src.out -> sink.x]
    """)
    spec = session.load(g, variables={"sec": 45})
    assert spec.variables["out"] == "res/run-45s.txt"
    assert spec.components["sink"].params["path"] == str(tmp_path / "res" / "run-45s.txt")
    g = write(tmp_path, "cyc.yaml", """
        variables: {a: "x${b}", b: "${c}/y", c: "${a}"}
        components:
          src: {type: t.Counter}
    """)
    a_at = loc_of(g, '"x${b}')
    assert problems_of(session, g) == [f"{a_at}: variable cycle: a -> b -> c -> a"]


# --- item 10: what the run would reject ----------------------------------------------------

def test_a_live_source_in_an_offline_graph_and_an_empty_graph_are_refused(tmp_path, session):
    g = write(tmp_path, "live.yaml", """
        components:
          radar: {type: t.LiveTicker}
          sink: t.CollectingSink
        connections: [radar.out -> sink.x]
    """)
    assert problems_of(session, g) == [
        f"{loc_of(g, 'type')}: component 'radar' (t.LiveTicker) is a live source: an offline graph (clock mode "
        "'replay') cannot run it; set clock: {mode: realtime}"]
    g.write_text(g.read_text() + "clock: {mode: realtime}\n")
    session.load(g)  # fine live
    empty = write(tmp_path, "empty.yaml", "name: nothing\n")
    assert problems_of(session, empty) == [f"{empty}:1:1: the graph has no components: nothing to run"]


def test_an_output_in_a_folder_that_cannot_be_created_is_refused(tmp_path, session):
    (tmp_path / "blocker").write_text("a file, not a folder")
    g = write(tmp_path, "o.yaml", """
        components:
          src: {type: t.Counter}
          sink: {type: t.FileSink, params: {path: blocker/sub/values.txt}}
        connections: [src.out -> sink.x]
        record: {path: blocker/run.mcap}
    """)
    lines = problems_of(session, g)
    assert lines == [
        f"{loc_of(g, 'path: b')}: component 'sink' (t.FileSink) parameter 'path': cannot write "
        f"'{tmp_path / 'blocker/sub/values.txt'}': its folder cannot be created: '{tmp_path / 'blocker'}' is a file",
        f"{loc_of(g, '{path: b', 2)}: record: cannot write '{tmp_path / 'blocker/run.mcap'}': its folder cannot be "
        f"created: '{tmp_path / 'blocker'}' is a file",
    ]
    assert not (tmp_path / "blocker" / "sub").exists()


# --- item 11: relative paths ----------------------------------------------------------------

def test_relative_paths_resolve_against_the_graph_file_folder(tmp_path, session, monkeypatch):
    cwd = tmp_path / "elsewhere"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    graphs = tmp_path / "graphs"
    write(graphs, "data/in.txt", "1\n2\n3\n")
    write(graphs, "parts/sink.yaml", """
        components:
          sink: {type: t.FileSink, params: {path: out/part.txt}}
    """)
    g = write(graphs, "g.yaml", """
        include: parts/sink.yaml
        variables: {out: out}
        components:
          src: {type: t.FileSource, params: {path: data/in.txt}}
        connections: [src.out -> sink.x]
        record: {path: "${out}/run.mcap"}
    """)
    spec = session.load(Path(os.path.relpath(g)))  # given relative to the working directory
    session.run(spec)
    assert (graphs / "parts/out/part.txt").read_text() == "1.0\n2.0\n3.0\n"  # the included file's folder
    assert _count(graphs / "out/run.mcap") == 3
    assert not (cwd / "out").exists()
    # on the command line (--var, --set) a relative path is the working directory's
    spec = session.load(g, overrides=["sink.path=here.txt"], variables={"out": "res"})
    assert spec.components["sink"].params["path"] == "here.txt"
    assert spec.record["path"] == "res/run.mcap"
    session.run(spec)
    assert (cwd / "here.txt").read_text() == "1.0\n2.0\n3.0\n" and _count(cwd / "res/run.mcap") == 3
    # a name is not a path; a file is
    g2 = write(graphs, "s.yaml", """
        components:
          a: {type: t.Scenario, params: {scenario: beynes}}
          b: {type: t.Scenario, params: {scenario: scenes/x.yaml}}
          c: {type: t.Scenario, params: {scenario: x.yaml}}
    """)
    spec = session.load(g2)
    assert [spec.components[k].params["scenario"] for k in "abc"] == [
        "beynes", str(graphs / "scenes/x.yaml"), str(graphs / "x.yaml")]


# --- item 12: YAML 1.2 core schema ----------------------------------------------------------

def test_yaml_1_1_surprises_are_strings_or_located_errors(tmp_path, session):
    g = write(tmp_path, "y.yaml", """
        components:
          src: {type: t.Counter, params: {n: 3, period_ns: 0o10}}
          scale: {type: t.Scale, params: {gain: 1:30}}
          sink: t.CollectingSink
        connections: [src.out -> scale.x, scale.y -> sink.x]
    """)
    lines = problems_of(session, g)
    assert lines == [f"{loc_of(g, 'gain')}: component 'scale' (t.Scale): parameter 'gain': expected float, "
                     "got str '1:30'"]  # YAML 1.1 would have read 90
    g = write(tmp_path, "y.yaml", g.read_text().replace("1:30", "1.5"))
    assert session.load(g).components["src"].params["period_ns"] == 8
    g = write(tmp_path, "octal.yaml", """
        components:
          src: {type: t.Counter, params: {n: 010}}
    """)
    assert problems_of(session, g) == [
        f"{loc_of(g, '010')}: invalid YAML: '010': a leading zero is ambiguous (YAML 1.1 reads octal 8, "
        "YAML 1.2 10): write 10, 0o10 for octal, or quote it"]
    g = write(tmp_path, "words.yaml", """
        variables: {a: yes, b: off, c: 2024-01-02, d: 1_000, e: .inf, f: True}
        components: {src: t.Counter}
    """)
    assert session.load(g).variables == {"a": "yes", "b": "off", "c": "2024-01-02", "d": "1_000",
                                         "e": float("inf"), "f": True}


# --- item 13: ids, encodings ----------------------------------------------------------------

@pytest.mark.parametrize(("key", "why"), [
    ("'my src'", "it contains ' '"),
    ("'a->b'", "it contains '->'"),
    ("'s[1]'", "it contains '['"),
])
def test_component_ids_that_cannot_be_written_in_a_connection_are_refused(tmp_path, session, key, why):
    g = write(tmp_path, "ids.yaml", f"""
        components:
          {key}: t.Counter
    """)
    lines = problems_of(session, g)
    assert len(lines) == 2 and lines[0].startswith(f"{g}:3:3: component id ")
    assert "cannot be written in a connection" in lines[0] and why in lines[0]


def test_a_non_string_component_id_is_refused(tmp_path, session):
    g = write(tmp_path, "ids.yaml", "components:\n  1: t.Counter\n  src: t.Counter\n")
    assert problems_of(session, g) == [
        f"{g}:2:3: component id 1 must be a string (YAML read it as int: quote it)"]


def test_a_graph_that_is_not_utf8_is_located(tmp_path, session):
    g = tmp_path / "latin1.yaml"
    g.write_bytes("name: caf\u00e9\ncomponents: {src: t.Counter}\n".encode("latin-1"))
    assert problems_of(session, g) == [f"{g}:1:10: not UTF-8 text (byte 0xe9); save the file as UTF-8"]


# --- item 14: layering ----------------------------------------------------------------------

def test_graph_pipeline_stages_import_in_one_direction_at_module_level():
    """spec <- paths <- load, resolve <- validate <- build (the session runs them in that
    order and is the only module that imports them all), every engine import at the top of
    the module. (The whole engine's order: the import-linter layers contract, and
    tests/engine/test_layers.py.)"""
    allowed = {"spec": set(), "paths": {"spec"}, "load": {"spec"}, "resolve": {"spec", "paths"},
               "validate": {"spec", "paths"}, "build": {"spec", "validate"}}
    for name, ok in allowed.items():
        tree = ast.parse((ENGINE / f"_{name}.py").read_text())
        top = {id(n) for n in tree.body}
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level == 1:
                assert id(node) in top, f"{name}.py:{node.lineno}: import inside a function"
                mod = (node.module or "").split(".")[0].lstrip("_")
                if mod in allowed:
                    assert mod in ok, f"{name}.py imports {mod}"
