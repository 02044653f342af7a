"""``slam.PoseGraph``: the smoothing back-end of seed 2 §VII on GTSAM (``gtsam`` from PyPI).

Any front end feeds it ``RelativePose2D`` constraints (``slam.EkfSlam``'s ``constraints``,
``slam.FmtRegistration``'s ``transform``...): each pose is a node named by its time; each
constraint a ``BetweenFactorPose2`` with the constraint's own covariance; the first node
is anchored at (0, 0, 0) by a tight prior (the map frame is the first pose, like the EKF's).
A new node's initial value is the estimate of the node it is constrained to, composed with
the constraint (dead reckoning along the odometry).

- ``solver: isam2``: incremental smoothing (the square-root SAM lineage of the seed's [8]):
  ``gtsam.ISAM2`` updated once per batch of constraints of one time, relinearised as it goes
  (extra updates after a loop closure so the whole trajectory settles). Emits ``trajectory``
  every ``trajectory_period_s`` and at the end, and ``pose`` (the newest node) per update.
- ``solver: lm``: batch Levenberg-Marquardt over the whole graph at the end of the mission
  from the dead-reckoned initial values; ``trajectory`` is emitted after every LM iteration
  (iteration 0 = the initial values): the seed's error and convergence per iteration.

``kernel`` (``huber`` or ``cauchy``, threshold ``kernel_k`` on the whitened error) wraps the
factors of the ``robust_kinds`` (loop closures by default) in a robust noise model so a
false loop closure is down-weighted instead of bending the trajectory. ``kinds`` selects
the constraints used; ``loop_rejected`` (candidates an EKF gate refused) is left out by
default and can be fed in to show what the kernel does with them. At the end each loop
factor's whitened error is checked (chi^2, 3 dof, 99 %): ``loop_outliers`` counts those
the solution does not satisfy (the kernel has down-weighted them).
"""

from __future__ import annotations

import math
import time
from typing import Any

import gtsam
import numpy as np

from impala_flow.msgs import RelativePose2D

__all__ = ["PoseGraphCore"]


