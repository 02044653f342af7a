"""Shared fixtures of the engine's test suite.

``example_plugin`` pip-installs ``tests/plugin_example`` (a real third-party plugin
package) into the running environment, once per test session, the way a user would
install a published plugin. The package stays installed afterwards: it only depends on
impala-flow, so the environment stays consistent, and the next run reinstalls it.
"""

from __future__ import annotations

import base64
import contextlib
import fcntl
import hashlib
import importlib
import shutil
import subprocess
import sys
import tempfile
import tomllib
import zipfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent
EXAMPLE_SRC = TESTS / "plugin_example"

# the example package has its own tests, run against the installed package by
# tests/test_plugins.py; collecting them here would import it before it is installed
collect_ignore = ["plugin_example"]


@dataclass(frozen=True)
class ExamplePlugin:
    dist: str  # distribution name, "impala-flow-example-plugin"
    version: str
    entry_point: str  # plugin name, "example"
    module: str  # "impala_flow_example.plugin"
    source: Path  # the copy that was installed (its tests/ folder is runnable)
    how: str  # "pip --no-build-isolation" or "pip (wheel built offline by the test suite)"


def _pip(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "pip", "--disable-pip-version-check", "--no-input", *args],
        capture_output=True, text=True, timeout=300,
    )


def _record_line(name: str, data: bytes) -> str:
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{name},sha256={digest},{len(data)}"


def build_wheel_offline(src: Path, out_dir: Path) -> Path:
    """A PEP 427 wheel of a pure-Python setuptools project, made with the standard library only.

    The fallback when the environment cannot build the example with its own backend
    without the network (setuptools older than 70.1 needs the ``wheel`` package). It
    reads the same ``pyproject.toml`` fields setuptools does: name, version, description,
    requires-python, dependencies, entry points and ``[tool.setuptools] packages``.
    """
    meta = tomllib.loads((src / "pyproject.toml").read_text(encoding="utf-8"))
    project = meta["project"]
    name, version = project["name"], project["version"]
    stem = f"{name.replace('-', '_')}-{version}"
    info = f"{stem}.dist-info"
    files: dict[str, bytes] = {}
    for pkg in meta["tool"]["setuptools"]["packages"]:
        pkg_dir = src / pkg.replace(".", "/")
        for f in sorted(pkg_dir.rglob("*")):
            if f.is_file() and "__pycache__" not in f.parts and f.suffix != ".pyc":
                files[f.relative_to(src).as_posix()] = f.read_bytes()
    lines = ["Metadata-Version: 2.1", f"Name: {name}", f"Version: {version}"]
    if "description" in project:
        lines.append(f"Summary: {project['description']}")
    if "requires-python" in project:
        lines.append(f"Requires-Python: {project['requires-python']}")
    lines += [f"Requires-Dist: {d}" for d in project.get("dependencies", [])]
    files[f"{info}/METADATA"] = ("\n".join(lines) + "\n").encode()
    files[f"{info}/WHEEL"] = b"Wheel-Version: 1.0\nGenerator: impala-flow-tests\nRoot-Is-Purelib: true\n" \
        b"Tag: py3-none-any\n"
    eps = []
    for group, entries in project.get("entry-points", {}).items():
        eps.append(f"[{group}]")
        eps += [f"{k} = {v}" for k, v in entries.items()]
        eps.append("")
    files[f"{info}/entry_points.txt"] = "\n".join(eps).encode()
    record = [_record_line(n, d) for n, d in files.items()] + [f"{info}/RECORD,,"]
    files[f"{info}/RECORD"] = ("\n".join(record) + "\n").encode()
    wheel = out_dir / f"{stem}-py3-none-any.whl"
    with zipfile.ZipFile(wheel, "w", zipfile.ZIP_DEFLATED) as z:
        for n, d in files.items():
            z.writestr(n, d)
    return wheel


@contextlib.contextmanager
def _install_lock() -> Iterator[None]:
    """Serialise installs of the example when several test runs share one environment."""
    env_id = hashlib.sha1(sys.prefix.encode()).hexdigest()[:12]
    lock = Path(tempfile.gettempdir()) / f"impala-flow-example-install-{env_id}.lock"
    with lock.open("w") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


@pytest.fixture(scope="session")
def example_plugin(tmp_path_factory: pytest.TempPathFactory) -> ExamplePlugin:
    """Install tests/plugin_example into this environment (no network needed) and return its facts."""
    # build from a copy: setuptools writes build/ and *.egg-info next to the sources
    src = tmp_path_factory.mktemp("plugin_example") / "impala-flow-example-plugin"
    shutil.copytree(EXAMPLE_SRC, src, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__", ".*"))
    meta = tomllib.loads((src / "pyproject.toml").read_text(encoding="utf-8"))
    with _install_lock():
        how = "pip --no-build-isolation"
        r = _pip("install", "--no-deps", "--no-build-isolation", "--force-reinstall", str(src))
        if r.returncode != 0:
            first_error = r.stdout + r.stderr
            wheel = build_wheel_offline(src, tmp_path_factory.mktemp("wheel"))
            how = "pip (wheel built offline by the test suite)"
            r = _pip("install", "--no-deps", "--force-reinstall", str(wheel))
            if r.returncode != 0:
                pytest.fail(f"cannot install {src}:\n--- with --no-build-isolation:\n{first_error}\n"
                            f"--- from an offline wheel:\n{r.stdout}{r.stderr}")
    importlib.invalidate_caches()  # new files in site-packages, new distribution metadata
    (group, entries), = meta["project"]["entry-points"].items()
    assert group == "impala_flow"
    (ep_name, module), = entries.items()
    return ExamplePlugin(
        dist=meta["project"]["name"], version=meta["project"]["version"], entry_point=ep_name,
        module=module, source=src, how=how,
    )


@pytest.fixture(scope="session")
def edinburgh_mission(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The real RADIATE Edinburgh head (400 turns and its GPS) imported once per session with the
    command a user runs, ``impala-flow import radiate`` (about a minute); skips without the data."""
    from impala_flow.cli import main

    from .datasets import radiate_edinburgh_head_or_skip

    folder = radiate_edinburgh_head_or_skip()
    mission = tmp_path_factory.mktemp("edinburgh") / "head.mcap"
    assert main(["import", "radiate", str(folder), "-o", str(mission), "--no-progress"]) == 0
    return mission
