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
    "relative_position",
    "interpolate_truth", "rigid_align_2d", "align_first", "align_start", "apply_rigid", "path_length_m",
    "distance_travelled_m", "relative_error_pct", "TrajectoryMetrics", "trajectory_metrics",
    "PairErrors", "pair_errors", "segment_error_pct", "segment_errors_pct", "TwistErrors", "twist_errors",
    "heading_known_at", "SEGMENT_LENGTHS_M", "gap_spans_ns", "in_spans",
]


#: segment lengths of the KITTI-style relative drift (m along the true path)
SEGMENT_LENGTHS_M = (100.0, 200.0, 300.0, 400.0, 500.0, 600.0, 700.0, 800.0)


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


def gap_spans_ns(t_ns: np.ndarray, factor: float = 3.0) -> np.ndarray:
    """(K, 2) int64: the (start, end) stamps of the intervals with no sample longer than
    ``factor`` periods. Repeated stamps (a GPS writing each fix twice) count once; the period
    is the median interval, intervals shorter than a quarter of the mean one (a fix repeated
    with a nearly equal stamp) left out."""
    t = np.unique(np.asarray(t_ns, np.int64))
    if len(t) < 3:
        return np.zeros((0, 2), np.int64)
    dt = np.diff(t)
    period = float(np.median(dt[dt >= 0.25 * float(np.mean(dt))]))
    at = np.flatnonzero(dt > factor * period)
    return np.column_stack([t[at], t[at + 1]])


def in_spans(t_ns: np.ndarray, spans_ns: np.ndarray, half_window_ns: int = 0) -> np.ndarray:
    """Mask of the times whose window ``t +- half_window_ns`` overlaps the inside of one of the
    (start, end) spans (sorted, disjoint): with 0, the times strictly inside one."""
    t = np.asarray(t_ns, np.int64)
    if not len(spans_ns):
        return np.zeros(len(t), bool)
    k = np.searchsorted(spans_ns[:, 0], t + half_window_ns, "left") - 1  # the last span starting before t + h
    kk = np.maximum(k, 0)
    return (k >= 0) & (spans_ns[kk, 1] > t - half_window_ns)


def heading_known_at(t_ns: np.ndarray, truth_t_ns: np.ndarray, truth_known: np.ndarray | None) -> np.ndarray:
    """Whether the truth heading interpolated at ``t_ns`` is known: the truth samples on both
    sides of each time are (the ones at that time when it is a truth time). ``truth_known``
    None: every heading known. Times outside the truth's span take the nearest end's."""
    t = np.asarray(t_ns, np.int64)
    if truth_known is None:
        return np.ones(len(t), bool)
    known = np.asarray(truth_known, bool)
    tt = np.asarray(truth_t_ns, np.int64)
    last = len(tt) - 1
    lo = np.clip(np.searchsorted(tt, t, "right") - 1, 0, last)  # last truth time <= t
    hi = np.clip(np.searchsorted(tt, t, "left"), 0, last)  # first truth time >= t
    return known[lo] & known[hi]


def rigid_align_2d(src_xy: np.ndarray, dst_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R 2x2, t 2) minimising sum |R src_i + t - dst_i|^2 (Kabsch/Umeyama, no scale)."""
    mu_s, mu_d = src_xy.mean(axis=0), dst_xy.mean(axis=0)
    # cross-covariance (up to 1/N); einsum's own loop, not BLAS, so the sum's order (and the
    # last bits) never depends on how many BLAS threads a process has (a Dask worker has one)
    h = np.einsum("ni,nj->ij", dst_xy - mu_d, src_xy - mu_s)
    u, _, vt = np.linalg.svd(h)
    d = np.diag([1.0, np.sign(np.linalg.det(u @ vt)) or 1.0])  # a rotation, never a reflection
    r = u @ d @ vt
    return r, mu_d - r @ mu_s


def align_first(est_xyt: np.ndarray, truth_xyt: np.ndarray, k: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) moving the ``k``-th estimated pose (the first by default) onto the ``k``-th true pose."""
    dth = truth_xyt[k, 2] - est_xyt[k, 2]
    c, s = math.cos(dth), math.sin(dth)
    r = np.array([[c, -s], [s, c]])
    return r, truth_xyt[k, :2] - r @ est_xyt[k, :2]


#: with a GPS truth (headings unknown somewhere), the start of the final drift is aligned on the
#: positions of the first START_FIT_FRACTION of the path from the first known heading (at least
#: START_FIT_MIN_M), not on one course-over-ground heading: on the RADIATE Edinburgh head the course
#: as the car moves off is 17 deg off the one a few seconds later, which alone made a 0.36 % ATE
#: read as a 26 % final drift
START_FIT_MIN_M = 20.0
START_FIT_FRACTION = 0.1


