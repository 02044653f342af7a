"""R-SLAM map matching on the real Oxford Radar RobotCar scans vs gt/radar_odometry.csv."""

import cv2

from ..datasets import oxford_sample_or_skip
from .oxford_pairs import register_oxford

cv2.setNumThreads(1)


def test_scan_to_map_registration_on_oxford():
    r = register_oxford(oxford_sample_or_skip(), cell_m=0.1)
    assert len(r.trans_err_m) == 10  # 11 scans, 10 consecutive pairs
    # measured: 8.5 cm and 0.065 deg mean (Cen & Newman: 5.2 cm, 0.09 deg; target 10 cm, 0.2 deg)
    assert r.mean_trans_err_m < 0.10
    assert r.mean_rot_err_deg < 0.2
    assert r.trans_err_m.max() < 0.2