class PoseGraphCore:
    """Nodes keyed by time, factors kept for the batch solve and the checks."""

    def __init__(self, solver: str = "isam2", kernel: str = "none", kernel_k: float = 2.0,
                 robust_kinds: tuple[str, ...] = ("loop", "loop_rejected"),
                 relinearize_threshold: float = 0.01) -> None:
        self.solver = solver
        self.kernel = kernel
        self.kernel_k = kernel_k
        self.robust_kinds = set(robust_kinds)
        self.keys: dict[int, int] = {}  # t_ns -> node key
        self.t_ns: list[int] = []
        self.initial = gtsam.Values()
        self.estimate: dict[int, gtsam.Pose2] = {}  # key -> latest estimate (iSAM2) / initial (LM)
        self.factors: list[tuple[int, int, np.ndarray, np.ndarray, str]] = []
        self.graph = gtsam.NonlinearFactorGraph()  # every factor (LM at the end)
        self._pending = gtsam.NonlinearFactorGraph()
        self._pending_values = gtsam.Values()
        self.orphans = 0
        self.solve_s = 0.0
        self.isam: Any = None
        if solver == "isam2":
            p = gtsam.ISAM2Params()
            p.setRelinearizeThreshold(relinearize_threshold)
            p.relinearizeSkip = 1
            self.isam = gtsam.ISAM2(p)

    def _noise(self, cov: np.ndarray, kind: str) -> Any:
        cov = 0.5 * (cov + cov.T) + np.eye(3) * 1e-12
        base = gtsam.noiseModel.Gaussian.Covariance(cov)
        if self.kernel == "none" or kind not in self.robust_kinds:
            return base
        m = (gtsam.noiseModel.mEstimator.Huber.Create(self.kernel_k) if self.kernel == "huber"
             else gtsam.noiseModel.mEstimator.Cauchy.Create(self.kernel_k))
        return gtsam.noiseModel.Robust.Create(m, base)

    def _new_node(self, t_ns: int, pose: gtsam.Pose2) -> int:
        k = len(self.t_ns)
        self.keys[t_ns] = k
        self.t_ns.append(t_ns)
        self.initial.insert(k, pose)
        self._pending_values.insert(k, pose)
        self.estimate[k] = pose
        return k

    def add(self, c: RelativePose2D) -> bool:
        """Add one constraint (and the node it introduces); False if it joins no known node."""
        if not self.keys:
            k0 = self._new_node(c.from_t_ns, gtsam.Pose2(0.0, 0.0, 0.0))
            prior = gtsam.PriorFactorPose2(k0, gtsam.Pose2(0.0, 0.0, 0.0),
                                           gtsam.noiseModel.Diagonal.Sigmas(np.array([1e-6, 1e-6, 1e-8])))
            self.graph.add(prior)
            self._pending.add(prior)
        if c.from_t_ns == c.to_t_ns:
            return True
        z = gtsam.Pose2(c.x_m, c.y_m, c.theta_rad)
        i, j = self.keys.get(c.from_t_ns), self.keys.get(c.to_t_ns)
        if i is None and j is None:
            self.orphans += 1
            return False
        if j is None:
            j = self._new_node(c.to_t_ns, self.estimate[i].compose(z))
        elif i is None:
            i = self._new_node(c.from_t_ns, self.estimate[j].compose(z.inverse()))
        cov = np.asarray(c.cov_xyt, float)
        f = gtsam.BetweenFactorPose2(i, j, z, self._noise(cov, c.kind))
        self.graph.add(f)
        self._pending.add(f)
        self.factors.append((i, j, np.array([c.x_m, c.y_m, c.theta_rad]), cov, c.kind))
        return True

    def update_isam(self, extra: int = 0) -> None:
        if self.isam is None or (self._pending.size() == 0 and self._pending_values.size() == 0):
            return
        t0 = time.perf_counter()
        self.isam.update(self._pending, self._pending_values)
        for _ in range(extra):
            self.isam.update()
        self._pending = gtsam.NonlinearFactorGraph()
        self._pending_values = gtsam.Values()
        est = self.isam.calculateEstimate()
        self.estimate = {k: est.atPose2(k) for k in range(len(self.t_ns))}
        self.solve_s += time.perf_counter() - t0

    def values_array(self, values: gtsam.Values) -> np.ndarray:
        return np.array([[values.atPose2(k).x(), values.atPose2(k).y(), values.atPose2(k).theta()]
                         for k in range(len(self.t_ns))]).reshape(-1, 3)

    def current(self) -> np.ndarray:
        return np.array([[p.x(), p.y(), p.theta()] for p in (self.estimate[k] for k in range(len(self.t_ns)))]
                        ).reshape(-1, 3)

    def lm_iterations(self, max_iterations: int = 100, rel_tol: float = 1e-6) -> list[np.ndarray]:
        """Batch Levenberg-Marquardt from the initial values: the poses after each iteration."""
        t0 = time.perf_counter()
        params = gtsam.LevenbergMarquardtParams()
        params.setRelativeErrorTol(rel_tol)
        params.setMaxIterations(max_iterations)
        opt = gtsam.LevenbergMarquardtOptimizer(self.graph, self.initial, params)
        out = [self.values_array(self.initial)]
        err = opt.error()
        for _ in range(max_iterations):
            opt.iterate()
            out.append(self.values_array(opt.values()))
            new = opt.error()
            if not math.isfinite(new) or abs(err - new) <= rel_tol * max(err, 1e-12):
                break
            err = new
        self.estimate = {k: opt.values().atPose2(k) for k in range(len(self.t_ns))}
        self.solve_s += time.perf_counter() - t0
        return out

    def loop_chi2(self) -> list[tuple[str, float]]:
        """(kind, Mahalanobis chi^2 of the residual) of every loop factor at the current estimate."""
        out = []
        for i, j, z, cov, kind in self.factors:
            if not kind.startswith("loop"):
                continue
            pred = self.estimate[i].between(self.estimate[j])
            r = np.array([pred.x() - z[0], pred.y() - z[1], math.remainder(pred.theta() - z[2], 2 * math.pi)])
            out.append((kind, float(r @ np.linalg.solve(cov, r))))
        return out
