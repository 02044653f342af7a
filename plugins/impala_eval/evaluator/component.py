"""``eval.TrajectoryEvaluator``: an estimated trajectory against the truth, report at stop()."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from impala_flow import Component, Input, Param
from impala_flow.msgs import Grid, Pose2D, Twist2D

from ..metrics import SEGMENT_LENGTHS_M, TrajectoryMetrics, TwistErrors, trajectory_metrics, twist_errors
from ..report import find_gaps, format_metrics, gap_summary, write_report

__all__ = ["TrajectoryEvaluator"]


def _arrays(samples: list[tuple[int, Pose2D]]) -> tuple[np.ndarray, np.ndarray]:
    t = np.array([s[0] for s in samples], np.int64)
    xyt = np.array([[p.x_m, p.y_m, p.theta_rad] for _, p in samples], float).reshape(-1, 3)
    order = np.argsort(t, kind="stable")
    return t[order], xyt[order]


def _truth_arrays(samples: list[tuple[int, Pose2D]]) -> tuple[np.ndarray, np.ndarray, np.ndarray | None, int]:
    """Truth times (sorted, each once: the first sample of a repeated stamp kept), poses, heading
    known per sample (None: everywhere) and how many repeated stamps were merged."""
    t = np.array([s[0] for s in samples], np.int64)
    xyt = np.array([[p.x_m, p.y_m, p.theta_rad] for _, p in samples], float).reshape(-1, 3)
    known = np.array([p.heading_known for _, p in samples], bool)
    t, first = np.unique(t, return_index=True)  # np.unique's index is the first occurrence
    known = known[first]
    return t, xyt[first], None if known.all() else known, len(samples) - len(t)


class TrajectoryEvaluator(Component):
    """Matches the estimate to the truth by timestamp (truth interpolated), aligns it (rigid
    least squares or first pose), and at stop() writes ``report``: metrics.json, error vs
    distance (seed Fig. 12), trajectory over the map (Fig. 10b), the map; with ``pairs``
    also every consecutive pair's relative-motion error (scan-to-scan registration against
    the truth's motion between the same times) and their figure, pair_errors.png. Data that
    never arrived is stated, never averaged away: time ranges of a stream with no sample for
    more than three median periods (a damaged chunk of the recording, a dropped sensor) go
    to metrics.json (``gaps``), the printed metrics and the error figure, with a one-line
    warning (per stream: how many, in all, the longest); repeated stamps are one sample.

    Truth from a GPS: a truth pose whose heading is unknown (``Pose2D.heading_known``: at
    rest) is scored on its position only. ATE (rigid) needs positions only; ``align: first``
    aligns on the first matched pose whose truth heading is known (refused, with a one-line
    warning, when there is none); heading RMSE, pair errors, final rotation, yaw-rate errors
    and relative errors use only the poses where it is known, and say how many were left out.
    Relative drift: KITTI-style over segments of 100, 200, ..., 800 m along the true path
    (``rel_err_pct`` their mean, ``rel_err_<L>m_pct`` per length), each starting at a pose
    whose truth heading is known (its frame); ``rel_err_per_100m_pct`` over ``segment_m``."""

    estimate = Input(Pose2D, maxsize=1 << 20, doc="estimated poses (each one evaluated)")
    truth = Input(Pose2D, maxsize=1 << 20, doc="reference poses (RTK-GPS, simulator truth)")
    baseline = Input(Pose2D, maxsize=1 << 20, required=False, doc="a second estimate (dead reckoning)")
    map = Input(Grid, policy="sampling", required=False, doc="the radar map drawn under the trajectories")
    twist = Input(Twist2D, maxsize=1 << 20, required=False,
                  doc="estimated speed and yaw rate: errors against the truth's over twist_window_s")

    report = Param(str, default="", path="write_dir", doc="report folder ('' = metrics only, no files)")
    align = Param(str, default="rigid", choices=("rigid", "first"), doc="alignment before the ATE")
    segment_m = Param(float, default=100.0, gt=0, doc="segment length of the relative error")
    title = Param(str, default="R-SLAM", doc="name of the estimate in the figures")
    baseline_title = Param(str, default="dead reckoning", doc="name of the baseline in the figures")
    pairs = Param(bool, default=False,
                  doc="report every consecutive pair's relative-motion error (metrics.json, pair_errors.png)")
    twist_window_s = Param(float, default=1.0, gt=0,
                           doc="truth speed and yaw rate: central difference of the truth over this window "
                               "(the estimator's own: one turn for a two-turn method)")
    map_scale = Param(str, default="db", choices=("db", "power"),
                      doc="unit of the map's values: dB (slam.RSlam's map) or linear power")

    def start(self) -> None:
        self.samples: dict[str, list] = {"estimate": [], "truth": [], "baseline": [], "twist": []}
        self.twist_errors: TwistErrors | None = None
        self.figures: dict = {}
        self.metrics: TrajectoryMetrics | None = None
        self.baseline_metrics: TrajectoryMetrics | None = None

    def process(self, t: int) -> None:
        # truth is kept whole (not a bounded history): an estimate stamped at t_ref may
        # arrive after later truth samples, and the match is done once, at stop()
        s = self.inputs[self.trigger].take_sample()
        self.samples[self.trigger].append((s.timestamp, s.data))

    def evaluate(self) -> dict:
        """Compute the metrics from what was received (also called by stop())."""
        est, truth, base = (self.samples[k] for k in ("estimate", "truth", "baseline"))
        if len(est) < 2 or len(truth) < 2:
            self.figures = {"error": f"not enough poses (estimate {len(est)}, truth {len(truth)})"}
            return self.figures
        tt, txyt, known, repeated = _truth_arrays(truth)
        if len(tt) < 2:
            self.figures = {"error": f"not enough truth poses ({len(tt)} distinct times)"}
            return self.figures
        if repeated:
            self.log.info("truth: %d samples repeat an earlier one's time stamp, the first of each kept", repeated)
        gaps = {k: g for k in ("estimate", "truth", "baseline")
                if (g := find_gaps(np.array([s[0] for s in self.samples[k]], np.int64)))}
        try:
            self.metrics = trajectory_metrics(*_arrays(est), tt, txyt, self.align, self.segment_m, known)
        except ValueError as e:
            self.figures = {"error": str(e)}
            return self.figures
        self.figures = self.metrics.figures()
        if gaps:
            self.figures["gaps"] = gaps
            self.figures["gap_total_s"] = round(sum(b - a for g in gaps.values() for a, b in g), 6)
        if len(base) >= 2:
            try:
                self.baseline_metrics = trajectory_metrics(*_arrays(base), tt, txyt, self.align, self.segment_m,
                                                           known)
                self.figures.update(self.baseline_metrics.figures("baseline_"))
            except ValueError as e:
                self.figures["baseline_error"] = str(e)
        tw = self.samples["twist"]
        if tw:
            t = np.array([s[0] for s in tw], np.int64)
            order = np.argsort(t, kind="stable")
            v = np.array([s[1].speed_mps for s in tw], float)[order]
            w = np.array([s[1].yaw_rate_radps for s in tw], float)[order]
            self.twist_errors = twist_errors(t[order], v, w, tt, txyt, self.twist_window_s, known)
            if len(self.twist_errors.t_ns):
                self.figures.update(self.twist_errors.figures())
        if self.pairs:
            self.figures["pairs"] = self.metrics.pairs.rows()
            if self.baseline_metrics is not None:
                self.figures["baseline_pairs"] = self.baseline_metrics.pairs.rows()
        return self.figures

    def stop(self) -> None:
        figures = self.evaluate()
        m = self.metrics
        if m is None:
            self.log.warning("no report: %s", figures.get("error"))
            return
        self.log.info("trajectory metrics\n%s", format_metrics(figures))
        if figures.get("baseline_error"):
            self.log.warning("baseline not scored: %s", figures["baseline_error"])
        if figures.get("gaps"):
            self.log.warning("data missing, metrics cover only what was received: %s", gap_summary(figures["gaps"]))
        if self.report:
            write_report(Path(self.report), figures, m, self.baseline_metrics, self.map.get(),
                         (m.rotation, m.translation_m), self.title, self.map_scale, self.baseline_title,
                         pairs_figure=self.pairs, twist=self.twist_errors)

    def summary(self) -> dict:
        keys = ("ate_rmse_m", "ate_pct", "drift_pct", "rel_err_pct", "rel_err_per_100m_pct",
                *(f"rel_err_{L:g}m_pct" for L in SEGMENT_LENGTHS_M), "baseline_ate_rmse_m", "baseline_drift_pct",
                "pair_trans_err_mean_m", "pair_rot_err_mean_deg", "gap_total_s", "speed_err_mean_mps",
                "speed_err_std_mps", "yaw_rate_err_mean_dps", "yaw_rate_err_std_dps", "final_error_x_m",
                "final_error_y_m", "final_rot_err_rad")
        out = {k: round(self.figures[k], 3) for k in keys if isinstance(self.figures.get(k), float)}
        if self.figures.get("error"):  # nothing scored: the summary says why (not only the log)
            out["not_scored"] = self.figures["error"]
        return out
