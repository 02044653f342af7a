"""The message the detector hands to the tracker (recordable: plain arrays)."""

from __future__ import annotations

import numpy as np

from impala_flow.msgs import message

__all__ = ["MoverDetections"]


@message("tracking.MoverDetections", version=1)
class MoverDetections:
    """Moving-object detections of one antenna turn, one row per object (clustered beams).

    ``xy_m`` (n, 2) and ``cov_xy`` (n, 2, 2) in ``frame``; ``radial_speed_mps`` is the
    ground-relative radial speed (ego-Doppler removed; negative when approaching) with its
    variance ``radial_var``; ``radar_xy_m`` the radar's position at the detection time
    ``t_ns`` (the Doppler is the projection of the velocity on the line of sight from it);
    ``sensor_xy_m`` the radar's position at the message time (the tracker's field of view).
    """

    turn: int
    t_ns: np.ndarray
    xy_m: np.ndarray
    cov_xy: np.ndarray
    radial_speed_mps: np.ndarray
    radial_var: np.ndarray
    radar_xy_m: np.ndarray
    range_m: np.ndarray
    amplitude: np.ndarray
    n_beams: np.ndarray
    sensor_xy_m: np.ndarray  # (2,) the radar's position at the message time (turn end)
    frame: str = "map"
