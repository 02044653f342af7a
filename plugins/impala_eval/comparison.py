"""``eval.TrajectoryComparison``: several SLAM back-ends side by side against the truth, as in
seed 2 §VII (Figs. 8 and 9).

Each estimate arrives on its own input (named by ``estimates``) as ``Trajectory2D`` samples:
one sample = one iteration (the EKF and iSAM2 every turn or period, batch LM after each of
its iterations), the last one the final estimate. At the end:

- Fig. 8 (``trajectories.png``): the final trajectories with the truth (and the baseline),
  over the radar map of the optional ``map`` input (the seed's Figs. 5 and 7), which lies in
  the first estimate's frame and is moved by that estimate's alignment;
- Fig. 9 (``convergence.png``): (a) the average position error of each iteration's poses
  against the truth; (b) the rate of convergence: the mean distance between each
  iteration's poses and the final estimate of the same poses (0 at the last one); (c) the
  final estimate's position error along the path;
- ``metrics.json`` / ``report.md``: per estimate ``N_ate_rmse_m``, ``N_ate_pct`` (of the
  truth's path length), ``N_final_err_m``, ``N_mean_err_m``, ``N_max_err_m``,
  ``N_iterations``, ``N_poses``, ``N_poses_outside_truth``, ``N_end_to_end_err_m`` (the last
  pose seen from the first against the truth's: no alignment, the drift a loop closure
  removes); ``path_length_m``; the baseline's
  ``baseline_ate_rmse_m`` and ``baseline_final_err_m``.

``align``: ``first`` (the seed's: the truth moved so its pose at the first estimated pose's
time coincides with it) or ``rigid`` (least squares on the final trajectory's positions,
the same transform applied to every iteration of that estimate).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from impala_flow.component import Component, Input, Output, Param
from impala_flow.msgs import Grid, Pose2D, Trajectory2D

from .metrics import align_first, apply_rigid, distance_travelled_m, interpolate_truth, path_length_m, rigid_align_2d
from .report import _figure, _show_map

__all__ = ["TrajectoryComparison"]

_COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b"]
_MAX_ROWS = 5_000_000


def _rel(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Position of pose b in the frame of pose a."""
    c, s = np.cos(a[2]), np.sin(a[2])
    d = b[:2] - a[:2]
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])