def align_start(est_xyt: np.ndarray, truth_xyt: np.ndarray, k: int, dist_m: np.ndarray,
                ) -> tuple[np.ndarray, np.ndarray]:
    """(R, t) of the rigid least-squares fit of the estimated positions on the true ones over the
    first stretch from pose ``k`` (``dist_m``: distance along the truth): max(START_FIT_MIN_M,
    START_FIT_FRACTION of the rest of the path), at least two poses. Heading-free: for a GPS truth."""
    rest = float(dist_m[-1] - dist_m[k])
    end = int(np.searchsorted(dist_m, dist_m[k] + max(START_FIT_MIN_M, START_FIT_FRACTION * rest), side="right"))
    end = max(end, k + 2)
    return rigid_align_2d(est_xyt[k:end, :2], truth_xyt[k:end, :2])


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


def _mean_pct(errs: np.ndarray) -> float | None:
    return 100.0 * float(np.mean(errs)) if len(errs) else None


def relative_error_pct(est_xyt: np.ndarray, truth_xyt: np.ndarray, segment_m: float = 100.0,
                       start_known: np.ndarray | None = None) -> float | None:
    """Mean translation error over every ``segment_m`` stretch of the true path, in % of it
    (KITTI-style relative pose error: both segment ends expressed in the segment start's frame).
    Only stretches starting where ``start_known`` (the truth heading there is known; None:
    everywhere). None when no stretch fits."""
    return _mean_pct(_segment_errors(est_xyt, truth_xyt, segment_m, start_known))


def _segment_errors(est_xyt: np.ndarray, truth_xyt: np.ndarray, segment_m: float,
                    start_known: np.ndarray | None = None) -> np.ndarray:
    """Relative translation error (fraction of the length) of every ``segment_m`` stretch of
    the true path starting at a pose (where ``start_known``) and ending at the first pose at
    least ``segment_m`` further along it."""
    dist = distance_travelled_m(truth_xyt[:, :2])
    i = np.arange(len(dist)) if start_known is None else np.flatnonzero(start_known)
    j = np.searchsorted(dist, dist[i] + segment_m, "left")
    fits = j < len(dist)
    i, j = i[fits], j[fits]
    d = _rel_v(est_xyt[i], est_xyt[j]) - _rel_v(truth_xyt[i], truth_xyt[j])
    return np.hypot(d[:, 0], d[:, 1]) / (dist[j] - dist[i])


def segment_errors_pct(est_xyt: np.ndarray, truth_xyt: np.ndarray,
                       lengths_m: tuple[float, ...] = SEGMENT_LENGTHS_M,
                       start_known: np.ndarray | None = None) -> dict[float, np.ndarray]:
    """Per segment length that fits in the path: the errors (%) of its segments (see
    :func:`relative_error_pct`)."""
    out = {float(L): 100.0 * _segment_errors(est_xyt, truth_xyt, L, start_known) for L in lengths_m}
    return {L: e for L, e in out.items() if len(e)}


def segment_error_pct(est_xyt: np.ndarray, truth_xyt: np.ndarray,
                      lengths_m: tuple[float, ...] = SEGMENT_LENGTHS_M,
                      start_known: np.ndarray | None = None) -> float | None:
    """KITTI-style relative error: :func:`relative_error_pct` averaged over every segment of
    every length in ``lengths_m`` that fits in the path (None if none does); the segment-drift
    figure radar-odometry papers report (CFEAR, BFAR: 1-2 % on Oxford)."""
    errs = segment_errors_pct(est_xyt, truth_xyt, lengths_m, start_known)
    return float(np.mean(np.concatenate(list(errs.values())))) if errs else None


def relative_position(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Position of pose ``b`` (x_m, y_m, theta_rad) in the frame of pose ``a``."""
    c, s = math.cos(a[2]), math.sin(a[2])
    d = b[:2] - a[:2]
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])


def _rel_v(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N, 2): each b's position in the frame of the a of the same row."""
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy])


def _steps(xyt: np.ndarray) -> np.ndarray:
    """(N-1, 3) motion from each pose to the next, in the frame of the first: (-) a (+) b."""
    a, b = xyt[:-1], xyt[1:]
    return np.column_stack([_rel_v(a, b), wrap_angle(b[:, 2] - a[:, 2])])


