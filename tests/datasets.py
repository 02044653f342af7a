"""Where the tests find the real datasets (never copied into the repo).

``$IMPALA_FLOW_TEST_DATA`` (the data root or a dataset folder itself), else
``../shared/data/<folder>`` beside the repository. Tests that need a dataset use
:func:`oxford_sample_or_skip`, :func:`boreas_frame_or_skip` or :func:`radiate_head_or_skip`
and skip cleanly when it is absent.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

SAMPLE = "oxford-radar-robotcar-sample"
BOREAS = "boreas-frame"
RADIATE = "radiate-fog-6-0-head"
EDINBURGH = "radiate-edinburgh-head"


def _find(name: str, marker: str) -> Path | None:
    candidates = []
    env = os.environ.get("IMPALA_FLOW_TEST_DATA")
    if env:
        candidates += [Path(env) / name, Path(env)]
    candidates.append(Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / name)
    for c in candidates:
        # the env folder itself counts only when it is this dataset (an Oxford copy: radar/ and gt/)
        itself = c == Path(env or "") and c.name != name
        if (c / marker).is_dir() and (not itself or (name == SAMPLE and (c / "gt").is_dir())):
            return c.resolve()
    return None


def find_oxford_sample() -> Path | None:
    return _find(SAMPLE, "radar")


def find_boreas_frame() -> Path | None:
    return _find(BOREAS, "radar")


def find_radiate_head() -> Path | None:
    return _find(RADIATE, "Navtech_Polar")


def find_radiate_edinburgh_head() -> Path | None:
    return _find(EDINBURGH, "Navtech_Polar")


def _or_skip(folder: Path | None, what: str) -> Path:
    if folder is None:
        pytest.skip(f"{what} not found (set IMPALA_FLOW_TEST_DATA)")
    return folder


def oxford_sample_or_skip() -> Path:
    return _or_skip(find_oxford_sample(), "Oxford Radar RobotCar sample")


def boreas_frame_or_skip() -> Path:
    return _or_skip(find_boreas_frame(), "Boreas frame")


def radiate_head_or_skip() -> Path:
    return _or_skip(find_radiate_head(), "RADIATE fog_6_0 head")


def radiate_edinburgh_head_or_skip() -> Path:
    return _or_skip(find_radiate_edinburgh_head(), "RADIATE Edinburgh head")
