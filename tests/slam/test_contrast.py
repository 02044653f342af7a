"""matching.contrast on a small image computed by hand (issue 9 item 6: the function does
what its docstring says)."""

import numpy as np
import pytest

from impala_slam.rslam.matching import contrast


def test_contrast_is_the_cell_minus_the_mean_of_the_observed_cells_around_it():
    img = np.zeros((5, 5), np.float32)
    img[1:4, 1:4] = [[1, 2, 3], [4, 5, 6], [7, 8, 0]]  # (3, 3) is 0: not observed
    out = contrast(img, 3)
    # centre (2, 2): its 3x3 window holds 1..8 and the unobserved 0 -> mean of 8 cells = 4.5
    assert out[2, 2] == pytest.approx(5 - 4.5, abs=1e-5)
    # corner (1, 1): window rows 0-2, cols 0-2 -> observed 1, 2, 4, 5 -> mean 3
    assert out[1, 1] == pytest.approx(1 - 3.0, abs=1e-5)  # negative below the local level: kept
    # (3, 2): window rows 2-4, cols 1-3 -> observed 4, 5, 6, 7, 8 -> mean 6
    assert out[3, 2] == pytest.approx(8 - 6.0, abs=1e-5)
    # never observed, or not observed itself: 0
    assert out[0, 0] == 0 and out[3, 3] == 0 and out[4, 4] == 0


def test_support_mask_decides_what_is_observed():
    img = np.array([[2, 2, 2], [2, 0, 2], [2, 2, 2]], np.float32)
    support = np.ones((3, 3), np.float32)  # the centre was observed, as 0 (an empty cell)
    out = contrast(img, 3, support)
    assert out[1, 1] == pytest.approx(0 - 16 / 9, abs=1e-5)  # its mean counts it: 16 / 9
    assert np.all(out[support == 0] == 0)
