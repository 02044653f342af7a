"""Trajectory metrics (RADAR.md item 10, seed 1 §4.1.2 and Fig. 12): pure numpy functions.

Estimated positions are matched to the truth by timestamp (truth interpolated linearly),
aligned by a least-squares rigid transform in the plane (Kabsch/Umeyama without scale,
by SVD) or on the first pose, then compared along the path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from impala_flow.msgs import wrap_angle

__all__ = [
    "interpolate_truth", "rigid_align_2d", "align_first", "apply_rigid", "path_length_m",
    "distance_travelled_m", "relative_error_pct", "TrajectoryMetrics", "trajectory_metrics",
    "PairErrors", "pair_errors", "segment_error_pct", "TwistErrors", "twist_errors",
]


def interpolate_truth(t_ns: np.ndarray, truth_t_ns: np.ndarray, truth_xyt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Truth (x, y, theta) at ``t_ns`` (linear; theta along the shortest arc) and the mask of
    times inside the truth's span (outside it nothing is extrapolated)."""
    t = np.asarray(t_ns, np.int64)
    tt = np.asarray(truth_t_ns, np.int64)
    inside = (t >= tt[0]) & (t <= tt[-1])
    rel = (t - tt[0]).astype(np.float64)  # relative ns: exact in float64 for missions < 104 days
    rel_t = (tt - tt[0]).astype(np.float64)
    x = np.interp(rel, rel_t, truth_xyt[:, 0])
    y = np.interp(rel, rel_t, truth_xyt[:, 1])
    th = np.interp(rel, rel_t, np.unwrap(truth_xyt[:, 2]))
    return np.column_stack([x, y, wrap_angle(th)]), inside


def rigid_align_2d(src_xy: np.ndarray, dst_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R 2x2, t 2) minimising sum |R src_i + t - dst_i|^2 (Kabsch/Umeyama, no scale)."""
    mu_s, mu_d = src_xy.mean(axis=0), dst_xy.mean(axis=0)
    h = (dst_xy - mu_d).T @ (src_xy - mu_s)  # cross-covariance (up to 1/N)
    u, _, vt = np.linalg.svd(h)
    d = np.diag([1.0, np.sign(np.linalg.det(u @ vt)) or 1.0])  # a rotation, never a reflection
    r = u @ d @ vt
    return r, mu_d - r @ mu_s


def align_first(est_xyt: np.ndarray, truth_xyt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) moving the first estimated pose onto the first true pose."""
    dth = truth_xyt[0, 2] - est_xyt[0, 2]
    c, s = math.cos(dth), math.sin(dth)
    r = np.array([[c, -s], [s, c]])
    return r, truth_xyt[0, :2] - r @ est_xyt[0, :2]


def apply_rigid(r: np.ndarray, t: np.ndarray, xyt: np.ndarray) -> np.ndarray:
    """Poses moved by (R, t): positions rotated and shifted, headings rotated."""
    xy = xyt[:, :2] @ r.T + t
    th = xyt[:, 2] + math.atan2(r[1, 0], r[0, 0])
    return np.column_stack([xy, wrap_angle(th)])


def distance_travelled_m(xy: np.ndarray) -> np.ndarray:
    """Cumulative distance along a polyline (0 at the first point)."""
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))])


def path_length_m(xy: np.ndarray) -> float:
    return float(distance_travelled_m(xy)[-1]) if len(xy) > 1 else 0.0


def relative_error_pct(est_xyt: np.ndarray, truth_xyt: np.ndarray, segment_m: float = 100.0) -> float:
    """Mean translation error over every ``segment_m`` stretch of the true path, in % of it
    (KITTI-style relative pose error: both segment ends expressed in the segment start's frame).
    NaN when the path is shorter than one segment."""
    errs = _segment_errors(est_xyt, truth_xyt, segment_m)
    return 100.0 * float(np.mean(errs)) if errs else float("nan")


def _segment_errors(est_xyt: np.ndarray, truth_xyt: np.ndarray, segment_m: float) -> list[float]:
    """Relative translation error (fraction) of every ``segment_m`` stretch of the true path."""
    dist = distance_travelled_m(truth_xyt[:, :2])
    errs = []
    for i in range(len(dist)):
        j = int(np.searchsorted(dist, dist[i] + segment_m))
        if j >= len(dist):
            break
        errs.append(np.hypot(*(_rel(est_xyt[i], est_xyt[j]) - _rel(truth_xyt[i], truth_xyt[j]))) / (dist[j] - dist[i]))
    return errs


def segment_error_pct(est_xyt: np.ndarray, truth_xyt: np.ndarray,
                      lengths_m: tuple[float, ...] = (100, 200, 300, 400, 500, 600, 700, 800)) -> float:
    """KITTI-style relative error: :func:`relative_error_pct` averaged over every segment of
    every length in ``lengths_m`` that fits in the path (NaN if none does); the segment-drift
    figure radar-odometry papers report (CFEAR, BFAR: 1-2 % on Oxford)."""
    errs = [e for L in lengths_m for e in _segment_errors(est_xyt, truth_xyt, L)]
    return 100.0 * float(np.mean(errs)) if errs else float("nan")


