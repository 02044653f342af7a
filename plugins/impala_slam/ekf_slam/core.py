"""Trajectory-oriented EKF-SLAM (seed 2, §IV): the state is every pose of the trajectory.

:class:`PoseEkf` holds x = [x_v1, ..., x_vn] (3 n) and its full covariance P (3n x 3n).

- **Augmentation** (the seed's eq. of §IV-B): a new pose x_{n+1} = x_n (+) u with the
  odometry increment u (covariance Q); P grows by one block row/column,
  P_{n+1,:} = J_x P_{n,:}, P_{n+1,n+1} = J_x P_nn J_x^T + J_u Q J_u^T.
- **Observation** T_ij = (-)((-)x_j (+) x_i) (the seed's h, written as the pose of j in
  the frame of i: the same transform read the other way round), from the Fourier-Mellin
  registration of scans i and j, covariance R; classical EKF update. H has two non-zero
  3x3 blocks, so P H^T is two column blocks of P and the update is a rank-3 correction of
  the whole P: that is the O(n^2) cost per step the bench measures.
- **Gates**: :meth:`PoseEkf.relative` gives the predicted relative pose of any pose
  against the newest and its covariance, for all of them at once (loop-closure candidates),
  and :meth:`PoseEkf.update` returns the innovation's chi^2 so the caller decides.

P lives in a pre-allocated square array that doubles when full (no copy per step). The
update is applied in row blocks so no n x n temporary is allocated. Memory is the limit:
3n x 3n doubles, 72 MB at 1 000 poses and 300 MB of capacity once past 1 024; for missions
of thousands of poses the pose graph (``slam.PoseGraph``) is the tool, the EKF the seed's
baseline (bench/fmt_ekf.py: 7.6 ms per step at 1 000 poses on one core).
"""

from __future__ import annotations

import math

import numpy as np

from ..se2 import between, compose, wrap

__all__ = ["PoseEkf", "between_jacobians", "compose_jacobians"]

Pose = tuple[float, float, float]


def compose_jacobians(a: Pose, u: Pose) -> tuple[np.ndarray, np.ndarray]:
    """d(a (+) u)/da and d(a (+) u)/du."""
    c, s = math.cos(a[2]), math.sin(a[2])
    ja = np.array([[1.0, 0.0, -s * u[0] - c * u[1]], [0.0, 1.0, c * u[0] - s * u[1]], [0.0, 0.0, 1.0]])
    ju = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return ja, ju


