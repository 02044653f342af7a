"""Fixtures of the io tests."""

from __future__ import annotations

import pytest

from impala_flow.io import CodecRegistry, run_codecs


@pytest.fixture
def registry() -> CodecRegistry:
    """The codecs of a run: standard types plus what the installed plugins register (types,
    mirrors: the view plugin's Foxglove schemas)."""
    return run_codecs()
