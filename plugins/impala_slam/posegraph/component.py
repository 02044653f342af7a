"""``slam.PoseGraph``: the component (ports, parameters, sample handling). The algorithm, and
what it follows, is described in :mod:`impala_slam.posegraph.core`.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from impala_flow import Component, Input, Output, Param, Periodic
from impala_flow.msgs import Pose2D, RelativePose2D, Trajectory2D

__all__ = ["PoseGraph"]


CHI2_3DOF_99 = 11.34


class PoseGraph(Component):
    """Pose-graph smoothing of relative-pose constraints with GTSAM (iSAM2 or batch LM)."""

    constraints = Input(RelativePose2D, maxsize=1 << 16, doc="relative poses between nodes named by their times")
    trajectory = Output(Trajectory2D, doc="every node's estimate (iSAM2: periodically and at the end; "
                                          "LM: after each iteration at the end)")
    pose = Output(Pose2D, doc="the newest node's estimate after each iSAM2 update")
    trajectory_timer = Periodic("trajectory_period_s")

    solver = Param(str, default="isam2", choices=("isam2", "lm"), doc="incremental iSAM2 or batch Levenberg-Marquardt")
    kernel = Param(str, default="cauchy", choices=("none", "huber", "cauchy"),
                   doc="robust kernel on the factors of robust_kinds")
    kernel_k = Param(float, default=2.0, gt=0, doc="kernel threshold on the whitened error")
    kinds = Param(list, default=["odometry", "registration", "loop"],
                  doc="constraint kinds used (add loop_rejected to see the kernel at work)")
    robust_kinds = Param(list, default=["loop", "loop_rejected"], doc="kinds wrapped in the robust kernel")
    trajectory_period_s = Param(float, default=10.0, gt=0, doc="period of the trajectory output (iSAM2)")
    lm_max_iterations = Param(int, default=100, ge=1, doc="LM iterations at most")
    loop_extra_updates = Param(int, default=3, ge=0, doc="extra iSAM2 updates after a loop closure")

    def start(self) -> None:
        from .core import PoseGraphCore  # here, not at import: gtsam costs 0.2 s to import, paid by every command

        self.core = PoseGraphCore(self.solver, self.kernel, self.kernel_k, tuple(self.robust_kinds))
        self.used: dict[str, int] = {}
        self.ignored: dict[str, int] = {}
        self._batch_t: int | None = None
        self._loop_in_batch = False
        self.lm_iterations_done = 0

    def process(self, t: int) -> None:
        core = self.core
        if self.trigger == "trajectory_timer":
            if self.solver == "isam2" and core.t_ns:
                self._flush_batch()
                self.trajectory.emit(t, Trajectory2D(np.array(core.t_ns, np.int64), core.current(), "map"))
            return
        c: RelativePose2D = self.constraints.take()
        if self._batch_t is not None and t != self._batch_t:
            self._flush_batch()
        self._batch_t = t
        if c.kind not in self.kinds and c.kind != "start":
            self.ignored[c.kind] = self.ignored.get(c.kind, 0) + 1
            return
        cov = np.asarray(c.cov_xyt, float)
        if c.from_t_ns != c.to_t_ns and (cov.shape != (3, 3) or not np.all(np.isfinite(cov))
                                          or np.any(np.linalg.eigvalsh(0.5 * (cov + cov.T)) <= 0)):
            self.ignored["bad_covariance"] = self.ignored.get("bad_covariance", 0) + 1
            self.log.warning("constraint %s %d -> %d at t=%d ns has no valid covariance: ignored",
                             c.kind, c.from_t_ns, c.to_t_ns, t)
            return
        if core.add(c):
            self.used[c.kind] = self.used.get(c.kind, 0) + 1
            self._loop_in_batch |= c.kind.startswith("loop")

    def _flush_batch(self) -> None:
        if self.solver != "isam2" or self._batch_t is None:
            return
        core = self.core
        had = core._pending.size() > 0
        core.update_isam(self.loop_extra_updates if self._loop_in_batch else 0)
        self._loop_in_batch = False
        if had and core.t_ns:
            p = core.estimate[len(core.t_ns) - 1]
            self.pose.emit(self._batch_t, Pose2D(p.x(), p.y(), p.theta(), np.zeros((0, 0)), "map"))

    def flush(self, t: int) -> None:
        core = self.core
        if not core.t_ns:
            return
        t_ns = np.array(core.t_ns, np.int64)
        if self.solver == "isam2":
            self._flush_batch()
            self.trajectory.emit(t, Trajectory2D(t_ns, core.current(), "map"))
            return
        its = core.lm_iterations(self.lm_max_iterations)
        self.lm_iterations_done = len(its) - 1
        for xyt in its:
            self.trajectory.emit(t, Trajectory2D(t_ns, xyt, "map"))

    def summary(self) -> dict:
        core = getattr(self, "core", None)
        if core is None or not core.t_ns:
            return {}
        loops = core.loop_chi2()
        out: dict[str, Any] = {"nodes": len(core.t_ns), "factors": len(core.factors),
                               **{f"used_{k}": v for k, v in sorted(self.used.items())},
                               **{f"ignored_{k}": v for k, v in sorted(self.ignored.items())},
                               "orphans": core.orphans, "loop_factors": len(loops),
                               "loop_outliers": sum(1 for _, c in loops if c > CHI2_3DOF_99),
                               "solve_ms": round(1e3 * core.solve_s, 1)}
        if self.solver == "lm":
            out["lm_iterations"] = self.lm_iterations_done
        return out