class TrajectoryComparison(Component):
    """Final trajectories and per-iteration errors of several estimates (seed 2, Figs. 8-9)."""

    truth = Input(Pose2D, maxsize=1 << 20, doc="reference poses (RTK-GPS, simulator truth)")
    baseline = Input(Pose2D, maxsize=1 << 20, required=False, doc="a pose stream drawn beside (dead reckoning)")
    map = Input(Grid, policy="sampling", required=False,
                doc="a radar map in the frame of the first estimate (dB), drawn under Fig. 8")

    estimates = Param(list, default=["ekf", "isam2", "lm"], doc="one Trajectory2D input per name")
    titles = Param(list, default=[], doc="names in the figures (default: the input names)")
    report = Param(str, default="", path="write_dir", doc="report folder ('' = metrics only, no files)")
    align = Param(str, default="first", choices=("first", "rigid"), doc="alignment before the errors")
    title = Param(str, default="SLAM back-ends", doc="title of the report")
    baseline_title = Param(str, default="dead reckoning", doc="name of the baseline")

    @classmethod
    def declare_ports(cls, params: dict[str, Any]) -> tuple[dict[str, Input], dict[str, Output]]:
        names = params.get("estimates", ["ekf", "isam2", "lm"])
        titles = params.get("titles", [])
        for n in names:
            if not isinstance(n, str) or not n.isidentifier() or n in ("truth", "baseline"):
                raise ValueError(f"parameter 'estimates': {n!r} is not a valid input name "
                                 "(an identifier other than truth/baseline)")
        if titles and len(titles) != len(names):
            raise ValueError(f"parameter 'titles': {len(titles)} titles for {len(names)} estimates")
        ins = dict(cls.__inputs__)
        for n in names:
            ins[n] = Input(Trajectory2D, maxsize=1 << 16, required=False, doc=f"iterations of estimate {n}")
        return ins, {}

    def start(self) -> None:
        self.samples: dict[str, list[Trajectory2D]] = {n: [] for n in self.estimates}
        self.truth_t: list[int] = []
        self.truth_xyt: list[tuple[float, float, float]] = []
        self.base_t: list[int] = []
        self.base_xyt: list[tuple[float, float, float]] = []
        self.figures: dict[str, Any] = {}
        self._done = False

    def process(self, t: int) -> None:
        s = self.inputs[self.trigger].take_sample()
        d = s.data
        if self.trigger == "truth":
            self.truth_t.append(s.timestamp)
            self.truth_xyt.append((d.x_m, d.y_m, d.theta_rad))
        elif self.trigger == "baseline":
            self.base_t.append(s.timestamp)
            self.base_xyt.append((d.x_m, d.y_m, d.theta_rad))
        elif self.trigger in self.samples:
            self.samples[self.trigger].append(d)

    # --- metrics ----------------------------------------------------------------------
    def _transform(self, t_ns: np.ndarray, xyt: np.ndarray, tt: np.ndarray, tx: np.ndarray):
        truth, inside = interpolate_truth(t_ns, tt, tx)
        if self.align == "first":
            return align_first(xyt[inside][:1], truth[inside][:1]), inside, truth
        return rigid_align_2d(xyt[inside, :2], truth[inside, :2]), inside, truth

    def compute(self) -> dict[str, Any]:
        if self._done:
            return self.figures
        self._done = True
        out: dict[str, Any] = {}
        self.curves: dict[str, dict[str, np.ndarray]] = {}
        self._map_transform: tuple[np.ndarray, np.ndarray] | None = None
        if len(self.truth_t) < 2:
            self.log.warning("fewer than two truth poses: nothing to compare")
            return out
        tt = np.asarray(self.truth_t, np.int64)
        tx = np.asarray(self.truth_xyt, float)
        span = 0.0
        for name in self.estimates:
            its = self.samples[name]
            if not its or len(its[-1].t_ns) == 0:
                self.log.info("estimate %s received nothing: left out", name)
                continue
            final = its[-1]
            t_f = np.asarray(final.t_ns, np.int64)
            x_f = np.asarray(final.xyt, float)
            (r, tr), inside, truth = self._transform(t_f, x_f, tt, tx)
            if not np.any(inside):
                self.log.warning("estimate %s lies outside the truth's time span", name)
                continue
            al = apply_rigid(r, tr, x_f[inside])
            if self._map_transform is None:  # the map lies in the first estimate's frame
                self._map_transform = (r, tr)
            err = np.hypot(*(al[:, :2] - truth[inside, :2]).T)
            path = path_length_m(truth[inside, :2])
            span = max(span, path)
            ate = float(np.sqrt(np.mean(err ** 2)))
            out.update({f"{name}_ate_rmse_m": round(ate, 4), f"{name}_final_err_m": round(float(err[-1]), 4),
                        f"{name}_mean_err_m": round(float(err.mean()), 4),
                        f"{name}_max_err_m": round(float(err.max()), 4),
                        f"{name}_iterations": len(its), f"{name}_poses": int(len(t_f)),
                        f"{name}_poses_outside_truth": int((~inside).sum())})
            if path > 0:
                out[f"{name}_ate_pct"] = round(100.0 * ate / path, 4)
            # alignment-free: the last pose seen from the first, against the truth's (loop drift)
            e0, e1, g0, g1 = x_f[inside][0], x_f[inside][-1], truth[inside][0], truth[inside][-1]
            out[f"{name}_end_to_end_err_m"] = round(float(np.hypot(*(_rel(e0, e1) - _rel(g0, g1)))), 4)
            # per iteration: (a) error vs truth, (b) distance to the final estimate
            keep = its if sum(len(s.t_ns) for s in its) <= _MAX_ROWS else \
                [its[i] for i in np.unique(np.linspace(0, len(its) - 1, 1000).astype(int))]
            final_of = dict(zip(t_f.tolist(), range(len(t_f)), strict=True))
            avg_err, conv = [], []
            for s in keep:
                t_s = np.asarray(s.t_ns, np.int64)
                x_s = np.asarray(s.xyt, float)
                tr_s, in_s = interpolate_truth(t_s, tt, tx)
                if np.any(in_s):
                    a = apply_rigid(r, tr, x_s[in_s])
                    avg_err.append(float(np.mean(np.hypot(*(a[:, :2] - tr_s[in_s, :2]).T))))
                else:
                    avg_err.append(np.nan)
                idx = np.array([final_of.get(int(v), -1) for v in t_s])
                m = idx >= 0
                conv.append(float(np.mean(np.hypot(*(x_s[m, :2] - x_f[idx[m], :2]).T))) if np.any(m) else np.nan)
            self.curves[name] = {"avg_err": np.array(avg_err), "conv": np.array(conv),
                                 "dist": distance_travelled_m(truth[inside, :2]), "err": err,
                                 "xy": al[:, :2], "subsampled": np.array(len(keep) < len(its))}
        if span > 0:
            out["path_length_m"] = round(span, 2)
        if len(self.base_t) >= 2:
            bt = np.asarray(self.base_t, np.int64)
            bx = np.asarray(self.base_xyt, float)
            (r, tr), inside, truth = self._transform(bt, bx, tt, tx)
            if np.any(inside):
                al = apply_rigid(r, tr, bx[inside])
                err = np.hypot(*(al[:, :2] - truth[inside, :2]).T)
                out["baseline_ate_rmse_m"] = round(float(np.sqrt(np.mean(err ** 2))), 4)
                out["baseline_final_err_m"] = round(float(err[-1]), 4)
                self.curves["_baseline"] = {"xy": al[:, :2]}
        self._truth_xy = tx[:, :2]
        self.figures = out
        return out

    # --- report -------------------------------------------------------------------------
    def _titles(self) -> dict[str, str]:
        return dict(zip(self.estimates, self.titles or self.estimates, strict=True))

    def write(self, folder: Path) -> None:
        folder.mkdir(parents=True, exist_ok=True)
        (folder / "metrics.json").write_text(json.dumps(self.figures, indent=2, sort_keys=True) + "\n")
        titles = self._titles()
        names = [n for n in self.estimates if n in self.curves]
        colour = {n: _COLOURS[i % len(_COLOURS)] for i, n in enumerate(self.estimates)}
        # Fig. 8
        fig = _figure(7.5, 6.5)
        ax = fig.add_subplot()
        radar_map = self.inputs["map"].latest()
        if radar_map is not None and self._map_transform is not None:
            _show_map(ax, radar_map.data, self._map_transform)  # the global map (seed 2, Figs. 5 and 7)
        ax.plot(*self._truth_xy.T, color="k", lw=0.8, label="truth (RTK-GPS)")
        if "_baseline" in self.curves:
            ax.plot(*self.curves["_baseline"]["xy"].T, "--", color="0.55", lw=1.0, label=self.baseline_title)
        for n in names:
            f = self.figures
            ax.plot(*self.curves[n]["xy"].T, color=colour[n], lw=1.4,
                    label=f"{titles[n]} (ATE {f[f'{n}_ate_rmse_m']:.2f} m, final {f[f'{n}_final_err_m']:.2f} m)")
        ax.plot(*self._truth_xy[0], "o", color="k", ms=6, label="start")
        ax.set(aspect="equal", xlabel="x (m)", ylabel="y (m)",
               title=f"{self.title}: final trajectories ({self.align} alignment)")
        ax.grid(alpha=0.3)
        ax.legend(loc="best", frameon=False, fontsize=8)
        fig.savefig(folder / "trajectories.png")
        # Fig. 9
        fig = _figure(8.0, 9.0)
        axes = fig.subplots(3, 1)
        for n in names:
            c = self.curves[n]
            it = np.arange(len(c["avg_err"]))
            ok = np.isfinite(c["avg_err"])
            axes[0].plot(it[ok], c["avg_err"][ok], color=colour[n], lw=1.2, label=titles[n])
            pos = np.isfinite(c["conv"]) & (c["conv"] > 0)
            axes[1].plot(it[pos], c["conv"][pos], color=colour[n], lw=1.2, label=titles[n])
            axes[2].plot(c["dist"], c["err"], color=colour[n], lw=1.2, label=titles[n])
        axes[0].set(xlabel="iteration", ylabel="average error (m)", title="(a) average error vs truth per iteration")
        axes[1].set(xlabel="iteration", ylabel="distance to final (m)",
                    title="(b) rate of convergence: mean distance to the final estimate")
        if any(line.get_ydata().size for line in axes[1].get_lines()):
            axes[1].set_yscale("log")
        axes[2].set(xlabel="distance travelled (m)", ylabel="position error (m)",
                    title="(c) error of the final estimates along the path")
        for a in axes:
            a.grid(alpha=0.3)
            if a.get_lines():
                a.legend(loc="best", frameon=False, fontsize=8)
        fig.savefig(folder / "convergence.png")
        rows = ["| estimate | ATE RMSE (m) | ATE (% of path) | final error (m) | end to end (m) | mean error (m) "
                "| iterations | poses |", "|---|---|---|---|---|---|---|---|"]
        f = self.figures
        for n in names:
            rows.append(f"| {titles[n]} | {f[f'{n}_ate_rmse_m']:.3f} | {f.get(f'{n}_ate_pct', float('nan')):.3f} | "
                        f"{f[f'{n}_final_err_m']:.3f} | {f[f'{n}_end_to_end_err_m']:.3f} | "
                        f"{f[f'{n}_mean_err_m']:.3f} | {f[f'{n}_iterations']} | {f[f'{n}_poses']} |")
        if "baseline_ate_rmse_m" in f:
            rows.append(f"| {self.baseline_title} | {f['baseline_ate_rmse_m']:.3f} | | {f['baseline_final_err_m']:.3f}"
                        " | | | | |")
        text = [f"# {self.title}", "", f"Truth path length: {f.get('path_length_m', 0):.1f} m; "
                f"{self.align} alignment.", "", *rows, "",
                "![final trajectories (seed 2, Fig. 8)](trajectories.png)", "",
                "![error and convergence per iteration (seed 2, Fig. 9)](convergence.png)", ""]
        (folder / "report.md").write_text("\n".join(text))

    def stop(self) -> None:
        if not hasattr(self, "samples"):
            return
        figures = self.compute()
        if self.report and figures:
            self.write(Path(self.report))

    def summary(self) -> dict:
        return dict(self.compute()) if hasattr(self, "samples") else {}
