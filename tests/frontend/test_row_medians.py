"""The compiled row medians (normalise_beams, the pairer's whitening) against np.median."""

import numpy as np

from impala_radar._median_jit import medians


def _rows():
    rng = np.random.default_rng(8)
    yield rng.exponential(1.0, (50, 288)).astype(np.float32)  # powers: even length
    yield rng.exponential(1.0, (50, 287)).astype(np.float32)  # odd length
    lp = np.log(np.maximum(rng.exponential(1.0, (60, 288)), 1e-30)).astype(np.float32)  # logs: both signs
    lp[:5, :200] = np.float32(np.log(1e-30))  # blanked bins: ties at the bottom
    lp[5:10] = np.round(lp[5:10])  # many ties, whole values, zeros
    yield lp
    mixed = rng.normal(0.0, 3.0, (40, 33)).astype(np.float32)
    mixed[0, :17] = 0.0
    mixed[1, 3] = np.float32(-0.0)
    mixed[2, 4] = np.nan
    mixed[3, :20] = -np.inf
    mixed[4, :10] = np.inf
    mixed[5] = np.float32(2.5)
    mixed[6, ::2] = np.float32(-1e-42)  # subnormals
    yield mixed
    yield rng.normal(0.0, 1.0, (7, 1)).astype(np.float32)
    yield rng.normal(0.0, 1.0, (7, 2)).astype(np.float32)


def test_row_medians_are_numpys_bit_for_bit():
    for p in _rows():
        out = medians(p)
        want = np.median(p, axis=1)
        assert np.array_equal(out.view(np.int32), want.view(np.int32)), p.shape
        if not np.isnan(p).any():  # the median of a monotone function of the rows, from theirs
            f = np.log(np.maximum(p, np.float32(1e-30)))
            got = medians(p, f)
            assert np.array_equal(got.view(np.int32), np.median(f, axis=1).view(np.int32)), p.shape
