"""run and validate: a graph of the test plugin, validation errors, a component that raises."""

from __future__ import annotations

import json
import re
from collections.abc import Callable
from pathlib import Path

import pytest

from .conftest import Installed

Write = Callable[[str, str], Path]

CHAIN = """\
name: small
components:
  src: {type: clitest.Ticker, params: {count: 4, period: 0.5}}
  gain: {type: clitest.Gain, params: {gain: 3.0}}
  out: {type: clitest.Printer, params: {label: value}}
connections:
  - src.tick -> gain.x
  - gain.y -> out.x
"""

BROKEN = """\
name: broken
components:
  src: {type: clitest.Ticker, params: {count: 0}}
  gain: {type: clitest.Gian}
  out: {type: clitest.Printer, params: {label: value}}
conection:
  - src.tick -> gain.x
connections:
  - src.tick -> out.y
"""

BOOM = """\
name: boom
components:
  src: {type: clitest.Ticker, params: {count: 5, period: 0.25}}
  boom: {type: clitest.Boom, params: {at: 2}}
connections:
  - src.tick -> boom.x
"""

LOCATED = re.compile(r"^\s+\S+\.yaml:\d+:\d+: \S")


def test_run_in_a_subprocess(installed: Installed, write: Write, tmp_path: Path) -> None:
    g = write("small.yaml", CHAIN)
    r = installed.run("run", str(g), "--summary-json", str(tmp_path / "s.json"))
    assert r.returncode == 0, r.stderr
    assert r.stdout.splitlines() == [f"value t={i * 500_000_000} {3.0 * i}" for i in range(4)]
    assert "graph 'small'" in r.stderr and "no sample dropped" in r.stderr
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["processed"]["gain"] == summary["processed"]["out"] == 4
    assert all(st["dropped"] == 0 for st in summary["inputs"].values())


def test_run_in_process_with_set(installed: Installed, write: Write, capsys: pytest.CaptureFixture[str]) -> None:
    g = write("small.yaml", CHAIN)
    code, out, err = installed.main("run", str(g), "--set", "gain.gain=0.5", "--set", "src.count=2", capsys=capsys)
    assert code == 0, err
    assert out.splitlines() == ["value t=0 0.0", "value t=500000000 0.5"]


def test_validate_ok(installed: Installed, write: Write, capsys: pytest.CaptureFixture[str]) -> None:
    g = write("small.yaml", CHAIN)
    code, out, _ = installed.main("validate", str(g), capsys=capsys)
    assert code == 0
    assert "ok" in out and "3 components, 2 connections" in out


def _check_problems(err: str, path: Path) -> list[str]:
    lines = err.strip().splitlines()
    assert lines[0].startswith("impala-flow validate: error: ") and "problems in graph" in lines[0]
    problems = lines[1:]
    for line in problems:
        assert LOCATED.match(line), line
        assert line.strip().startswith(str(path)), line
    assert "Traceback" not in err
    return problems


def test_validate_reports_every_problem_with_file_line_col(installed: Installed, write: Write) -> None:
    g = write("broken.yaml", BROKEN)
    r = installed.run("validate", str(g))
    assert r.returncode == 2
    problems = _check_problems(r.stderr, g)
    text = "\n".join(problems)
    assert f"{g}:3:" in text and "parameter 'count'" in text          # out of range
    assert f"{g}:4:" in text and "unknown type 'clitest.Gian'" in text and "clitest.Gain" in text
    assert f"{g}:6:1: unknown key 'conection'" in text and "did you mean 'connections'" in text
    assert f"{g}:9:" in text and "has no input 'y'" in text
    assert len(problems) >= 4


def test_validate_errors_in_process(installed: Installed, write: Write, capsys: pytest.CaptureFixture[str]) -> None:
    g = write("broken.yaml", BROKEN)
    code, out, err = installed.main("validate", str(g), capsys=capsys)
    assert code == 2 and out == ""
    assert len(_check_problems(err, g)) >= 4


def test_run_of_an_invalid_graph_exits_2(installed: Installed, write: Write) -> None:
    r = installed.run("run", str(write("broken.yaml", BROKEN)))
    assert r.returncode == 2 and "unknown key 'conection'" in r.stderr


def test_missing_graph_file(installed: Installed, tmp_path: Path) -> None:
    r = installed.run("validate", str(tmp_path / "nope.yaml"))
    assert r.returncode in (1, 2)
    assert "nope.yaml" in r.stderr and "Traceback" not in r.stderr


def test_component_error_is_one_line_without_traceback(installed: Installed, write: Write) -> None:
    r = installed.run("run", str(write("boom.yaml", BOOM)))
    assert r.returncode == 1
    assert "Traceback" not in r.stderr
    errors = [line for line in r.stderr.splitlines() if "error:" in line]
    assert len(errors) == 1
    line = errors[0]
    assert line.startswith("impala-flow run: error: component 'boom', input 'x', sample t=500000000 ns")
    assert line.endswith("ValueError: boom on purpose")


