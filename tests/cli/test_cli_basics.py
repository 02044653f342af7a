"""--help of every subcommand, --version: in a subprocess and in this process."""

from __future__ import annotations

import pytest

from impala_flow import __version__

from .conftest import Installed

MINE = ("run", "validate", "plugins", "graph", "schema")
NO_EXAMPLE_YET: set[str] = set()


@pytest.mark.parametrize("command", MINE)
def test_help_in_process(installed: Installed, command: str, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = installed.main(command, "--help", capsys=capsys)
    assert code == 0
    assert out.startswith(f"usage: impala-flow {command}")
    if command not in NO_EXAMPLE_YET:
        assert "example" in out  # every subcommand teaches by example


def test_help_lists_every_subcommand_in_a_subprocess(installed: Installed) -> None:
    r = installed.run("--help")
    assert r.returncode == 0, r.stderr
    for command in MINE:
        assert f"\n    {command} " in r.stdout
    assert "exit codes" in r.stdout


@pytest.mark.parametrize("command", ["plugins", "graph", "schema"])
def test_help_in_a_subprocess(installed: Installed, command: str) -> None:
    r = installed.run(command, "--help")
    assert r.returncode == 0, r.stderr
    assert r.stdout.startswith(f"usage: impala-flow {command}")
    assert "examples:" in r.stdout


def test_version(installed: Installed, capsys: pytest.CaptureFixture[str]) -> None:
    r = installed.run("--version")
    assert (r.returncode, r.stdout.strip()) == (0, f"impala-flow {__version__}")
    code, out, _ = installed.main("--version", capsys=capsys)
    assert (code, out.strip()) == (0, f"impala-flow {__version__}")


def test_no_subcommand_prints_help_and_exits_2(installed: Installed, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = installed.main(capsys=capsys)
    assert code == 2 and "usage: impala-flow" in out


def test_unknown_subcommand_is_a_usage_error(installed: Installed) -> None:
    r = installed.run("frobnicate")
    assert r.returncode == 2
    assert "invalid choice: 'frobnicate'" in r.stderr
