"""``slam.KissIcp``: kiss-icp (Vizzo et al., RA-L 2023), the point-to-point ICP odometry many
radar engineers try first, fed with a radar's point detections, as a baseline beside the chain.

kiss-icp is an optional dependency (``pip install 'impala-flow[peers]'``), imported when the
component starts. Per turn of detections (e.g. ``radar.PeakExtractor``: the strongest returns of
each beam, each with its beam's time), the points are placed in the plane (x forward, y left,
z = 0) and given to :class:`kiss_icp.kiss_icp.KissICP` as one frame: deskewed, voxelised,
registered to its local voxel map with its adaptive threshold, added to the map.

Two things are adapted to a rotating radar, with kiss-icp's own functions:

- kiss-icp's constant-velocity model counts in frames; a radar log misses turns (gaps of up to
  1.6 s in RADIATE). Before each frame its last relative motion is rescaled (on SE(2), constant
  twist) from the time it spanned to the time since the previous turn, so a gap predicts the
  distance driven in it.
- kiss-icp's deskew normalises the points' times over the frame ([first, last] -> [0, 1]) and
  moves every point to the pose at the last one, with its last relative motion as the motion
  over the frame. A turn lasts one rotation whatever the time since the previous turn, so the
  deskew is done apart (kiss-icp's Preprocessor) with that motion rescaled to the time between
  the turn's first and last points, and the registration runs on the deskewed points. The
  first two turns, registered before any motion is known, enter the map undeskewed: once the
  second is registered the map is made again from both, deskewed with the motion between them
  (a vehicle already moving at the first turn: without it the third turn jumps by a metre).
- A radar standing still adds its clutter to the map turn after turn until every voxel near it
  is full, and the registration then holds the vehicle still when it drives off (the RADIATE
  drive's first minute). With ``map_min_motion_m`` a turn enters the map only once the pose has
  moved that far (or turned a tenth of it in radians) since the last turn that did.

The pose (frame ``odom``, the first turn's pose at the origin) is the registered pose projected
on the plane, stamped at the turn's last point (its last beam for ``radar.PeakExtractor``, unless
that beam had no return): the time the points were deskewed to. The twist is the mean velocity
since the previous turn in the body frame. A turn with fewer than ``min_points`` points is not registered (counted in
``skipped_turns``). Runs single-threaded by default (``threads``): the same recording gives
bit-identical poses.
"""

from __future__ import annotations

import math

import numpy as np

from .. import se2


def planar_pose(m: np.ndarray) -> tuple[float, float, float]:
    return float(m[0, 3]), float(m[1, 3]), math.atan2(float(m[1, 0]), float(m[0, 0]))


def pose_matrix(x: float, y: float, theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    m = np.eye(4)
    m[:2, :2] = [[c, -s], [s, c]]
    m[0, 3], m[1, 3] = x, y
    return m


def scaled_twist(twist: tuple[float, float, float], s: float) -> np.ndarray:
    """4x4 matrix of the planar motion of ``twist`` over ``s`` of its time."""
    return pose_matrix(*se2.exp((s * twist[0], s * twist[1], s * twist[2])))