def between_jacobians(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """d((-)a (+) b)/da and /db, vectorised over rows of a and b (k x 3) -> (k x 3 x 3) each."""
    a = np.atleast_2d(a)
    b = np.atleast_2d(b)
    c, s = np.cos(a[:, 2]), np.sin(a[:, 2])
    dx, dy = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    k = len(a)
    ja = np.zeros((k, 3, 3))
    jb = np.zeros((k, 3, 3))
    ja[:, 0, 0], ja[:, 0, 1], ja[:, 0, 2] = -c, -s, -s * dx + c * dy
    ja[:, 1, 0], ja[:, 1, 1], ja[:, 1, 2] = s, -c, -c * dx - s * dy
    ja[:, 2, 2] = -1.0
    jb[:, 0, 0], jb[:, 0, 1] = c, s
    jb[:, 1, 0], jb[:, 1, 1] = -s, c
    jb[:, 2, 2] = 1.0
    return ja, jb


class PoseEkf:
    """Mean and covariance of every pose (see the module docstring)."""

    def __init__(self, first: Pose = (0.0, 0.0, 0.0), first_cov: np.ndarray | None = None,
                 capacity: int = 256) -> None:
        self._x = np.zeros(3 * capacity)
        self._p = np.zeros((3 * capacity, 3 * capacity))
        self.n = 1
        self._x[:3] = first
        if first_cov is not None:
            self._p[:3, :3] = first_cov

    # --- views -----------------------------------------------------------------------
    @property
    def x(self) -> np.ndarray:
        """n x 3 poses (a view: do not modify)."""
        return self._x[: 3 * self.n].reshape(self.n, 3)

    @property
    def p(self) -> np.ndarray:
        return self._p[: 3 * self.n, : 3 * self.n]

    def pose(self, i: int) -> Pose:
        x = self._x[3 * i: 3 * i + 3]
        return float(x[0]), float(x[1]), float(x[2])

    def cov(self, i: int) -> np.ndarray:
        return self._p[3 * i: 3 * i + 3, 3 * i: 3 * i + 3].copy()

    def _grow(self) -> None:
        cap = self._x.size // 3
        if self.n < cap:
            return
        m = 3 * self.n
        x = np.zeros(6 * cap)
        p = np.zeros((6 * cap, 6 * cap))
        x[:m] = self._x[:m]
        p[:m, :m] = self._p[:m, :m]
        self._x, self._p = x, p

    # --- augmentation ------------------------------------------------------------------
    def augment(self, u: Pose, q: np.ndarray) -> int:
        """Add x_{n+1} = x_n (+) u (u's covariance q); return the new pose's index."""
        self._grow()
        last = self.n - 1
        a = self.pose(last)
        ja, ju = compose_jacobians(a, u)
        m = 3 * self.n
        i0 = 3 * last
        new = m
        self._x[new: new + 3] = compose(a, u)
        rows = ja @ self._p[i0: i0 + 3, :m]  # J_x P_{n,:}
        self._p[new: new + 3, :m] = rows
        self._p[:m, new: new + 3] = rows.T
        self._p[new: new + 3, new: new + 3] = ja @ self._p[i0: i0 + 3, i0: i0 + 3] @ ja.T + ju @ q @ ju.T
        self.n += 1
        return self.n - 1

    # --- observation ---------------------------------------------------------------------
    def relative(self, idx: np.ndarray, j: int) -> tuple[np.ndarray, np.ndarray]:
        """Predicted T_ij (pose j in frame i) for each i of ``idx`` and its covariance (k x 3 x 3)."""
        idx = np.asarray(idx, int)
        xa = self.x[idx]
        xb = np.repeat(self.x[j][None, :], len(idx), axis=0)
        c, s = np.cos(xa[:, 2]), np.sin(xa[:, 2])
        dx, dy = xb[:, 0] - xa[:, 0], xb[:, 1] - xa[:, 1]
        z = np.column_stack([c * dx + s * dy, -s * dx + c * dy, wrap(xb[:, 2] - xa[:, 2])])
        ja, jb = between_jacobians(xa, xb)
        p = self._p
        r = (3 * idx[:, None] + np.arange(3)[None, :])  # k x 3 state indices
        jj = 3 * j + np.arange(3)
        p_ii = p[r[:, :, None], r[:, None, :]]
        p_ij = p[r[:, :, None], jj[None, None, :]]
        p_jj = p[np.ix_(jj, jj)]
        cov = (ja @ p_ii @ ja.transpose(0, 2, 1) + ja @ p_ij @ jb.transpose(0, 2, 1)
               + jb @ p_ij.transpose(0, 2, 1) @ ja.transpose(0, 2, 1) + jb @ p_jj @ jb.transpose(0, 2, 1))
        return z, cov

    def innovation(self, i: int, j: int, z: Pose, r: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        """(nu, S, nu^T S^-1 nu) of the observation z = T_ij with covariance r."""
        h, cov = self.relative(np.array([i]), j)
        nu = np.asarray(z, float) - h[0]
        nu[2] = wrap(nu[2])
        s = cov[0] + r
        return nu, s, float(nu @ np.linalg.solve(s, nu))

    def update(self, i: int, j: int, z: Pose, r: np.ndarray, block_rows: int = 512) -> float:
        """EKF update with T_ij = z (covariance r); returns the innovation's chi^2."""
        nu, s, chi2 = self.innovation(i, j, z, r)
        m = 3 * self.n
        ja, jb = between_jacobians(self.x[i][None, :], self.x[j][None, :])
        p = self._p
        pht = p[:m, 3 * i: 3 * i + 3] @ ja[0].T + p[:m, 3 * j: 3 * j + 3] @ jb[0].T  # P H^T (m x 3)
        k = np.linalg.solve(s, pht.T).T  # P H^T S^-1 (S symmetric)
        self._x[:m] += k @ nu
        xs = self._x[:m].reshape(-1, 3)
        xs[:, 2] = wrap(xs[:, 2])
        for r0 in range(0, m, block_rows):  # P -= K (P H^T)^T, in row blocks: no m x m temporary
            r1 = min(m, r0 + block_rows)
            p[r0:r1, :m] -= k[r0:r1] @ pht.T
        return chi2

    def relative_pose(self, i: int, j: int) -> Pose:
        return between(self.pose(i), self.pose(j))

