"""``eval.TrackingEvaluator``: tracks against the movers' truth, report at stop() (seed 1 §4.3.4).

    metrics.json    CLEAR-MOT and identity metrics (motmetrics: MOTA, MOTP in m, IDF1, ID
                    switches, fragmentations), per-track mean position and speed errors (the
                    longest track's as the seed reports it), false tracks and their lifetime in turns
    tracks.png      every track over the map with the truth dashed, the radar a cross (Fig. 19)
    existence.png   existence probability of every launched track over time (Fig. 18)

Frames: tracks, truth, existence and pose are scored only in one frame, the truth's (the
``frame`` of its first sample). A sample in another frame (tracks in ``radar`` because the
tracker had no pose, truth in ``map``) is never compared: it is left out, counted
(``unscored_turns`` for tracks, ``unscored_truth``, ``unscored_existence``,
``unscored_pose``) in the summary and metrics.json (``frame_errors``), and the first of each
input is one ERROR line naming the input, both frames and the sample's time. With every
track turn left out, the CLEAR-MOT figures are absent, never computed on mixed frames.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from impala_flow import Component, Input, Param
from impala_flow.msgs import Pose2D
from impala_msgs import ObjectStates, TrackExistence

from .core import TrackingFrames, tracking_metrics

__all__ = ["TrackingEvaluator", "write_tracking_report"]

_SUMMARY_KEYS = ("mota", "motp_m", "idf1", "id_switches", "fragmentations", "pos_err_m", "speed_err_mps",
                 "false_tracks", "false_track_max_turns")
#: input -> the counter of its samples left out (in a frame other than the truth's)
_UNSCORED = {"tracks": "unscored_turns", "truth": "unscored_truth", "existence": "unscored_existence",
             "pose": "unscored_pose"}


class TrackingEvaluator(Component):
    """Matches the tracker's confirmed tracks to the movers' truth frame by frame (tracker
    output times; truth moved to each time by its velocity; movers out of the radar's range
    left out) and at stop() writes ``report``: metrics.json, tracks.png (Fig. 19) and
    existence.png (Fig. 18). See :mod:`impala_eval.tracking.core` for the definitions."""

    tracks = Input(ObjectStates, maxsize=1 << 20, doc="confirmed tracks, one sample per turn")
    truth = Input(ObjectStates, maxsize=1 << 20, doc="movers' truth (movers/states)")
    existence = Input(TrackExistence, maxsize=1 << 20, required=False,
                      doc="every launched track and its existence probability (false-track lifetimes, Fig. 18)")
    pose = Input(Pose2D, maxsize=1 << 20, required=False, doc="radar position (range of the truth, the map's cross)")

    report = Param(str, default="", path="write_dir", doc="report folder ('' = metrics only, no files)")
    match_m = Param(float, default=3.0, gt=0, doc="a track and a mover farther apart do not match")
    range_min_m = Param(float, default=3.0, ge=0, doc="movers nearer the radar are not counted")
    range_max_m = Param(float, default=100.0, gt=0, doc="movers farther from the radar are not counted")
    turn_s = Param(float, default=1.0, gt=0, doc="antenna turn period (lifetimes in turns)")
    title = Param(str, default="DATMO", doc="title of the figures")

    def start(self) -> None:
        self.frames = TrackingFrames()
        self.figures: dict[str, Any] = {}
        self._truth_frame: str | None = None
        self._held: list[tuple[str, int, Any]] = []  # (input, t, data) received before the first truth
        self.unscored: dict[str, int] = {}  # input -> samples left out (another frame than the truth's)
        self.frame_errors: dict[str, str] = {}  # input -> the line logged for its first

    def process(self, t: int) -> None:
        s = self.inputs[self.trigger].take_sample()
        if self._truth_frame is None and self.trigger != "truth":
            self._held.append((self.trigger, s.timestamp, s.data))  # its frame is judged at the first truth
            return
        if self.trigger == "truth" and self._truth_frame is None:
            self._truth_frame = s.data.frame
            self._store("truth", s.timestamp, s.data)
            held, self._held = self._held, []
            for port, t_ns, data in held:
                self._store(port, t_ns, data)
            return
        self._store(self.trigger, s.timestamp, s.data)

    def _store(self, port: str, t_ns: int, d: Any) -> None:
        f = self.frames
        if d.frame != self._truth_frame:
            self.unscored[port] = self.unscored.get(port, 0) + 1
            if port not in self.frame_errors:
                self.frame_errors[port] = (
                    f"input '{port}': sample t={t_ns} ns is in frame '{d.frame}', the truth in "
                    f"'{self._truth_frame}': not scored (no transform between them here; give the tracker "
                    f"the radar pose in '{self._truth_frame}'); further ones counted as unscored")
                self.log.error("%s", self.frame_errors[port])
            return
        if port == "tracks":
            f.t_ns.append(t_ns)
            f.track_ids.append(np.asarray(d.ids, np.int64))
            f.track_xy.append(np.asarray(d.xy_m, float).reshape(-1, 2))
            f.track_v.append(np.asarray(d.v_xy_mps, float).reshape(-1, 2))
        elif port == "truth":
            f.truth_t_ns.append(t_ns)
            f.truth_ids.append(np.asarray(d.ids, np.int64))
            f.truth_xy.append(np.asarray(d.xy_m, float).reshape(-1, 2))
            f.truth_v.append(np.asarray(d.v_xy_mps, float).reshape(-1, 2))
        elif port == "existence":
            f.exist_t_ns.append(t_ns)
            f.exist_ids.append(np.asarray(d.ids, np.int64))
            f.exist_xy.append(np.asarray(d.xy_m, float).reshape(-1, 2))
            f.exist_p.append(np.asarray(d.probability, float))
            f.exist_conf.append(np.asarray(d.confirmed, bool))
        else:
            f.radar_t_ns.append(t_ns)
            f.radar_xy.append(np.array([d.x_m, d.y_m]))

    def evaluate(self) -> dict[str, Any]:
        """Compute the metrics from what was received (also called by stop())."""
        if self._held:  # no truth ever came: nothing can be scored
            for port, _, _ in self._held:
                self.unscored[port] = self.unscored.get(port, 0) + 1
            port, t_ns, _ = self._held[0]
            self.frame_errors.setdefault(port, f"input '{port}': no truth received, nothing scored "
                                               f"(first sample t={t_ns} ns)")
            self.log.error("%s", self.frame_errors[port])
            self._held = []
        self.figures = tracking_metrics(self.frames, self.match_m, (self.range_min_m, self.range_max_m), self.turn_s)
        for port, n in self.unscored.items():
            self.figures[_UNSCORED[port]] = n
        if self.frame_errors:
            self.figures["frame_errors"] = dict(self.frame_errors)
        return self.figures

    def stop(self) -> None:
        figures = self.evaluate()
        shown = {k: figures.get(k) for k in _SUMMARY_KEYS}
        self.log.info("tracking metrics: %s", json.dumps(shown))
        if self.report:
            write_tracking_report(Path(self.report), figures, self.frames, self.title)

    def summary(self) -> dict:
        keys = (*_SUMMARY_KEYS, *_UNSCORED.values())
        return {k: self.figures[k] for k in keys if isinstance(self.figures.get(k), (int, float))}


def write_tracking_report(folder: Path, figures: dict[str, Any], frames: TrackingFrames, title: str) -> None:
    """metrics.json, tracks.png (Fig. 19), existence.png (Fig. 18)."""
    from ..report import new_figure, save_figure

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "metrics.json").write_text(json.dumps(figures, indent=2, sort_keys=True) + "\n")
    cmap = _colors()
    # Fig. 19: every launched track (thin: never confirmed), truth dashed, radar a cross
    fig = new_figure(7.0, 6.0)
    ax = fig.add_subplot(1, 1, 1)
    paths: dict[int, list] = {}
    conf: set[int] = set()
    for ids, xy, c in zip(frames.exist_ids, frames.exist_xy, frames.exist_conf, strict=True):
        for k, i in enumerate(map(int, ids)):
            paths.setdefault(i, []).append(xy[k])
            if c[k]:
                conf.add(i)
    for i, pts in paths.items():
        p = np.asarray(pts)
        ax.plot(p[:, 0], p[:, 1], "-" if i in conf else ":", color=cmap(i % 20), lw=1.8 if i in conf else 0.8,
                marker="." if len(p) < 3 else None)
    for _, pts in figures.get("truth_paths", {}).items():
        p = np.asarray(pts)
        ax.plot(p[:, 1], p[:, 2], "k--", lw=0.8)
    radar = np.asarray(frames.radar_xy).reshape(-1, 2)
    if len(radar):
        ax.plot(radar[:, 0], radar[:, 1], "k-", lw=0.6)
        ax.plot(radar[0, 0], radar[0, 1], "kx", ms=10)
    else:
        ax.plot(0.0, 0.0, "kx", ms=10)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{title}: tracks (solid: confirmed, dotted: tentative), truth dashed")
    save_figure(fig, folder / "tracks.png")
    # Fig. 18: existence probability of every track over time
    fig = new_figure(8.0, 4.0)
    ax = fig.add_subplot(1, 1, 1)
    series: dict[int, list] = {}
    t0 = frames.exist_t_ns[0] if frames.exist_t_ns else 0
    for t, ids, p in zip(frames.exist_t_ns, frames.exist_ids, frames.exist_p, strict=True):
        for k, i in enumerate(map(int, ids)):
            series.setdefault(i, []).append(((t - t0) * 1e-9, p[k]))
    for i, pts in series.items():
        p = np.asarray(pts)
        ax.plot(p[:, 0], p[:, 1], "-", color=cmap(i % 20), lw=1.5 if i in conf else 0.7,
                marker="." if len(p) < 3 else None)
    ax.set_ylim(0.0, 1.02)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("existence probability")
    ax.set_title(f"{title}: existence probability of every track")
    save_figure(fig, folder / "existence.png")


def _colors():  # type: ignore[no-untyped-def]
    from matplotlib import colormaps

    return colormaps["tab20"]
