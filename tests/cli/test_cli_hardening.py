"""Command-line usage errors are one line and exit 2, before anything runs (issue 11 items
9, 12, 13): bad --speed, an unwritable --summary-json, a graph that is not UTF-8, an
unknown --var."""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pytest

from .conftest import Installed

Write = Callable[[str, str], Path]

CHAIN = """\
name: small
variables: {gain: 3.0}
components:
  src: {type: clitest.Ticker, params: {count: 4, period: 0.5}}
  gain: {type: clitest.Gain, params: {gain: "${gain}"}}
  out: {type: clitest.Printer, params: {label: value}}
connections:
  - src.tick -> gain.x
  - gain.y -> out.x
"""


def _one_error(err: str, command: str = "run") -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    assert lines[0].startswith(f"impala-flow {command}: error: ")
    return lines[0]


@pytest.mark.parametrize("speed", ["0", "-1", "nan", "1e-300", "inf", "fast"])
def test_a_bad_speed_exits_2_with_one_line(installed: Installed, write: Write, capsys: pytest.CaptureFixture[str],
                                           speed: str) -> None:
    g = write("small.yaml", CHAIN)
    code, out, err = installed.main("run", str(g), f"--speed={speed}", capsys=capsys)
    assert code == 2 and out == ""  # nothing ran
    assert _one_error(err) == ("impala-flow run: error: --speed: speed must be 'max' or a finite factor >= 0.001, "
                               f"got {speed!r}")


def test_slow_and_max_speeds_are_accepted(installed: Installed, write: Write,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    g = write("small.yaml", CHAIN.replace("count: 4", "count: 1"))
    for speed in ("max", "0.001", "2"):
        code, out, err = installed.main("run", str(g), "--speed", speed, "--no-progress", capsys=capsys)
        assert code == 0, err
        assert out == "value t=0 0.0\n"


def test_an_unwritable_summary_json_is_refused_before_the_run(installed: Installed, write: Write, tmp_path: Path,
                                                              capsys: pytest.CaptureFixture[str]) -> None:
    g = write("small.yaml", CHAIN)
    for target, why in ((tmp_path, "is a folder"), (tmp_path / "no" / "s.json", f"folder {tmp_path / 'no'} does "
                                                                                  "not exist")):
        code, out, err = installed.main("run", str(g), "--summary-json", str(target), capsys=capsys)
        assert code == 2 and out == ""  # the Printer printed nothing: the run never started
        assert _one_error(err) == f"impala-flow run: error: --summary-json {target}: {why}"


def test_a_graph_that_is_not_utf8_exits_2_naming_the_file(installed: Installed, tmp_path: Path) -> None:
    g = tmp_path / "latin1.yaml"
    g.write_bytes(CHAIN.replace("name: small", "name: d\xe9mo").encode("latin-1"))
    r = installed.run("validate", str(g))
    assert r.returncode == 2
    # "name: d" is 7 bytes: the bad byte is the 8th of line 1
    assert _one_error(r.stderr, "validate") == (f"impala-flow validate: error: {g}:1:8: not UTF-8 text (byte 0xe9); "
                                                "save the file as UTF-8")


def test_an_unknown_var_exits_2_with_the_closest_name(installed: Installed, write: Write,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    g = write("small.yaml", CHAIN)
    code, _, err = installed.main("validate", str(g), "--var", "gian=2", capsys=capsys)
    assert code == 2
    assert _one_error(err, "validate") == ("impala-flow validate: error: --var gian: the graph has no variable "
                                           "'gian' (closest: gain)")
    code, out, err = installed.main("run", str(g), "--var", "gain=0.5", "--set", "src.count=2", capsys=capsys)
    assert code == 0 and out.splitlines() == ["value t=0 0.0", "value t=500000000 0.5"]


def test_an_ambiguous_octal_on_the_command_line_exits_2(installed: Installed, write: Write,
                                                        capsys: pytest.CaptureFixture[str]) -> None:
    g = write("small.yaml", CHAIN)
    code, out, err = installed.main("run", str(g), "--set", "src.count=010", capsys=capsys)
    assert code == 2 and out == ""
    assert "--set src.count=010: '010': a leading zero is ambiguous (YAML 1.1 reads octal 8, YAML 1.2 10)" in err
    code, _, err = installed.main("run", str(g), "--var", "gain=010", capsys=capsys)
    assert code == 2 and _one_error(err).startswith("impala-flow run: error: --var gain=010: '010': a leading zero")


def test_a_failed_run_still_writes_its_summary_json(installed: Installed, write: Write, tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    """The JSON of a failed run names the error and counts what was processed before it:
    Boom raises on its 3rd sample (at=2), so it processed 2 and the ticker emitted 3."""
    g = write("boom.yaml", """\
name: boom
components:
  src: {type: clitest.Ticker, params: {count: 6, period: 0.5}}
  boom: {type: clitest.Boom, params: {at: 2}}
connections:
  - src.tick -> boom.x
""")
    out = tmp_path / "s.json"
    code, _, err = installed.main("run", str(g), "--no-progress", "--summary-json", str(out), capsys=capsys)
    assert code == 1 and "boom on purpose" in err
    s = json.loads(out.read_text())
    assert "boom on purpose" in s["error"] and "'boom'" in s["error"]
    assert s["processed"]["boom"] == 2 and s["emitted"]["src.tick"] == 3
    assert s["events"] == 3 + 3  # 3 source events and 3 deliveries, the last one failing
