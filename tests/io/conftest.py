"""Fixtures of the io tests."""

from __future__ import annotations

import pytest

from impala_flow.io import CodecRegistry


@pytest.fixture
def registry() -> CodecRegistry:
    return CodecRegistry.with_standard_types()
