"""Shared fixtures of the engine's test suite, and what lets it run on several cores.

The suite runs on every CPU this process may use (pytest-xdist, ``-n auto --dist loadfile`` in
pyproject.toml: a file's tests share one worker, so its module fixtures are built once). An
expensive session fixture is built once per run, not once per worker: ``built_once`` makes it
in the folder all workers share, under a lock. ``pytest -n 0`` runs the suite in one process.

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
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import tomllib
import zipfile
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent
EXAMPLE_SRC = TESTS / "plugin_example"

# the example package has its own tests, run against the installed package by
# tests/test_plugins.py; collecting them here would import it before it is installed
collect_ignore = ["plugin_example"]


def pytest_configure(config: pytest.Config) -> None:
    # a shell starts a background job (`pytest ... &`, nohup, some CI runners) with SIGINT ignored,
    # which its child processes inherit: the Ctrl-C tests need the default, Python's KeyboardInterrupt
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


#: the files that take longest (CPU seconds of a serial run on a 2-core machine, 2026-11-27), handed to
#: the workers first so that none is left running alone at the end; every other file follows in
#: collection order. Only the order changes, in parallel runs only; a file missing here is harmless.
HEAVY_FIRST = (
    "sweep/test_local.py",  # 270 s
    "slam/test_distortion_odometry.py",  # 95 s (+ the RADIATE import, 55 s)
    "view/test_bridge.py",  # 95 s, mostly replays at real time
    "slam/test_fmt_ekf.py",  # 75 s
    "tracking/test_datmo_graph.py",  # 65 s (+ the DATMO missions)
    "sweep/test_hardening.py",  # 65 s
    "cli/test_cli_graph.py",  # 60 s
    "sweep/test_cluster.py",  # 55 s
    "slam/test_rslam_radiate.py",  # 50 s
    "cli/test_plugin_extras.py",  # 50 s
    "test_plugins.py",  # 50 s
)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    if getattr(config.option, "numprocesses", None) in (None, 0) or getattr(config.option, "dist", "no") == "no":
        return  # one process: the files in their usual order
    rank = {name: i for i, name in enumerate(HEAVY_FIRST)}

    def key(item: pytest.Item) -> int:
        return rank.get(Path(item.fspath).relative_to(TESTS).as_posix(), len(HEAVY_FIRST))

    items.sort(key=key)  # stable: the other files, and the tests within a file, keep their order


def pytest_xdist_auto_num_workers(config: pytest.Config) -> int | None:
    """``-n auto``: one worker per CPU this process may run on (its affinity, as ``nproc`` counts),
    not psutil's count of the machine's physical cores; PYTEST_XDIST_AUTO_NUM_WORKERS still wins."""
    if os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS") or not hasattr(os, "sched_getaffinity"):
        return None  # pytest-xdist's own rule
    return max(1, len(os.sched_getaffinity(0)))


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    with path.open("w") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def built_once(tmp_path_factory: pytest.TempPathFactory, name: str, build: Callable[[Path], None]) -> Path:
    """The folder ``name`` of this test run, filled by ``build(folder)`` once per run.

    With pytest-xdist every worker has its own base temp folder inside the run's: the folder is
    made there, by the first worker that needs it, while the others wait on a lock and then use
    it as it is. A build that failed or skipped leaves no folder behind, so the next worker
    tries again (and skips or fails the same way).
    """
    root = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        root = root.parent  # the run's folder, shared by its workers
    folder = root / f"once-{name}"
    done = root / f"once-{name}.done"
    with _locked(root / f"once-{name}.lock"):
        if not done.exists():
            shutil.rmtree(folder, ignore_errors=True)
            folder.mkdir()
            try:
                build(folder)
            except BaseException:
                shutil.rmtree(folder, ignore_errors=True)
                raise
            done.touch()
    return folder


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


def _install_lock() -> contextlib.AbstractContextManager[None]:
    """Serialise installs of the example when several test runs share one environment."""
    env_id = hashlib.sha1(sys.prefix.encode()).hexdigest()[:12]
    return _locked(Path(tempfile.gettempdir()) / f"impala-flow-example-install-{env_id}.lock")


def _install_example(folder: Path) -> None:
    # build from a copy: setuptools writes build/ and *.egg-info next to the sources
    src = folder / "impala-flow-example-plugin"
    shutil.copytree(EXAMPLE_SRC, src, ignore=shutil.ignore_patterns("build", "*.egg-info", "__pycache__", ".*"))
    with _install_lock():
        how = "pip --no-build-isolation"
        r = _pip("install", "--no-deps", "--no-build-isolation", "--force-reinstall", str(src))
        if r.returncode != 0:
            first_error = r.stdout + r.stderr
            (folder / "wheel").mkdir()
            wheel = build_wheel_offline(src, folder / "wheel")
            how = "pip (wheel built offline by the test suite)"
            r = _pip("install", "--no-deps", "--force-reinstall", str(wheel))
            if r.returncode != 0:
                pytest.fail(f"cannot install {src}:\n--- with --no-build-isolation:\n{first_error}\n"
                            f"--- from an offline wheel:\n{r.stdout}{r.stderr}")
    (folder / "how.txt").write_text(how, encoding="utf-8")


@pytest.fixture(scope="session")
def example_plugin(tmp_path_factory: pytest.TempPathFactory) -> ExamplePlugin:
    """Install tests/plugin_example into this environment (no network needed) and return its facts.

    Installed once per test run: pytest-xdist's workers share the install (a second
    ``--force-reinstall`` would rewrite the package under a worker that is using it)."""
    folder = built_once(tmp_path_factory, "plugin_example", _install_example)
    src = folder / "impala-flow-example-plugin"
    meta = tomllib.loads((src / "pyproject.toml").read_text(encoding="utf-8"))
    importlib.invalidate_caches()  # new files in site-packages, new distribution metadata
    (group, entries), = meta["project"]["entry-points"].items()
    assert group == "impala_flow"
    (ep_name, module), = entries.items()
    return ExamplePlugin(
        dist=meta["project"]["name"], version=meta["project"]["version"], entry_point=ep_name,
        module=module, source=src, how=(folder / "how.txt").read_text(encoding="utf-8"),
    )


@pytest.fixture(scope="session")
def edinburgh_mission(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The real RADIATE Edinburgh head (400 turns and its GPS) imported once per test run with the
    command a user runs, ``impala-flow import radiate`` (about a minute); skips without the data."""
    from impala_flow.cli import main

    from .datasets import radiate_edinburgh_head_or_skip

    source = radiate_edinburgh_head_or_skip()

    def build(folder: Path) -> None:
        assert main(["import", "radiate", str(source), "-o", str(folder / "head.mcap"), "--no-progress"]) == 0

    return built_once(tmp_path_factory, "edinburgh", build) / "head.mcap"
