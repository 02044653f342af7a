"""Node.js readers for the tests that check a file with another implementation (Foxglove's
TypeScript libraries): the npm packages are installed once per machine in a cache
(``$IMPALA_FLOW_NPM_CACHE``, default ``~/.cache/impala-flow-npm``), and a test skips where node,
npm or the registry is not available."""

from __future__ import annotations

import os
import shutil
import subprocess
from pathlib import Path

import pytest


def node_script(script: Path, packages: list[str], marker: str) -> list[str]:
    """The command running ``script`` (copied next to the cached ``node_modules``), with ``packages``
    installed unless ``node_modules/<marker>`` is there already."""
    node, npm = shutil.which("node"), shutil.which("npm")
    if node is None or npm is None:
        pytest.skip("node and npm are not installed")
    cache = Path(os.environ.get("IMPALA_FLOW_NPM_CACHE", Path.home() / ".cache" / "impala-flow-npm"))
    if not (cache / "node_modules" / marker).is_dir():
        cache.mkdir(parents=True, exist_ok=True)
        r = subprocess.run([npm, "install", "--no-audit", "--no-fund", "--prefix", str(cache), *packages],
                           capture_output=True, text=True, timeout=300)
        if r.returncode != 0:
            pytest.skip(f"npm could not install {packages}: {r.stderr.strip().splitlines()[-1:]}")
    shutil.copy(script, cache / script.name)  # next to its node_modules
    return [node, str(cache / script.name)]
