"""``run``, ``graph`` and ``schema`` under careless or hostile input (issue 24, item 12): named
pipes where files are read or written, wrongly typed ``--set`` values, an included file that
is not a graph, outputs over the graph file, an absurd ``--dpi``. Each is one line and exit 2,
before anything runs."""

from __future__ import annotations

import os
import subprocess
from collections.abc import Callable
from pathlib import Path

import pytest

from .conftest import Installed

Write = Callable[[str, str], Path]

CHAIN = """\
name: small
components:
  src: {type: clitest.Ticker, params: {count: 4, period: 0.5}}
  out: {type: clitest.Printer, params: {label: value}}
connections:
  - src.tick -> out.x
"""

needs_fifo = pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes")


def _one_error(err: str, command: str = "run") -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(f"impala-flow {command}: error: "), err
    return lines[0].split(": error: ", 1)[1]


def _run(installed: Installed, *args: str) -> subprocess.CompletedProcess[str]:
    try:
        return installed.run(*args)
    except subprocess.TimeoutExpired:
        pytest.fail(f"impala-flow {' '.join(args)} did not return: it waits on a named pipe")


@needs_fifo
def test_run_a_named_pipe_is_one_line_not_a_wait(installed: Installed, tmp_path: Path) -> None:
    fifo = tmp_path / "graph.yaml"
    os.mkfifo(fifo)
    r = _run(installed, "run", str(fifo))
    assert r.returncode == 2 and r.stdout == ""
    assert _one_error(r.stderr) == f"{fifo}: is a named pipe, not a graph file"


@needs_fifo
def test_a_summary_json_that_is_a_named_pipe_is_refused_before_the_run(installed: Installed, write: Write,
                                                                       tmp_path: Path) -> None:
    g = write("small.yaml", CHAIN)
    fifo = tmp_path / "s.json"
    os.mkfifo(fifo)
    r = _run(installed, "run", str(g), "--no-progress", "--summary-json", str(fifo))
    assert r.returncode == 2 and r.stdout == ""  # nothing ran
    assert _one_error(r.stderr) == f"--summary-json {fifo}: it is a named pipe or a socket, not a file"


def test_an_included_text_file_is_one_line_that_does_not_echo_it(installed: Installed, write: Write,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    secret = write("shadow", "".join(f"u{i}:$6$salt$HASH{i}HASH:19000:0:99999:7:::\n" for i in range(100)))
    g = write("small.yaml", "include: shadow\n" + CHAIN)
    code, out, err = installed.main("run", str(g), capsys=capsys)
    assert code == 2 and out == ""
    assert "HASH" not in err
    assert _one_error(err) == (f"{secret}:1:1: not a graph file: none of its 100 keys is a graph key (name, "
                               "description, include, variables, clock, components, connections, record)")


@pytest.mark.parametrize(("item", "why"), [
    ("src.count=abc", "parameter 'count': expected int, got str 'abc'"),
    ("src.count=2.5", "parameter 'count': expected int, got float 2.5"),
    ("src.period=.inf", "parameter 'period': inf is not allowed: a finite number is expected"),
    ("src.period=[1, 2]", "parameter 'period': expected float, got list [1, 2]"),
])
def test_a_wrongly_typed_set_is_one_line_naming_the_option(installed: Installed, write: Write,
                                                           capsys: pytest.CaptureFixture[str], item: str,
                                                           why: str) -> None:
    g = write("small.yaml", CHAIN)
    code, out, err = installed.main("run", str(g), "--set", item, capsys=capsys)
    assert code == 2 and out == ""
    assert _one_error(err) == f"--set {item}: component 'src' (clitest.Ticker): {why}"


def test_graph_png_over_the_graph_file_and_absurd_dpi_are_refused(installed: Installed, write: Write,
                                                                  capsys: pytest.CaptureFixture[str]) -> None:
    g = write("small.yaml", CHAIN)
    text = g.read_text()
    code, _, err = installed.main("graph", str(g), "--png", str(g), capsys=capsys)
    assert code == 2
    assert _one_error(err, "graph") == f"--png: '{g}' is the graph file '{g}' itself: it would be overwritten"
    assert g.read_text() == text
    for dpi in ("0", "-5", "100000"):
        code, _, err = installed.main("graph", str(g), "--png", str(g.with_suffix(".png")), "--dpi", dpi,
                                      capsys=capsys)
        assert code == 2
        assert _one_error(err, "graph") == f"--dpi {dpi}: expected 10 to 1200"
    assert not g.with_suffix(".png").exists()


@needs_fifo
def test_schema_into_a_named_pipe_is_refused(installed: Installed, tmp_path: Path) -> None:
    fifo = tmp_path / "schema.json"
    os.mkfifo(fifo)
    r = _run(installed, "schema", "-o", str(fifo))
    assert r.returncode == 2
    assert _one_error(r.stderr, "schema") == f"-o {fifo}: it is a named pipe or a socket, not a file"
