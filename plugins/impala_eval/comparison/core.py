"""``eval.TrajectoryComparison``: several SLAM back-ends side by side against the truth, as in
seed 2 (Gérossier et al., trajectory-oriented EKF-SLAM with the Fourier-Mellin transform),
Figs. 8 and 9.

Each estimate arrives on its own input (one per name in ``estimates``) as ``Trajectory2D``
samples: one sample = one iteration (the EKF and iSAM2 every period, the batch LM after
each of its runs), a whole trajectory re-estimated each time, the last one the final
estimate; or, for the names also in ``poses``, as ``Pose2D`` samples (an odometry, R-SLAM's
pose): the whole stream is then the final trajectory (one iteration). The truth (``truth``,
RTK-GPS) is interpolated at each pose's time; poses outside its span are dropped and
counted. Everything is computed at stop() (truth stamped later than a trajectory may arrive
after it). The report folder (``report``) holds:

- ``trajectories.png`` (Fig. 8): the final trajectories with the truth and the ``baseline``
  (dead reckoning), over the radar map of the optional ``map`` input (Figs. 5 and 7), which
  lies in the first estimate's frame and is moved by that estimate's alignment;
- ``convergence.png`` (Fig. 9): (a) the average position error of each iteration's poses
  against the truth; (b) the rate of convergence: the mean distance between each
  iteration's poses and the final estimate's poses of the same times (0 at the last one);
  (c) the final estimates' position error along the distance travelled;
- ``metrics.json`` (what :meth:`TrajectoryComparison.summary` returns) and ``report.md``
  (a table, the figures). Per estimate ``N``: ``N_ate_rmse_m``, ``N_ate_pct`` (of the
  truth's path over the final trajectory's span), ``N_final_err_m``, ``N_mean_err_m``,
  ``N_max_err_m``, ``N_iterations``, ``N_poses``, ``N_poses_outside_truth``,
  ``N_end_to_end_err_m`` (the last pose seen from the first against the truth's: no
  alignment, the drift a loop closure removes), ``N_poses_in_truth_gaps`` (left out: inside
  a gap of the truth, see ``metrics.gap_spans_ns``); ``path_length_m`` (the longest final
  trajectory's); the baseline's ``baseline_ate_rmse_m``, ``baseline_final_err_m``,
  ``baseline_mean_err_m``, ``baseline_max_err_m``, ``baseline_end_to_end_err_m``,
  ``baseline_ate_pct``, ``baseline_poses``, ``baseline_poses_outside_truth``. An estimate
  that received nothing is left out.

The per-iteration curves keep every sample's times and positions until stop(); beyond
``MAX_ROWS`` poses in all (5e6, shared equally by the estimates) an estimate keeps every
2nd, 4th, ... iteration and its last one, and report.md says so.

``align``: ``first`` (the seed's: truth and estimate made to coincide, position and heading,
at the first estimated pose's time) or ``rigid`` (least squares on the final trajectory's
positions, rotation and translation). Either transform is computed once per estimate, on
its final trajectory, and used for all its iterations; the estimates are moved into the
truth's frame (the errors are those of the truth moved onto the estimate).

Truth from a GPS: repeated time stamps count once (the first kept); a truth pose whose
heading is unknown (``Pose2D.heading_known``, at rest) is used for its position only: ``first``
aligns on the first final pose whose truth heading is known (an estimate with none is left
out, with a one-line warning) and the end-to-end error starts there.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from impala_flow.msgs import Trajectory2D

from ..metrics import (
    interpolate_truth,
)

#: poses kept for the per-iteration curves, over all iterations of all estimates (shared equally)
MAX_ROWS = 5_000_000


BATCH_ROWS = 1 << 20  # poses interpolated at once for the per-iteration curves


def sorted_by_time(t_ns: np.ndarray, xyt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    if len(t_ns) > 1 and np.any(np.diff(t_ns) < 0):
        order = np.argsort(t_ns, kind="stable")
        return t_ns[order], xyt[order]
    return t_ns, xyt


@dataclass
class Iterations:
    """The samples of one estimate: every one counted, the latest whole, the rest kept (their
    times and positions) for the per-iteration curves, evenly thinned beyond ``budget`` poses."""

    budget: int = MAX_ROWS
    received: int = 0
    stride: int = 1  # every stride-th iteration is kept (1, 1 + stride, ...)
    rows: int = 0
    kept: list[tuple[int, np.ndarray, np.ndarray]] = field(default_factory=list)  # (iteration, t_ns, xy)
    final: tuple[int, np.ndarray, np.ndarray] | None = None  # (iteration, t_ns, xyt)

    def add(self, traj: Trajectory2D) -> bool:
        """Store one sample; True when this one made the store thin its iterations."""
        self.received += 1
        t_ns = np.asarray(traj.t_ns, np.int64).reshape(-1)
        xyt = np.asarray(traj.xyt, np.float64).reshape(-1, 3)
        if len(t_ns) != len(xyt):
            raise ValueError(f"Trajectory2D with {len(t_ns)} times and {len(xyt)} poses")
        if len(t_ns) == 0:  # counted as an iteration, nothing to score
            return False
        t_ns, xyt = sorted_by_time(t_ns, xyt)
        self.final = (self.received, t_ns, xyt)
        if (self.received - 1) % self.stride:
            return False
        self.kept.append((self.received, t_ns, np.ascontiguousarray(xyt[:, :2])))
        self.rows += len(t_ns)
        thinned = False
        while self.rows > self.budget and len(self.kept) > 1:
            self.kept = self.kept[::2]
            self.stride *= 2
            self.rows = sum(len(k[1]) for k in self.kept)
            thinned = True
        return thinned

    def iterations(self) -> list[tuple[int, np.ndarray, np.ndarray]]:
        """The kept iterations, the final one last (kept even when the stride skipped it)."""
        assert self.final is not None
        k, t_ns, xyt = self.final
        if self.kept and self.kept[-1][0] == k:
            return self.kept
        return [*self.kept, (k, t_ns, xyt[:, :2])]


def iteration_curves(its: list[tuple[int, np.ndarray, np.ndarray]], r: np.ndarray, tr: np.ndarray,
                      t_final: np.ndarray, xy_final: np.ndarray, truth_t_ns: np.ndarray,
                      truth_xyt: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per iteration (seed 2, Fig. 9): (a) the mean position error of its poses against the
    truth after the estimate's alignment (r, tr); (b) the mean distance between its poses
    and the final estimate's poses of the same t_ns (others ignored). NaN: nothing to
    average. Vectorised over batches of iterations."""
    n = len(its)
    sums = np.zeros((4, n))  # error sum, error count, distance sum, distance count
    lo = 0
    while lo < n:
        hi, rows = lo, 0
        while hi < n and (hi == lo or rows + len(its[hi][1]) <= BATCH_ROWS):
            rows += len(its[hi][1])
            hi += 1
        t_ns = np.concatenate([it[1] for it in its[lo:hi]])
        xy = np.concatenate([it[2] for it in its[lo:hi]])
        which = np.repeat(np.arange(lo, hi), [len(it[1]) for it in its[lo:hi]])
        truth, inside = interpolate_truth(t_ns, truth_t_ns, truth_xyt)
        err = np.hypot(*(xy[inside] @ r.T + tr - truth[inside, :2]).T)
        sums[0] += np.bincount(which[inside], err, minlength=n)
        sums[1] += np.bincount(which[inside], minlength=n)
        j = np.minimum(np.searchsorted(t_final, t_ns), len(t_final) - 1)
        same = t_final[j] == t_ns
        dist = np.hypot(*(xy[same] - xy_final[j[same]]).T)
        sums[2] += np.bincount(which[same], dist, minlength=n)
        sums[3] += np.bincount(which[same], minlength=n)
        lo = hi
    avg_err = np.divide(sums[0], sums[1], out=np.full(n, np.nan), where=sums[1] > 0)
    conv = np.divide(sums[2], sums[3], out=np.full(n, np.nan), where=sums[3] > 0)
    return avg_err, conv
