"""The FMT's compiled loop (numba, ``cache=True``; imported at its first call, never with the
plugin): the 2 x 2 mean of a grid, the same bits as the numpy formulation it replaces
(``((x00 + x01) + (x10 + x11)) / 4`` in float32; tests/slam/test_fmt_core.py compares them)."""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["mean2x2"]


@numba.njit(cache=True, nogil=True)
def mean2x2(data, out):  # pragma: no cover - compiled
    """out[i, j] = ((d[2i, 2j] + d[2i, 2j+1]) + (d[2i+1, 2j] + d[2i+1, 2j+1])) / 4 in float32, one pass
    (numpy's strided sums read the grid three times)."""
    four = np.float32(4)
    for i in range(out.shape[0]):
        r0 = data[2 * i]
        r1 = data[2 * i + 1]
        for j in range(out.shape[1]):
            out[i, j] = ((r0[2 * j] + r0[2 * j + 1]) + (r1[2 * j] + r1[2 * j + 1])) / four
    return out
