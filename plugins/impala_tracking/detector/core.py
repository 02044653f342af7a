"""``tracking.MoverDetector``: moving objects from the Doppler of paired detections (seed 1 §4.3.2).

The fuzzy pairer has already compared the up- and down-ramp spectra of every beam: a pair
whose peaks sit ``2 f_d`` apart (eq. 3) has radial speed ``V``. A static target seen from a
radar moving forward at ``s`` has ``V_static = -s cos(theta) cos(el)`` (seed 1 eq. 7, the
depression factor ``cos el`` = ground / slant range for ground echoes, 1 for raised ones), so
removing the ego-Doppler leaves the ground-relative radial speed

    v_g = V - V_static = u . v_target                                  (u: line of sight)

which is zero for the static world. A detection is a mover candidate when ``|v_g|`` exceeds
``n_sigma`` times its standard deviation ``sqrt(sigma_D^2 + (cos theta sigma_s)^2)`` (Doppler
measurement noise, ego-speed uncertainty) and ``min_radial_speed_mps``; under both height
hypotheses (ground, raised) when the radar moves. Candidates of adjacent beams with close
range and Doppler are one object (a car spans its beam width, several beams): clustered
(``scipy.sparse.csgraph.connected_components``) into one detection with amplitude-weighted
range, azimuth, Doppler and time. False detections are filtered by a minimum amplitude, a
clutter map (cells where candidates keep appearing: persistent ghost pairs, fluttering
vegetation) and optionally persistence (a candidate near the previous turn's). Each
detection carries its position and radial-speed covariances, in the frame of the ``pose``
input (map frame from RTK-GPS or odometry; the radar's own frame without it).
"""

from __future__ import annotations

import numpy as np

__all__ = ["ground_radial_speed_mps", "cluster_candidates", "absorb_ghosts", "ClutterMap"]


def ground_radial_speed_mps(radial_mps, azimuth_rad, range_m, speed_mps: float,
                            radar_height_m: float = 1.3) -> tuple[np.ndarray, np.ndarray]:
    """Ego-Doppler removed (eq. 7): ``(v_raised, v_ground)`` = V + s cos(theta) f, f = 1 for a
    raised scatterer, ground / slant range for a ground one (NaN nearer than the height)."""
    v = np.asarray(radial_mps, float)
    c = speed_mps * np.cos(np.asarray(azimuth_rad, float))
    r = np.asarray(range_m, float)
    ratio = np.divide(radar_height_m, r, out=np.full(r.shape, np.inf), where=r > 0)
    f_ground = np.sqrt(np.clip(1.0 - ratio**2, 0.0, None))
    return v + c, v + c * f_ground


def cluster_candidates(beam: np.ndarray, range_m: np.ndarray, v_mps: np.ndarray, n_beams: int,
                       max_beam_gap: int, max_range_gap_m: float, max_speed_gap_mps: float) -> np.ndarray:
    """Label of each candidate: connected components of 'adjacent beams (circular), close range
    and close Doppler'."""
    n = len(beam)
    if n == 0:
        return np.zeros(0, np.int64)
    db = np.abs(beam[:, None] - beam[None, :])
    db = np.minimum(db, n_beams - db)
    near = ((db <= max_beam_gap) & (np.abs(range_m[:, None] - range_m[None, :]) <= max_range_gap_m)
            & (np.abs(v_mps[:, None] - v_mps[None, :]) <= max_speed_gap_mps))
    i, j = np.nonzero(near)
    # here, not at import: scipy.sparse costs 0.2-0.4 s to import, paid by every command's start otherwise
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    _, labels = connected_components(coo_matrix((np.ones(len(i)), (i, j)), shape=(n, n)), directed=False)
    return labels


def absorb_ghosts(labels: np.ndarray, range_m: np.ndarray, azimuth_rad: np.ndarray, weight: np.ndarray,
                  radius_m: float, max_beams: int) -> np.ndarray:
    """Cluster each cluster merges into: a cluster of at most ``max_beams`` detections within
    ``radius_m`` (range and arc) of one with at least twice as many (and 3 or more) is a ghost
    pair of that object's peaks (front and rear of a car paired crosswise, seed 1 §2.4): its
    position still belongs to the object, its Doppler does not. Others map to themselves."""
    n = int(labels.max()) + 1
    cnt = np.bincount(labels, minlength=n)
    wsum = np.bincount(labels, weight, n)
    r = np.bincount(labels, weight * range_m, n) / wsum
    az = np.arctan2(np.bincount(labels, weight * np.sin(azimuth_rad), n),
                    np.bincount(labels, weight * np.cos(azimuth_rad), n))
    target = np.arange(n)
    big = cnt >= 3
    for i in np.nonzero(cnt <= max_beams)[0]:
        arc = np.abs(np.angle(np.exp(1j * (az - az[i])))) * r[i]
        c = np.nonzero(big & (cnt >= 2 * cnt[i]) & (np.abs(r - r[i]) <= radius_m) & (arc <= radius_m))[0]
        if len(c):
            target[i] = c[np.argmax(cnt[c])]
    return target


class ClutterMap:
    """Rate of mover candidates per cell of ``cell_m`` in the detection frame, forgotten with
    time constant ``tau_turns``: cells above ``threshold`` candidates per turn are clutter."""

    def __init__(self, cell_m: float, tau_turns: float, threshold: float) -> None:
        self.cell_m, self.decay, self.threshold = cell_m, 1.0 - 1.0 / tau_turns, threshold
        self.rate: dict[tuple[int, int], float] = {}

    def is_clutter(self, xy_m: np.ndarray) -> np.ndarray:
        keys = np.floor(np.asarray(xy_m).reshape(-1, 2) / self.cell_m).astype(np.int64)
        return np.array([self.rate.get((int(a), int(b)), 0.0) > self.threshold for a, b in keys], bool)

    def update(self, xy_m: np.ndarray) -> None:
        self.rate = {k: v * self.decay for k, v in self.rate.items() if v * self.decay > 1e-3}
        w = 1.0 / self.decay if self.decay > 0 else 1.0
        for a, b in np.floor(np.asarray(xy_m).reshape(-1, 2) / self.cell_m).astype(np.int64):
            k = (int(a), int(b))
            self.rate[k] = self.rate.get(k, 0.0) + (1.0 - self.decay) * w
