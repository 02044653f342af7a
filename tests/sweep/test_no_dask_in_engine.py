"""The engine stays ignorant of Dask: importing impala-flow, the sweep plugin (all but its runner), building the
command line and running a graph never import dask or distributed; only a sweep does."""

from __future__ import annotations

import subprocess
import sys

from .conftest import ROOT, env_without_plugin_blocks

CODE = """
import sys
import impala_flow, impala_sweep.spec, impala_sweep.check, impala_sweep.folder, impala_sweep.task, impala_sweep.results
import impala_sweep.command, impala_sweep.plugin
from impala_flow.cli import make_parser
make_parser().parse_args(["sweep", "x.yaml", "-o", "out"])
from impala_flow._session import Session
Session()
loaded = sorted(m for m in sys.modules if m.split(".")[0] in ("dask", "distributed"))
print(loaded)
"""


def test_dask_is_imported_by_a_sweep_only() -> None:
    out = subprocess.run([sys.executable, "-c", CODE], capture_output=True, text=True, cwd=ROOT, timeout=120,
                         env=env_without_plugin_blocks(), check=True).stdout
    assert out.strip().splitlines()[-1] == "[]"
