"""``eval.TrajectoryComparison``: the component (ports, parameters, sample handling). The algorithm, and
what it follows, is described in :mod:`impala_eval.comparison.core`.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from impala_flow import Component, Input, Output, Param, ParamError
from impala_flow.msgs import Grid, Pose2D, Trajectory2D

from ..metrics import (
    align_first,
    apply_rigid,
    distance_travelled_m,
    gap_spans_ns,
    heading_known_at,
    in_spans,
    interpolate_truth,
    relative_position,
    rigid_align_2d,
)
from ..report import METRICS_FILE, new_figure, save_figure, show_map
from .core import MAX_ROWS, Iterations, iteration_curves, sorted_by_time

__all__ = ["TrajectoryComparison"]


_COLOURS = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#8c564b", "#e377c2", "#17becf", "#bcbd22"]


#: the metrics of each estimate N, as N_<key>
_KEYS = ("ate_rmse_m", "ate_pct", "final_err_m", "mean_err_m", "max_err_m", "end_to_end_err_m", "iterations",
         "poses", "poses_outside_truth")


class TrajectoryComparison(Component):
    """Final trajectories and per-iteration errors of several estimates against the truth
    (seed 2, Figs. 8 and 9; see the module doc for the metrics and the files)."""

    truth = Input(Pose2D, maxsize=1 << 20, doc="reference poses (RTK-GPS, simulator truth)")
    baseline = Input(Pose2D, maxsize=1 << 20, required=False, doc="a pose stream drawn and scored beside "
                     "(dead reckoning)")
    map = Input(Grid, policy="sampling", required=False,
                doc="a radar map in the frame of the first estimate (dB), drawn under Fig. 8")

    estimates = Param(list, default=["ekf", "isam2", "lm"], doc="one Trajectory2D input per name (one sample = "
                      "one iteration, the last one the final estimate)")
    poses = Param(list, default=[], doc="names of `estimates` whose input is a Pose2D stream (the whole stream "
                  "one final trajectory)")
    titles = Param(list, default=[], doc="names in the figures, one per estimate ([]: the input names)")
    report = Param(str, default="", path="write_dir", doc="report folder ('' = metrics only, no files)")
    align = Param(str, default="first", choices=("first", "rigid"),
                  doc="first: on the first estimated pose (the seed's); rigid: least squares on the final positions")
    title = Param(str, default="SLAM back-ends", doc="title of the report")
    baseline_title = Param(str, default="dead reckoning", doc="name of the baseline in the figures")

    @classmethod
    def declare_ports(cls, params: dict[str, Any]) -> tuple[dict[str, Input], dict[str, Output]]:
        names = params.get("estimates", cls.estimates.default)
        titles = params.get("titles", [])
        poses = params.get("poses", [])
        taken = set(cls.__inputs__) | set(cls.__params__)
        if not names:
            raise ParamError("parameter 'estimates': give at least one name")
        for n in names:
            if not isinstance(n, str) or not n.isidentifier() or n in taken:
                raise ParamError(f"parameter 'estimates': {n!r} is not a valid input name (an identifier, "
                                 "not truth, baseline, map nor a parameter name)")
        if len(set(names)) != len(names):
            raise ParamError(f"parameter 'estimates': a name is given twice in {names}")
        if titles and len(titles) != len(names):
            raise ParamError(f"parameter 'titles': {len(titles)} titles for {len(names)} estimates "
                             "(one per estimate, or [] for the names)")
        stray = [n for n in poses if n not in names]
        if stray:
            raise ParamError(f"parameter 'poses': {stray} not in 'estimates' {names} (poses names the estimates "
                             "that arrive as Pose2D streams)")
        ins = dict(cls.__inputs__)
        for n in names:
            if n in poses:
                ins[n] = Input(Pose2D, maxsize=1 << 20, required=False,
                               doc=f"poses of estimate {n} (the whole stream its final trajectory)")
            else:
                ins[n] = Input(Trajectory2D, maxsize=1 << 16, overflow="block", required=False,
                               doc=f"iterations of estimate {n} (one Trajectory2D each)")
        return ins, {}

    def start(self) -> None:
        self.samples = {n: Iterations(budget=MAX_ROWS // len(self.estimates)) for n in self.estimates}
        self.truth_t: list[int] = []
        self.truth_xyt: list[tuple[float, float, float]] = []
        self.truth_known: list[bool] = []
        self.pose_streams: dict[str, tuple[list[int], list[tuple[float, float, float]]]] = {
            n: ([], []) for n in self.poses}
        self.base_t: list[int] = []
        self.base_xyt: list[tuple[float, float, float]] = []
        self.figures: dict[str, Any] = {}
        #: per estimate (with a score): iteration (1-based), avg_err and conv (m) per kept
        #: iteration, dist and err (m) of the final poses, xy the aligned final positions
        self.curves: dict[str, dict[str, Any]] = {}
        self._done = False

    def process(self, t: int) -> None:
        s = self.inputs[self.trigger].take_sample()
        d = s.data
        if self.trigger == "truth":
            self.truth_t.append(s.timestamp)
            self.truth_xyt.append((d.x_m, d.y_m, d.theta_rad))
            self.truth_known.append(d.heading_known)
        elif self.trigger in self.pose_streams:
            ts, xs = self.pose_streams[self.trigger]
            ts.append(s.timestamp)
            xs.append((d.x_m, d.y_m, d.theta_rad))
        elif self.trigger == "baseline":
            self.base_t.append(s.timestamp)
            self.base_xyt.append((d.x_m, d.y_m, d.theta_rad))
        elif self.trigger in self.samples:
            its = self.samples[self.trigger]
            if its.add(d):
                self.log.warning("estimate %s: more than %d poses over its iterations, every %d-th iteration "
                                 "kept for the convergence curves", self.trigger, its.budget, its.stride)

    # --- metrics --------------------------------------------------------------------------
    def _score(self, name: str, t_ns: np.ndarray, xyt: np.ndarray, tt: np.ndarray, tx: np.ndarray,
               dist_truth: np.ndarray, tk: np.ndarray | None = None) -> dict[str, Any] | None:
        """Errors of one trajectory (the final estimate or the baseline) after its alignment;
        None when no pose lies inside the truth's span (or, aligned on the first pose, none has
        a known truth heading). ``tk``: truth heading known per truth pose (None: all)."""
        truth, inside = interpolate_truth(t_ns, tt, tx)
        in_gap = inside & in_spans(t_ns, gap_spans_ns(tt))
        if in_gap.any():  # said in one line at the end of compute()
            self._in_gaps.append(f"{name} {int(np.count_nonzero(in_gap))} of {len(t_ns)}")
        known = heading_known_at(t_ns, tt, tk)[inside & ~in_gap]
        outside = int(np.count_nonzero(~inside))
        if outside:  # one or two at the ends are routine (a truth that starts or stops a little late)
            (self.log.info if outside <= 2 else self.log.warning)(
                "%s: %d of %d poses outside the truth's time span, left out", name, outside, len(t_ns))
        inside &= ~in_gap
        if not np.any(inside):
            return None
        est, truth, t_in = xyt[inside], truth[inside], t_ns[inside]
        k0 = int(np.argmax(known)) if known.any() else None
        if k0 is None and self.align == "first":
            self.log.warning("%s: align first needs a known truth heading and the truth's is unknown at all its %d "
                             "poses (GPS at rest?): left out (align: rigid scores positions only)", name, len(t_in))
            self._notes.append(f"{name}: truth heading unknown at all its poses, not aligned on the first (left out).")
            return None
        r, tr = (rigid_align_2d(est[:, :2], truth[:, :2]) if self.align == "rigid"
                 else align_first(est, truth, k0 or 0))
        aligned = apply_rigid(r, tr, est)
        err = np.hypot(*(aligned[:, :2] - truth[:, :2]).T)
        rel = (t_in - tt[0]).astype(np.float64)
        travelled = np.interp(rel, (tt - tt[0]).astype(np.float64), dist_truth)  # along the truth (m)
        travelled -= travelled[0]
        ate = float(np.sqrt(np.mean(err ** 2)))
        return {"ate_rmse_m": ate, "final_err_m": float(err[-1]), "mean_err_m": float(np.mean(err)),
                "max_err_m": float(np.max(err)), "poses_outside_truth": outside,
                "poses_in_truth_gaps": int(np.count_nonzero(in_gap)), "path_m": float(travelled[-1]),
                "end_to_end_err_m": None if k0 is None else
                float(np.hypot(*(relative_position(est[k0], est[-1]) - relative_position(truth[k0], truth[-1])))),
                "r": r, "t": tr, "err": err, "dist": travelled, "xy": aligned[:, :2], "t_ns": t_in}

    def compute(self) -> dict[str, Any]:
        """The metrics of what was received (once; stop() and summary() share them)."""
        if self._done:
            return self.figures
        self._done = True
        out: dict[str, Any] = {}
        self._map_transform: tuple[np.ndarray, np.ndarray] | None = None
        self._baseline_xy: np.ndarray | None = None
        self._notes: list[str] = []
        self._in_gaps: list[str] = []
        for name, (ts, xs) in self.pose_streams.items():
            if ts and self.samples[name].final is None:  # the whole stream: one final trajectory
                self.samples[name].add(Trajectory2D(np.asarray(ts, np.int64),
                                                    np.asarray(xs, np.float64).reshape(-1, 3)))
        for name in self.estimates:
            its = self.samples[name]
            if its.final is None:
                self.log.info("estimate %s received nothing (no pose): left out", name)
                self._notes.append(f"{name}: received nothing (no pose), left out.")
                continue
            out[f"{name}_iterations"] = its.received
            out[f"{name}_poses"] = int(len(its.final[1]))
        if len(self.truth_t) < 2:
            self.log.warning("fewer than two truth poses (%d): no error computed", len(self.truth_t))
            self._notes.append(f"Fewer than two truth poses ({len(self.truth_t)}): no error computed.")
            self.figures = self._grouped(out)
            return self.figures
        tt, first = np.unique(np.asarray(self.truth_t, np.int64), return_index=True)  # repeated stamps: the first
        tx = np.asarray(self.truth_xyt, np.float64)[first]
        tk = np.asarray(self.truth_known, bool)[first]
        if len(tt) < len(self.truth_t):
            self.log.info("truth: %d samples repeat an earlier one's time stamp, the first of each kept",
                          len(self.truth_t) - len(tt))
        if len(tt) < 2:
            self.log.warning("fewer than two distinct truth times (%d): no error computed", len(tt))
            self._notes.append(f"Fewer than two distinct truth times ({len(tt)}): no error computed.")
            self.figures = self._grouped(out)
            return self.figures
        unknown = int(np.count_nonzero(~tk))
        if unknown:
            self._notes.append(f"Truth heading unknown at {unknown} of {len(tt)} truth poses (at rest): positions "
                               "only there.")
        tk_arg = tk if unknown else None
        dist_truth = distance_travelled_m(tx[:, :2])
        longest = 0.0
        for name in self.estimates:
            its = self.samples[name]
            if its.final is None:
                continue
            _, t_f, x_f = its.final
            s = self._score(name, t_f, x_f, tt, tx, dist_truth, tk_arg)
            out[f"{name}_poses_outside_truth"] = int(len(t_f)) if s is None else s["poses_outside_truth"]
            if s is None:  # the note on the poses outside says it
                continue
            for k in ("ate_rmse_m", "final_err_m", "mean_err_m", "max_err_m", "end_to_end_err_m",
                      "poses_in_truth_gaps"):
                out[f"{name}_{k}"] = s[k]
            if s["path_m"] > 0:
                out[f"{name}_ate_pct"] = 100.0 * s["ate_rmse_m"] / s["path_m"]
            longest = max(longest, s["path_m"])
            if self._map_transform is None:  # the map lies in the first estimate's frame
                self._map_transform = (s["r"], s["t"])
            kept = its.iterations()
            avg_err, conv = iteration_curves(kept, s["r"], s["t"], t_f, x_f[:, :2], tt, tx)
            self.curves[name] = {"iteration": np.array([k[0] for k in kept]), "avg_err": avg_err, "conv": conv,
                                 "dist": s["dist"], "err": s["err"], "xy": s["xy"], "t_ns": s["t_ns"],
                                 "subsampled": its.stride > 1}
            if its.stride > 1:
                self._notes.append(f"{name}: {its.received} iterations, {len(kept)} drawn in Fig. 9 (every "
                                   f"{its.stride}-th and the last: more than {its.budget} poses over them, "
                                   f"{MAX_ROWS} shared by the estimates).")
        if longest > 0:
            out["path_length_m"] = longest
        if self.base_t:
            bt, bx = sorted_by_time(np.asarray(self.base_t, np.int64), np.asarray(self.base_xyt, np.float64))
            s = self._score("baseline", bt, bx, tt, tx, dist_truth, tk_arg)
            out["baseline_poses"] = int(len(bt))
            out["baseline_poses_outside_truth"] = int(len(bt)) if s is None else s["poses_outside_truth"]
            if s is not None:
                for k in ("ate_rmse_m", "final_err_m", "mean_err_m", "max_err_m", "end_to_end_err_m",
                          "poses_in_truth_gaps"):
                    out[f"baseline_{k}"] = s[k]
                if s["path_m"] > 0:
                    out["baseline_ate_pct"] = 100.0 * s["ate_rmse_m"] / s["path_m"]
                self._baseline_xy = s["xy"]
        self._truth = (tt, tx)
        if self._in_gaps:
            self.log.warning("poses inside gaps of the truth (no truth to interpolate from), left out: %s",
                             ", ".join(self._in_gaps))
        self.figures = self._grouped(out)
        return self.figures

    def _grouped(self, out: dict[str, Any]) -> dict[str, Any]:
        """The metrics estimate by estimate (in ``estimates`` order), then the rest."""
        order = [k for n in self.estimates for x in _KEYS if (k := f"{n}_{x}") in out]
        return {k: out[k] for k in order + [k for k in out if k not in order]}

    # --- report ---------------------------------------------------------------------------
    def _titles(self) -> dict[str, str]:
        return {n: str(t) for n, t in zip(self.estimates, self.titles or self.estimates, strict=True)}

    def _colours(self) -> dict[str, str]:  # by position in `estimates`: the same in both figures
        return {n: _COLOURS[i % len(_COLOURS)] for i, n in enumerate(self.estimates)}

    def table(self) -> str:
        """The markdown table of report.md: one row per estimate, then the baseline."""
        f = self.figures

        def cell(key: str, fmt: str = ".3f") -> str:
            v = f.get(key)
            return "n/a" if v is None else format(v, fmt)

        rows = ["| estimate | ATE RMSE (m) | ATE (% of path) | final error (m) | end to end (m) | mean error (m) "
                "| iterations | poses |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
        titles = self._titles()
        for n in self.estimates:
            if f"{n}_iterations" in f:
                rows.append(f"| {titles[n]} | {cell(f'{n}_ate_rmse_m')} | {cell(f'{n}_ate_pct')} | "
                            f"{cell(f'{n}_final_err_m')} | {cell(f'{n}_end_to_end_err_m')} | "
                            f"{cell(f'{n}_mean_err_m')} | {f[f'{n}_iterations']} | {f[f'{n}_poses']} |")
        if "baseline_poses" in f:
            rows.append(f"| {self.baseline_title} | {cell('baseline_ate_rmse_m')} | {cell('baseline_ate_pct')} | "
                        f"{cell('baseline_final_err_m')} | {cell('baseline_end_to_end_err_m')} | "
                        f"{cell('baseline_mean_err_m')} | | "
                        f"{f['baseline_poses']} |")
        return "\n".join(rows)

    def write(self, folder: Path) -> None:
        """metrics.json, report.md and, with errors to draw, trajectories.png, convergence.png."""
        folder.mkdir(parents=True, exist_ok=True)
        (folder / METRICS_FILE).write_text(json.dumps(self.figures, indent=2, sort_keys=True) + "\n")
        drawn = bool(self.curves)
        if drawn:
            self._trajectories_figure(folder / "trajectories.png")
            self._convergence_figure(folder / "convergence.png")
        f = self.figures
        outside = [f"{n}: {f[f'{n}_poses_outside_truth']} of {f[f'{n}_poses']} poses outside the truth's time "
                   "span, left out."
                   for n in (*self.estimates, "baseline") if f.get(f"{n}_poses_outside_truth")]
        outside += [f"{n}: {f[f'{n}_poses_in_truth_gaps']} poses inside gaps of the truth (nothing to interpolate "
                    "from), left out." for n in (*self.estimates, "baseline") if f.get(f"{n}_poses_in_truth_gaps")]
        path = f" Truth path length {f['path_length_m']:.1f} m." if "path_length_m" in f else ""
        text = [f"# {self.title}", "",
                f"Alignment: {self.align}.{path} Errors: positions against the truth interpolated at each pose's "
                "time; ATE % of the truth's path over each final trajectory's time span.", "",
                self.table(), ""]
        text += [f"- {note}" for note in (*self._notes, *outside)] + ([""] if self._notes or outside else [])
        if drawn:
            text += ["![final trajectories (seed 2, Fig. 8)](trajectories.png)", "",
                     "![error and convergence per iteration (seed 2, Fig. 9)](convergence.png)", ""]
        (folder / "report.md").write_text("\n".join(text))

    def _trajectories_figure(self, path: Path) -> None:
        """Fig. 8: truth (thin black), final estimates, baseline (dashed grey), start marker."""
        titles, colour, f = self._titles(), self._colours(), self.figures
        tt, tx = self._truth
        spans = [c["t_ns"] for c in self.curves.values()]
        t0, t1 = min(int(s[0]) for s in spans), max(int(s[-1]) for s in spans)
        sel = (tt > t0) & (tt < t1)
        ends, _ = interpolate_truth(np.array([t0, t1], np.int64), tt, tx)
        truth_xy = np.vstack([ends[:1, :2], tx[sel, :2], ends[1:, :2]])
        xys = [truth_xy, *(c["xy"] for c in self.curves.values())]
        if self._baseline_xy is not None:
            xys.append(self._baseline_xy)
        xy = np.vstack(xys)
        lo, hi = xy.min(axis=0), xy.max(axis=0)
        # equal axes around the paths, each axis its own span: the figure takes the paths' shape
        mid, half = 0.5 * (lo + hi), 0.54 * (hi - lo) + 2.0 + 0.04 * float(np.max(hi - lo))
        half = np.maximum(half, 0.3 * float(np.max(half)))  # a straight path keeps some room either side
        rows = (len(self.curves) + (self._baseline_xy is not None) + 3) // 2  # the legend, below the plot
        fig = new_figure(8.0, float(np.clip(7.0 * half[1] / half[0] + 1.0, 3.5, 8.5)) + 0.22 * rows)
        ax = fig.add_subplot()
        radar_map = self.map.get()
        if radar_map is not None and self._map_transform is not None:
            show_map(ax, radar_map, self._map_transform)  # the global map (seed 2, Figs. 5 and 7)
        import matplotlib.patheffects as pe  # after new_figure: matplotlib is imported lazily

        halo = [pe.Stroke(linewidth=3.2, foreground="w", alpha=0.9), pe.Normal()]  # readable over a dark map
        ax.plot(*truth_xy.T, color="k", lw=1.0, label="truth", zorder=5, path_effects=halo)
        if self._baseline_xy is not None:
            ax.plot(*self._baseline_xy.T, "--", color="0.55", lw=1.0, zorder=2,
                    label=f"{self.baseline_title} (ATE {f['baseline_ate_rmse_m']:.2f} m)")
        for n, c in self.curves.items():
            pct = f.get(f"{n}_ate_pct")
            ax.plot(*c["xy"].T, color=colour[n], lw=1.3, zorder=4, path_effects=halo,
                    label=f"{titles[n]} (ATE {f[f'{n}_ate_rmse_m']:.3f} m" + (f" = {pct:.2f} %" if pct else "")
                    + f", final {f[f'{n}_final_err_m']:.3f} m)")
            ax.plot(*c["xy"][-1], "x", color=colour[n], ms=8, mew=2.0, zorder=6)
        ax.plot(*truth_xy[0], "o", color="k", mfc="w", ms=7, mew=1.5, zorder=6, label="start")
        ax.plot(*truth_xy[-1], "s", color="k", mfc="w", ms=7, mew=1.5, zorder=6, label="end (x: each estimate's)")
        ax.set_xlim(mid[0] - half[0], mid[0] + half[0])
        ax.set_ylim(mid[1] - half[1], mid[1] + half[1])
        ax.set_aspect("equal")
        ax.set(xlabel="x (m)", ylabel="y (m)", title=f"{self.title}: final trajectories ({self.align} alignment)")
        ax.grid(alpha=0.3)
        fig.legend(loc="outside lower center", ncol=2, frameon=False, fontsize=8)  # never over the paths
        save_figure(fig, path)

    def _convergence_figure(self, path: Path) -> None:
        """Fig. 9: (a) average error per iteration, (b) rate of convergence, (c) the final
        estimates' error along the distance travelled. (b) on a log scale when it has positive
        values, (a) when they span more than 30x (a first batch iteration far off); values
        that a log scale cannot show (0: the last iteration of (b)) are left out."""
        titles, colour = self._titles(), self._colours()
        fig = new_figure(8.0, 9.6)
        from matplotlib.ticker import MaxNLocator  # after new_figure: matplotlib is imported lazily

        a, b, c = fig.subplots(3, 1)
        curves = self.curves.values()
        pos = [np.concatenate([cv[k][np.isfinite(cv[k]) & (cv[k] > 0)] for cv in curves]) for k in ("avg_err", "conv")]
        log_a = pos[0].size > 0 and float(pos[0].max()) > 30.0 * float(pos[0].min())
        log_b = pos[1].size > 0
        for n, cv in self.curves.items():
            it = cv["iteration"]
            style = dict(color=colour[n], lw=1.2, marker="o" if len(it) <= 30 else None, ms=3,
                         label=titles[n] + (" (iterations subsampled)" if cv["subsampled"] else ""))
            for ax, key, log in ((a, "avg_err", log_a), (b, "conv", log_b)):
                ok = np.isfinite(cv[key]) & ((cv[key] > 0) if log else True)
                if np.any(ok):
                    ax.plot(it[ok], cv[key][ok], **style)
            c.plot(cv["dist"], cv["err"], color=colour[n], lw=1.2, label=titles[n])
        a.set(xlabel="iteration", ylabel="average error (m)", title="(a) average total error per iteration")
        b.set(xlabel="iteration", ylabel="mean distance to final (m)",
              title="(b) rate of convergence: mean distance to the final estimate")
        c.set(xlabel="distance travelled (m)", ylabel="position error (m)",
              title=f"(c) error of the final estimates along the path ({self.align} alignment)")
        for ax, log in ((a, log_a), (b, log_b)):
            ax.xaxis.set_major_locator(MaxNLocator(integer=True))
            if log:
                ax.set_yscale("log")
            else:
                ax.set_ylim(bottom=0)
        if log_b:
            b.text(0.99, 0.02, "0 at the last iteration (not drawn on the log scale)", transform=b.transAxes,
                   ha="right", va="bottom", fontsize=7, color="0.4")
        c.set_ylim(bottom=0)
        c.set_xlim(left=0)
        for ax in (a, b, c):
            ax.grid(alpha=0.3)
            if ax.get_lines():
                ax.legend(loc="best", frameon=False, fontsize=8)
        fig.suptitle(self.title)
        save_figure(fig, path)

    # --- lifecycle --------------------------------------------------------------------------
    def stop(self) -> None:
        if not hasattr(self, "samples"):  # start() did not run
            return
        self.compute()
        if self.curves:
            self.log.info("trajectory comparison (%s alignment)\n%s", self.align, self.table())
        if self.report:
            self.write(Path(self.report))

    def summary(self) -> dict:
        return {k: round(v, 4) if isinstance(v, float) else v for k, v in self.compute().items()}