@dataclass
class PairErrors:
    """Relative-motion errors of consecutive estimated poses (scan-to-scan registration):
    each step (-) x_{k-1} (+) x_k against the truth's step between the same times, in the
    earlier pose's frame. ``along_err_m``/``lateral_err_m`` are the signed components of
    the translation error (x forward, y left); ``t_ns`` the later pose's time. Only pairs
    whose truth heading is known at both ends are scored; ``n_skipped`` counts the others."""

    t_ns: np.ndarray
    trans_err_m: np.ndarray
    rot_err_deg: np.ndarray
    along_err_m: np.ndarray
    lateral_err_m: np.ndarray
    true_step_m: np.ndarray
    n_skipped: int = 0

    def figures(self, prefix: str = "") -> dict[str, float | int | None]:
        n = len(self.t_ns)
        out: dict[str, float | int | None] = {prefix + "n_pairs": n,
                                              prefix + "n_pairs_heading_unknown": int(self.n_skipped)}
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


def pair_errors(est_xyt: np.ndarray, truth_xyt: np.ndarray, t_ns: np.ndarray,
                heading_known: np.ndarray | None = None) -> PairErrors:
    """:class:`PairErrors` of estimated poses and the truth at the same times; with
    ``heading_known`` (per pose) only the pairs whose truth heading is known at both ends."""
    e, g = _steps(np.asarray(est_xyt, float)), _steps(np.asarray(truth_xyt, float))
    keep = np.ones(len(e), bool) if heading_known is None else heading_known[:-1] & heading_known[1:]
    d, g = (e - g)[keep], g[keep]
    return PairErrors(np.asarray(t_ns, np.int64)[1:][keep], np.hypot(d[:, 0], d[:, 1]),
                      np.degrees(np.abs(wrap_angle(d[:, 2]))), d[:, 0], d[:, 1], np.hypot(g[:, 0], g[:, 1]),
                      int(np.count_nonzero(~keep)))


@dataclass
class TrajectoryMetrics:
    """Every figure with its unit in its name; ``error_m``/``distance_m`` along the path.
    Figures that need the truth heading (heading RMSE, final rotation, relative errors, pair
    errors) use only the poses where it is known (``heading_known``); None when none is."""

    t_ns: np.ndarray
    est_aligned_xyt: np.ndarray
    truth_xyt: np.ndarray
    error_m: np.ndarray
    distance_m: np.ndarray
    ate_rmse_m: float
    ate_mean_m: float
    ate_max_m: float
    heading_rmse_deg: float | None
    rel_err_per_100m_pct: float | None  # segments of segment_m (100 m by default)
    final_error_m: float | None
    final_error_x_m: float | None  # final pose error in the truth's frame, first poses aligned
    final_error_y_m: float | None
    final_rot_err_rad: float | None
    rel_err_pct: float | None  # KITTI-style: mean over every segment of 100, 200, ..., 800 m
    drift_pct: float | None
    path_length_m: float
    n_poses: int
    align: str
    rotation: np.ndarray  # (R, t) of the alignment: estimate frame -> truth frame
    translation_m: np.ndarray
    pairs: PairErrors
    heading_known: np.ndarray  # per matched pose: the truth heading there is known
    segment_errors_pct: dict[float, np.ndarray]  # per length (m) that fits: each segment's error (%)
    first_pose: int  # the pose the first-pose alignment uses (the first with a known truth heading)
    n_in_truth_gaps: int = 0  # estimated poses left out: no truth around them (a truth gap, see gap_spans_ns)

    @property
    def ate_pct(self) -> float | None:
        """ATE RMSE in % of the true path length."""
        return 100.0 * self.ate_rmse_m / self.path_length_m if self.path_length_m > 0 else None

    def figures(self, prefix: str = "") -> dict[str, float | int | str | None]:
        keys = ("ate_rmse_m", "ate_mean_m", "ate_max_m", "ate_pct", "heading_rmse_deg", "rel_err_per_100m_pct",
                "final_error_m", "final_error_x_m", "final_error_y_m", "final_rot_err_rad", "rel_err_pct",
                "drift_pct", "path_length_m", "n_poses", "align")
        out: dict[str, float | int | str | None] = {}
        for k in keys:
            v = getattr(self, k)
            out[prefix + k] = None if isinstance(v, float) and not math.isfinite(v) else v
        out[prefix + "n_heading_unknown"] = int(np.count_nonzero(~self.heading_known))
        out[prefix + "n_poses_in_truth_gaps"] = self.n_in_truth_gaps
        out[prefix + "rel_err_segments"] = int(sum(len(e) for e in self.segment_errors_pct.values()))
        for L, e in self.segment_errors_pct.items():
            out[prefix + f"rel_err_{L:g}m_pct"] = float(np.mean(e))
            out[prefix + f"rel_err_{L:g}m_segments"] = int(len(e))
        if self.first_pose:
            out[prefix + "first_aligned_pose"] = int(self.first_pose)
        out.update(self.pairs.figures(prefix))
        return out