def _rel(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    c, s = math.cos(a[2]), math.sin(a[2])
    d = b[:2] - a[:2]
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])


def _steps(xyt: np.ndarray) -> np.ndarray:
    """(N-1, 3) motion from each pose to the next, in the frame of the first: (-) a (+) b."""
    a, b = xyt[:-1], xyt[1:]
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy, wrap_angle(b[:, 2] - a[:, 2])])


@dataclass
class PairErrors:
    """Relative-motion errors of consecutive estimated poses (scan-to-scan registration):
    each step (-) x_{k-1} (+) x_k against the truth's step between the same times, in the
    earlier pose's frame. ``along_err_m``/``lateral_err_m`` are the signed components of
    the translation error (x forward, y left); ``t_ns`` the later pose's time."""

    t_ns: np.ndarray
    trans_err_m: np.ndarray
    rot_err_deg: np.ndarray
    along_err_m: np.ndarray
    lateral_err_m: np.ndarray
    true_step_m: np.ndarray

    def figures(self, prefix: str = "") -> dict[str, float | int | None]:
        n = len(self.t_ns)
        out: dict[str, float | int | None] = {prefix + "n_pairs": n}
        for key, values, reduce in (("pair_trans_err_mean_m", self.trans_err_m, np.mean),
                                    ("pair_trans_err_max_m", self.trans_err_m, np.max),
                                    ("pair_rot_err_mean_deg", self.rot_err_deg, np.mean),
                                    ("pair_rot_err_max_deg", self.rot_err_deg, np.max),
                                    ("pair_lateral_err_mean_m", self.lateral_err_m, np.mean),
                                    ("pair_along_err_mean_m", self.along_err_m, np.mean)):
            out[prefix + key] = float(reduce(values)) if n else None
        return out

    def rows(self) -> list[dict[str, float | int]]:
        """One record per pair (for metrics.json)."""
        return [{"t_ns": int(t), "trans_err_m": float(e), "rot_err_deg": float(r), "along_err_m": float(a),
                 "lateral_err_m": float(lat), "true_step_m": float(d)}
                for t, e, r, a, lat, d in zip(self.t_ns, self.trans_err_m, self.rot_err_deg, self.along_err_m,
                                              self.lateral_err_m, self.true_step_m, strict=True)]


def pair_errors(est_xyt: np.ndarray, truth_xyt: np.ndarray, t_ns: np.ndarray) -> PairErrors:
    """:class:`PairErrors` of estimated poses and the truth at the same times."""
    e, g = _steps(np.asarray(est_xyt, float)), _steps(np.asarray(truth_xyt, float))
    d = e - g
    return PairErrors(np.asarray(t_ns, np.int64)[1:], np.hypot(d[:, 0], d[:, 1]),
                      np.degrees(np.abs(wrap_angle(d[:, 2]))), d[:, 0], d[:, 1], np.hypot(g[:, 0], g[:, 1]))


@dataclass
class TrajectoryMetrics:
    """Every figure with its unit in its name; ``error_m``/``distance_m`` along the path."""

    t_ns: np.ndarray
    est_aligned_xyt: np.ndarray
    truth_xyt: np.ndarray
    error_m: np.ndarray
    distance_m: np.ndarray
    ate_rmse_m: float
    ate_mean_m: float
    ate_max_m: float
    heading_rmse_deg: float
    rel_err_per_100m_pct: float
    final_error_m: float
    final_error_x_m: float  # final pose error in the truth's frame, first poses aligned
    final_error_y_m: float
    final_rot_err_rad: float
    rel_err_pct: float  # KITTI-style, segments of 100-800 m
    drift_pct: float
    path_length_m: float
    n_poses: int
    align: str
    rotation: np.ndarray  # (R, t) of the alignment: estimate frame -> truth frame
    translation_m: np.ndarray
    pairs: PairErrors

    def figures(self, prefix: str = "") -> dict[str, float | int | str]:
        keys = ("ate_rmse_m", "ate_mean_m", "ate_max_m", "heading_rmse_deg", "rel_err_per_100m_pct",
                "final_error_m", "final_error_x_m", "final_error_y_m", "final_rot_err_rad", "rel_err_pct",
                "drift_pct", "path_length_m", "n_poses", "align")
        out: dict[str, float | int | str] = {}
        for k in keys:
            v = getattr(self, k)
            out[prefix + k] = v if isinstance(v, (int, str)) or not math.isnan(v) else None  # type: ignore[assignment]
        out.update(self.pairs.figures(prefix))
        return out


