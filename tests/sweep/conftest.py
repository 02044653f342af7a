"""Fixtures of the sweep tests: short simulated missions (simulated once per session through
the `simulate` command, as a user would), and a writer of sweep files."""

from __future__ import annotations

import csv
import os
from collections.abc import Callable
from pathlib import Path

import pytest

from impala_flow import cli

from ..conftest import built_once

ROOT = Path(__file__).resolve().parents[2]
GRAPH = ROOT / "graphs" / "rslam.yaml"
#: short missions keep a task at about 2 s: R-SLAM still gets 4 turns and the evaluator its figures
DURATION_S = 4
#: columns that differ between two runs of the same task (timing, which process ran it)
TIMING = ("wall_s", "worker")


def simulate(path: Path, seed: int, duration_s: float = DURATION_S, scenario: str = "beynes") -> Path:
    code = cli.main(["simulate", scenario, "-o", str(path), "--duration", f"{duration_s}s", "--seed", str(seed),
                     "--no-progress"])
    assert code == 0
    return path


@pytest.fixture(scope="session")
def missions(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Two 4-second Beynes missions (seeds 1 and 2), as `impala-flow simulate` writes them (once per run)."""

    def build(folder: Path) -> None:
        for seed in (1, 2):
            simulate(folder / f"beynes-{seed}.mcap", seed)

    folder = built_once(tmp_path_factory, "sweep-missions", build)
    return [folder / f"beynes-{seed}.mcap" for seed in (1, 2)]


@pytest.fixture
def write_sweep(tmp_path: Path) -> Callable[..., Path]:
    def write(text: str, name: str = "sweep.yaml") -> Path:
        path = tmp_path / name
        path.write_text(text, encoding="utf-8")
        return path

    return write


def read_rows(folder: Path) -> list[dict[str, str]]:
    with open(folder / "results.csv", encoding="utf-8", newline="") as f:
        return list(csv.DictReader(f))


def without_timing(rows: list[dict[str, str]]) -> list[dict[str, str]]:
    return [{k: v for k, v in r.items() if k not in TIMING} for r in rows]


def sweep_main(*args: str) -> int:
    """``impala-flow sweep ARGS`` in this process (the workers are processes of their own)."""
    return cli.main(["sweep", *args, "--no-progress"])


def env_without_plugin_blocks() -> dict[str, str]:
    env = dict(os.environ)
    env.pop("IMPALA_FLOW_DISABLE_PLUGINS", None)
    return env


def plain_run(mission: Path, out: Path, *sets: str) -> dict:
    """``impala-flow run graphs/rslam.yaml --var mission=M --var out=O --set ...``: its summary (JSON)."""
    import json

    summary = out.with_suffix(".json")
    args = ["run", str(GRAPH), "--var", f"mission={mission}", "--var", f"out={out}", "--summary-json", str(summary),
            "--no-progress"]
    for s in sets:
        args += ["--set", s]
    assert cli.main(args) == 0
    return json.loads(summary.read_text(encoding="utf-8"))


def assert_row_is_the_plain_run(row: dict[str, str], plain: dict, metrics: list[str]) -> None:
    """A sweep's row gives the figures of the same graph run alone: every metric, the counters."""
    for m in metrics:
        comp, key = m.split(".")
        assert float(row[m]) == plain["extra"][comp][key], m
    assert int(row["samples"]) == sum(plain["emitted"].values())
    assert int(row["lost"]) == plain["lost_total"]