def trajectory_metrics(t_ns: np.ndarray, est_xyt: np.ndarray, truth_t_ns: np.ndarray, truth_xyt: np.ndarray,
                       align: str = "rigid", segment_m: float = 100.0,
                       truth_heading_known: np.ndarray | None = None) -> TrajectoryMetrics:
    """All metrics of an estimated trajectory against the truth (``align``: rigid|first).

    Estimated poses outside the truth's span or inside one of its gaps (:func:`gap_spans_ns`:
    nothing to interpolate from) are left out and counted (``n_poses_in_truth_gaps``).
    ATE after the chosen alignment: ``rigid`` fits the positions only (SE(2) least squares,
    as evo_ape --align); ``first`` puts the first estimated pose whose truth heading is known
    onto the truth (ValueError when none is). The final drift is always measured after that
    first-pose alignment (the start is known; a least-squares fit would hide the end's
    error), in % of the true distance travelled from that pose; with a GPS truth (headings
    unknown somewhere) the start is aligned on the positions of the path's first tenth instead
    (:func:`align_start`: one course-over-ground heading is too noisy to carry a whole drive).
    ``truth_heading_known`` (per truth sample, None: all): see :class:`TrajectoryMetrics` for what is scored where not.
    Relative errors (KITTI-style) start only where the truth heading is known: their frame is
    the truth's pose there (segments starting at rest, where GPS gives no heading, duplicate
    the ones starting when the vehicle moves off).
    """
    t_ns = np.asarray(t_ns, np.int64)
    truth, inside = interpolate_truth(t_ns, truth_t_ns, truth_xyt)
    in_gap = in_spans(t_ns, gap_spans_ns(truth_t_ns)) & inside
    inside &= ~in_gap
    known = heading_known_at(t_ns, truth_t_ns, truth_heading_known)[inside]
    t_ns, est, truth = t_ns[inside], np.asarray(est_xyt, float)[inside], truth[inside]
    if len(t_ns) < 2:
        raise ValueError(f"fewer than two estimated poses fall inside the truth's time span (outside its gaps): "
                         f"{len(t_ns)} of {len(inside)}")
    k0 = int(np.argmax(known)) if known.any() else None
    if align == "first" and k0 is None:
        raise ValueError(f"align: first needs a known truth heading at a matched pose, and the truth's heading is "
                         f"unknown at all {len(t_ns)} (GPS at rest?): use align: rigid (positions only)")
    r, t = rigid_align_2d(est[:, :2], truth[:, :2]) if align == "rigid" else align_first(est, truth, k0)
    aligned = apply_rigid(r, t, est)
    err = np.hypot(*(aligned[:, :2] - truth[:, :2]).T)
    dth = wrap_angle(aligned[known, 2] - truth[known, 2])
    dist = distance_travelled_m(truth[:, :2])
    length = float(dist[-1])
    final_xy: np.ndarray | None = None
    final_rot = None
    drift = None
    if k0 is not None:
        gps_like = not bool(np.all(known))  # headings unknown somewhere: a GPS truth, no trusted single heading
        start = align_start(est, truth, k0, dist) if gps_like else align_first(est, truth, k0)
        first = apply_rigid(*start, est)
        final_xy = first[-1, :2] - truth[-1, :2]
        if known[-1]:
            final_rot = float(abs(wrap_angle(first[-1, 2] - truth[-1, 2])))
        travelled = length - float(dist[k0])
        drift = 100.0 * float(np.hypot(*final_xy)) / travelled if travelled > 0 else None
    segments = segment_errors_pct(est, truth, SEGMENT_LENGTHS_M, known)
    return TrajectoryMetrics(
        t_ns, aligned, truth, err, dist,
        ate_rmse_m=float(np.sqrt(np.mean(err ** 2))), ate_mean_m=float(np.mean(err)), ate_max_m=float(np.max(err)),
        heading_rmse_deg=float(np.degrees(np.sqrt(np.mean(dth ** 2)))) if len(dth) else None,
        rel_err_per_100m_pct=relative_error_pct(est, truth, segment_m, known),
        final_error_m=None if final_xy is None else float(np.hypot(*final_xy)),
        final_error_x_m=None if final_xy is None else float(abs(final_xy[0])),
        final_error_y_m=None if final_xy is None else float(abs(final_xy[1])),
        final_rot_err_rad=final_rot,
        rel_err_pct=float(np.mean(np.concatenate(list(segments.values())))) if segments else None,
        drift_pct=drift, path_length_m=length, n_poses=int(len(t_ns)), align=align, rotation=r, translation_m=t,
        pairs=pair_errors(est, truth, t_ns, known), heading_known=known, segment_errors_pct=segments,
        first_pose=k0 or 0, n_in_truth_gaps=int(np.count_nonzero(in_gap)),
    )