def test_component_error_in_process(installed: Installed, write: Write, capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = installed.main("run", str(write("boom.yaml", BOOM)), capsys=capsys)
    assert code == 1
    assert "component 'boom', input 'x', sample t=500000000 ns: ValueError: boom on purpose" in err
    assert "Traceback" not in err


def test_debug_shows_the_traceback(installed: Installed, write: Write) -> None:
    r = installed.run("--debug", "run", str(write("boom.yaml", BOOM)))
    assert r.returncode == 1
    assert "Traceback (most recent call last)" in r.stderr
    assert "boom on purpose" in r.stderr


LIVE_RECORDED = """\
name: live-recorded
clock: {mode: realtime}
components:
  src: {type: clitest.Ticker, params: {count: 1000000, period: 0.02}}
  gain: {type: clitest.Gain, params: {gain: 3.0}}
connections:
  - src.tick -> gain.x
record: {path: live.mcap, streams: ["gain.y"]}
"""


def test_run_duration_offline_takes_that_much_mission_and_exits_0(installed: Installed, write: Write,
                                                                  tmp_path: Path) -> None:
    g = write("small.yaml", CHAIN)
    r = installed.run("run", str(g), "--duration", "1", "--summary-json", str(tmp_path / "s.json"))
    assert r.returncode == 0, r.stderr
    # samples every 0.5 s from t=0: the first second holds t=0 and t=0.5
    assert r.stdout.splitlines() == ["value t=0 0.0", "value t=500000000 3.0"]
    head = r.stderr.splitlines()[0] if r.stderr.startswith("graph") else \
        next(line for line in r.stderr.splitlines() if line.startswith("graph 'small'"))
    assert head.endswith("- stopped at --duration 1 s")
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["stopped_at_duration"] is True and summary["interrupted"] is False
    assert summary["duration_s"] == 1.0 and summary["processed"]["out"] == 2
    assert summary["timing"]["gain"]["calls"] == 2 and summary["latency"] == {}


def test_run_duration_live_closes_the_recording(installed: Installed, write: Write, tmp_path: Path) -> None:
    from impala_flow.io import MissionReader

    g = write("live.yaml", LIVE_RECORDED)
    r = installed.run("run", str(g), "--duration", "0.5", "--no-progress", "--summary-json", str(tmp_path / "s.json"))
    assert r.returncode == 0, r.stderr
    assert "stopped at --duration 0.5 s" in r.stderr and "INTERRUPTED" not in r.stderr
    summary = json.loads((tmp_path / "s.json").read_text())
    n = summary["emitted"]["gain.y"]
    assert n > 0 and summary["processed"]["record"] == n
    assert summary["latency"]["gain.y"]["count"] == n
    assert any(line.startswith("  LATENCY gain.y: ") for line in r.stderr.splitlines())
    with MissionReader(tmp_path / "live.mcap") as rec:       # a complete file: closed, with its summary
        assert rec.info().complete
        values = [m.data for m in rec.messages()]
    assert values == [3.0 * i for i in range(n)]


@pytest.mark.parametrize("bad", ["0", "-1", "nan", "inf", "soon"])
def test_run_duration_must_be_a_positive_number(installed: Installed, write: Write, bad: str,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    code, _, err = installed.main("run", str(write("small.yaml", CHAIN)), f"--duration={bad}", capsys=capsys)
    assert code == 2 and f"argument --duration: expected a number of seconds > 0, got '{bad}'" in err


@pytest.mark.parametrize(("arg", "expected"), [(None, 1), ("3", 3), ("0", None)])
def test_run_blas_threads(installed: Installed, write: Write, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                          arg: str | None, expected: int | None) -> None:
    """--blas-threads N reaches the run (its summary says which limit held); 0: the library's own."""
    g = write("small.yaml", CHAIN)
    extra = [] if arg is None else ["--blas-threads", arg]
    code, out, err = installed.main("run", str(g), "--no-progress", "--summary-json", str(tmp_path / "s.json"),
                                    *extra, capsys=capsys)
    assert code == 0, err
    assert json.loads((tmp_path / "s.json").read_text())["blas_threads"] == expected


@pytest.mark.parametrize("bad", ["-1", "two", "1.5"])
def test_run_blas_threads_refuses_a_bad_count(installed: Installed, write: Write,
                                              capsys: pytest.CaptureFixture[str], bad: str) -> None:
    g = write("small.yaml", CHAIN)
    code, out, err = installed.main("run", str(g), "--blas-threads", bad, capsys=capsys)
    assert code == 2 and "--blas-threads" in err
    assert f"expected an integer >= 0 (0: the library's own), got {bad!r}" in err
