"""Where the tests find the real Oxford Radar RobotCar sample (never copied into the repo).

``$IMPALA_FLOW_TEST_DATA`` (the data root or the sample folder itself), else
``../shared/data/oxford-radar-robotcar-sample`` beside the repository. Tests that need it
use :func:`oxford_sample_or_skip` and skip cleanly when it is absent.
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest

SAMPLE = "oxford-radar-robotcar-sample"


def find_oxford_sample() -> Path | None:
    candidates = []
    env = os.environ.get("IMPALA_FLOW_TEST_DATA")
    if env:
        candidates += [Path(env) / SAMPLE, Path(env)]
    candidates.append(Path(__file__).resolve().parents[1] / ".." / "shared" / "data" / SAMPLE)
    for c in candidates:
        if (c / "radar").is_dir():
            return c.resolve()
    return None


def oxford_sample_or_skip() -> Path:
    folder = find_oxford_sample()
    if folder is None:
        pytest.skip("Oxford Radar RobotCar sample not found (set IMPALA_FLOW_TEST_DATA)")
    return folder
