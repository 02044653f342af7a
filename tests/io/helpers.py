"""Helpers of the io tests: exact comparison of decoded values."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np


def assert_same(a: Any, b: Any, where: str = "value") -> None:
    """Exact equality: same types, dtypes (byte order included), shapes, bits of NaN/inf."""
    if isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray), where
        assert a.dtype == b.dtype and a.dtype.str == b.dtype.str, (where, a.dtype, b.dtype)
        assert a.shape == b.shape, (where, a.shape, b.shape)
        assert np.ascontiguousarray(a).tobytes() == np.ascontiguousarray(b).tobytes(), where
    elif dataclasses.is_dataclass(a) and not isinstance(a, type):
        assert type(a) is type(b), where
        for f in dataclasses.fields(a):
            assert_same(getattr(a, f.name), getattr(b, f.name), f"{where}.{f.name}")
    elif isinstance(a, float) and math.isnan(a):
        assert isinstance(b, float) and math.isnan(b), where
    else:
        assert type(a) is type(b) and a == b, (where, a, b)
