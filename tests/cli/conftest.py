"""Fixtures of the command-line tests.

``installed`` puts a ``.dist-info`` folder on the path whose entry points (group
``impala_flow``) name modules of this folder: Session() then finds those plugins through
the ordinary entry-point path, in this process and in a subprocess (through PYTHONPATH).
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from impala_flow import cli

ROOT = Path(__file__).resolve().parents[2]


class Installed:
    """Plugins installed for one test; ``run`` and ``main`` call the command line."""

    def __init__(self, site: Path, monkeypatch: pytest.MonkeyPatch) -> None:
        self.site = site
        self.monkeypatch = monkeypatch
        self.env = dict(os.environ)
        self.env["PYTHONPATH"] = os.pathsep.join([str(site), str(ROOT), self.env.get("PYTHONPATH", "")]).rstrip(
            os.pathsep)
        self.env.pop("IMPALA_FLOW_DISABLE_PLUGINS", None)
        monkeypatch.delenv("IMPALA_FLOW_DISABLE_PLUGINS", raising=False)
        monkeypatch.syspath_prepend(str(site))

    def add(self, dist: str, version: str, entry_points: dict[str, str], metadata: str = "") -> None:
        """Install a distribution ``dist`` whose ``impala_flow`` entry points are ``entry_points``;
        ``metadata``: more METADATA lines (``Provides-Extra: x``, ``Requires-Dist: y; extra == "x"``)."""
        info = self.site / f"{dist.replace('-', '_')}-{version}.dist-info"
        info.mkdir()
        (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: {version}\n{metadata}",
                                       encoding="utf-8")
        lines = "".join(f"{k} = {v}\n" for k, v in entry_points.items())
        (info / "entry_points.txt").write_text(f"[impala_flow]\n{lines}", encoding="utf-8")
        self.monkeypatch.syspath_prepend(str(self.site))  # invalidates the import caches

    def run(self, *args: str, cwd: Path | None = None) -> subprocess.CompletedProcess[str]:
        """``python -m impala_flow ARGS`` in a subprocess."""
        return subprocess.run([sys.executable, "-m", "impala_flow", *args], capture_output=True, text=True,
                              env=self.env, cwd=cwd, timeout=120, check=False)

    def main(self, *args: str, capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
        """``impala_flow.cli.main(ARGS)`` in this process: (exit code, stdout, stderr)."""
        try:
            code = cli.main(list(args))
        except SystemExit as e:  # --help, --version, argparse errors
            code = int(e.code or 0)
        out, err = capsys.readouterr()
        return code, out, err


@pytest.fixture
def installed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Installed:
    """The installed plugins plus ``clitest`` (tests/cli/clitest_plugin.py)."""
    site = tmp_path / "site"
    site.mkdir()
    inst = Installed(site, monkeypatch)
    inst.add("impala-flow-clitest", "0.3.1", {"clitest": "tests.cli.clitest_plugin"})
    return inst


@pytest.fixture
def write(tmp_path: Path) -> Callable[[str, str], Path]:
    """Write a text file into tmp_path; return its path."""

    def _write(name: str, text: str) -> Path:
        p = tmp_path / name
        p.write_text(text, encoding="utf-8")
        return p

    return _write
