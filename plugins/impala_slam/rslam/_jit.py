"""R-SLAM's compiled loop (numba, ``cache=True``, nogil; imported at the first map update, never
with the plugin): the merge of a turn into one map tile (eq. 6) in one pass. It gives the bits of
the numpy formulation it replaces (alpha zeroed where the amplitude is NaN, alpha A, a masked add
and the normaliser's add; tests/slam/test_map_update.py compares them)."""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["merge_tile"]


@numba.njit(cache=True, nogil=True)
def merge_tile(amp, alpha, ws, cnt, weighted):  # pragma: no cover - compiled
    """Where alpha > 0 and ``amp`` is a number: ``ws += alpha * amp`` and ``cnt += alpha``
    (``weighted``) or ``cnt += 1``; float32 throughout (the same roundings as numpy's float32
    ufuncs). Returns whether any cell was merged."""
    touched = False
    one = np.float32(1.0)
    for i in range(amp.shape[0]):
        a_row, w_row, s_row, c_row = amp[i], alpha[i], ws[i], cnt[i]
        for j in range(amp.shape[1]):
            w = w_row[j]
            v = a_row[j]
            if w > 0 and v == v:
                s_row[j] += w * v
                c_row[j] += w if weighted else one
                touched = True
    return touched