def trajectory_metrics(t_ns: np.ndarray, est_xyt: np.ndarray, truth_t_ns: np.ndarray, truth_xyt: np.ndarray,
                       align: str = "rigid", segment_m: float = 100.0) -> TrajectoryMetrics:
    """All metrics of an estimated trajectory against the truth (``align``: rigid|first).

    ATE after the chosen alignment; the final drift is always measured after aligning the
    first pose (the start is known; a least-squares fit would hide the end's error), in %
    of the true distance travelled.
    """
    t_ns = np.asarray(t_ns, np.int64)
    truth, inside = interpolate_truth(t_ns, truth_t_ns, truth_xyt)
    t_ns, est, truth = t_ns[inside], np.asarray(est_xyt, float)[inside], truth[inside]
    if len(t_ns) < 2:
        raise ValueError("fewer than two estimated poses fall inside the truth's time span")
    r, t = rigid_align_2d(est[:, :2], truth[:, :2]) if align == "rigid" else align_first(est, truth)
    aligned = apply_rigid(r, t, est)
    err = np.hypot(*(aligned[:, :2] - truth[:, :2]).T)
    dth = wrap_angle(aligned[:, 2] - truth[:, 2])
    dist = distance_travelled_m(truth[:, :2])
    first = apply_rigid(*align_first(est, truth), est)
    final = float(np.hypot(*(first[-1, :2] - truth[-1, :2])))
    length = float(dist[-1])
    return TrajectoryMetrics(
        t_ns, aligned, truth, err, dist,
        ate_rmse_m=float(np.sqrt(np.mean(err ** 2))), ate_mean_m=float(np.mean(err)), ate_max_m=float(np.max(err)),
        heading_rmse_deg=float(np.degrees(np.sqrt(np.mean(dth ** 2)))),
        rel_err_per_100m_pct=relative_error_pct(first, truth, segment_m),
        final_error_m=final, final_error_x_m=float(abs(first[-1, 0] - truth[-1, 0])),
        final_error_y_m=float(abs(first[-1, 1] - truth[-1, 1])),
        final_rot_err_rad=float(abs(wrap_angle(first[-1, 2] - truth[-1, 2]))),
        rel_err_pct=segment_error_pct(first, truth), drift_pct=100.0 * final / length if length > 0 else float("nan"),
        path_length_m=length, n_poses=int(len(t_ns)), align=align, rotation=r, translation_m=t,
        pairs=pair_errors(est, truth, t_ns),
    )


@dataclass
class TwistErrors:
    """Estimated speed and yaw rate against the truth's, at the estimate's times."""

    t_ns: np.ndarray
    speed_err_mps: np.ndarray  # estimate - truth
    yaw_rate_err_dps: np.ndarray
    truth_speed_mps: np.ndarray
    truth_yaw_rate_dps: np.ndarray
    window_s: float

    def figures(self) -> dict[str, float | int]:
        v, w = self.speed_err_mps, self.yaw_rate_err_dps
        return {"speed_err_mean_mps": float(np.mean(v)), "speed_err_std_mps": float(np.std(v)),
                "speed_err_abs_median_mps": float(np.median(np.abs(v))),
                "yaw_rate_err_mean_dps": float(np.mean(w)), "yaw_rate_err_std_dps": float(np.std(w)),
                "yaw_rate_err_abs_median_dps": float(np.median(np.abs(w))), "twist_n": int(len(v)),
                "twist_window_s": self.window_s}


def twist_errors(t_ns: np.ndarray, speed_mps: np.ndarray, yaw_rate_radps: np.ndarray, truth_t_ns: np.ndarray,
                 truth_xyt: np.ndarray, window_s: float = 1.0) -> TwistErrors:
    """Errors of estimated (speed, yaw rate) against the truth's central differences over
    ``window_s`` centred on each estimate (the truth interpolated at both ends): the mean
    velocity over the window, which a two-turn estimate also measures; the noise of a 2 cm
    RTK fix stays below 0.03 m/s over 1 s. Estimates whose window leaves the truth's span
    are left out."""
    t_ns = np.asarray(t_ns, np.int64)
    h = int(round(0.5 * window_s * 1e9))
    inside = (t_ns - h >= truth_t_ns[0]) & (t_ns + h <= truth_t_ns[-1])
    t_ns = t_ns[inside]
    a, _ = interpolate_truth(t_ns - h, truth_t_ns, truth_xyt)
    b, _ = interpolate_truth(t_ns + h, truth_t_ns, truth_xyt)
    d = b - a
    mid = a[:, 2] + 0.5 * wrap_angle(d[:, 2])
    # signed speed: the displacement along the mean heading
    v_true = (np.cos(mid) * d[:, 0] + np.sin(mid) * d[:, 1]) / window_s
    w_true = wrap_angle(d[:, 2]) / window_s
    v = np.asarray(speed_mps, float)[inside]
    w = np.asarray(yaw_rate_radps, float)[inside]
    return TwistErrors(t_ns, v - v_true, np.degrees(w - w_true), v_true, np.degrees(w_true), float(window_s))