@dataclass
class TwistErrors:
    """Estimated speed and yaw rate against the truth's, at the estimate's times. The yaw
    rate is scored only where the truth heading is known at both ends of the window
    (``yaw_known``); elsewhere the truth speed is unsigned (its sign taken from the estimate)."""

    t_ns: np.ndarray
    speed_err_mps: np.ndarray  # estimate - truth
    yaw_rate_err_dps: np.ndarray  # at t_ns[yaw_known]
    truth_speed_mps: np.ndarray
    truth_yaw_rate_dps: np.ndarray  # at t_ns[yaw_known]
    window_s: float
    yaw_known: np.ndarray

    def figures(self) -> dict[str, float | int | None]:
        v, w = self.speed_err_mps, self.yaw_rate_err_dps
        has_w = len(w) > 0
        return {"speed_err_mean_mps": float(np.mean(v)), "speed_err_std_mps": float(np.std(v)),
                "speed_err_abs_median_mps": float(np.median(np.abs(v))),
                "yaw_rate_err_mean_dps": float(np.mean(w)) if has_w else None,
                "yaw_rate_err_std_dps": float(np.std(w)) if has_w else None,
                "yaw_rate_err_abs_median_dps": float(np.median(np.abs(w))) if has_w else None,
                "twist_n": int(len(v)), "twist_yaw_rate_n": int(len(w)),
                "twist_heading_unknown": int(len(v) - len(w)), "twist_window_s": self.window_s}


def twist_errors(t_ns: np.ndarray, speed_mps: np.ndarray, yaw_rate_radps: np.ndarray, truth_t_ns: np.ndarray,
                 truth_xyt: np.ndarray, window_s: float = 1.0,
                 truth_heading_known: np.ndarray | None = None) -> TwistErrors:
    """Errors of estimated (speed, yaw rate) against the truth's central differences over
    ``window_s`` centred on each estimate (the truth interpolated at both ends): the mean
    velocity over the window, which a two-turn estimate also measures; the noise of a 2 cm
    RTK fix stays below 0.03 m/s over 1 s. Estimates whose window leaves the truth's span
    or overlaps one of its gaps (:func:`gap_spans_ns`) are left out. Where the truth heading
    is unknown at either end (``truth_heading_known`` per truth sample, None: known
    everywhere) the yaw rate is not scored and the true speed is the displacement's length
    with the estimate's sign."""
    t_ns = np.asarray(t_ns, np.int64)
    h = int(round(0.5 * window_s * 1e9))
    inside = (t_ns - h >= truth_t_ns[0]) & (t_ns + h <= truth_t_ns[-1])
    inside &= ~in_spans(t_ns, gap_spans_ns(truth_t_ns), h)  # no truth across a gap
    t_ns = t_ns[inside]
    a, _ = interpolate_truth(t_ns - h, truth_t_ns, truth_xyt)
    b, _ = interpolate_truth(t_ns + h, truth_t_ns, truth_xyt)
    known = (heading_known_at(t_ns - h, truth_t_ns, truth_heading_known)
             & heading_known_at(t_ns + h, truth_t_ns, truth_heading_known))
    d = b - a
    mid = a[:, 2] + 0.5 * wrap_angle(d[:, 2])
    v = np.asarray(speed_mps, float)[inside]
    w = np.asarray(yaw_rate_radps, float)[inside]
    # signed speed: the displacement along the mean heading; unsigned where that is unknown
    v_true = np.where(known, np.cos(mid) * d[:, 0] + np.sin(mid) * d[:, 1],
                      np.copysign(np.hypot(d[:, 0], d[:, 1]), v)) / window_s
    w_true = wrap_angle(d[known, 2]) / window_s
    return TwistErrors(t_ns, v - v_true, np.degrees(w[known] - w_true), v_true, np.degrees(w_true),
                       float(window_s), known)
