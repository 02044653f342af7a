"""Compiled last step of :func:`impala_radar.speckle.core.multilook` (numba): the mean of the
looks and their count as float32 in one pass, instead of numpy's division of the whole grid,
a mask, a conversion and ``cv2.copyTo`` (the same float32 division: the same bits). Imported
at first use, compiled once per machine (``cache=True``).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["mean_of_looks"]


@numba.njit(cache=True, nogil=True, error_model="numpy")
def mean_of_looks(acc, cnt, out, cnt_f):  # pragma: no cover - compiled
    """out = acc / cnt where cnt > 0, else 0; cnt_f = cnt as float32."""
    a, c, o, cf = acc.ravel(), cnt.ravel(), out.ravel(), cnt_f.ravel()
    zero = np.float32(0.0)
    for k in range(a.size):
        n = np.float32(c[k])
        cf[k] = n
        o[k] = a[k] / n if n > zero else zero
