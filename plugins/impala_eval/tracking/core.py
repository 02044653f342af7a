"""Tracking metrics: CLEAR-MOT and identity metrics (``motmetrics``), per-track errors,
false-track lifetimes (RADAR.md item 10, seed 1 §4.3.4).

Frames are the tracker's output times (one per turn). The truth (``movers/states``, 10 Hz)
is brought to each frame time from its nearest sample by its own constant velocity (cars
move at constant speed between two truth samples), and only movers within the radar's range
of the radar position count (what the sensor cannot see is not a miss of the tracker). A
track and a mover match when they are less than ``match_m`` apart (Euclidean, MOTP in m).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = ["TrackingFrames", "tracking_metrics", "truth_at"]


@dataclass
class TrackingFrames:
    """What the evaluator received, as arrays per frame."""

    t_ns: list[int] = field(default_factory=list)
    track_ids: list[np.ndarray] = field(default_factory=list)
    track_xy: list[np.ndarray] = field(default_factory=list)
    track_v: list[np.ndarray] = field(default_factory=list)
    truth_t_ns: list[int] = field(default_factory=list)
    truth_ids: list[np.ndarray] = field(default_factory=list)
    truth_xy: list[np.ndarray] = field(default_factory=list)
    truth_v: list[np.ndarray] = field(default_factory=list)
    exist_t_ns: list[int] = field(default_factory=list)
    exist_ids: list[np.ndarray] = field(default_factory=list)
    exist_xy: list[np.ndarray] = field(default_factory=list)
    exist_p: list[np.ndarray] = field(default_factory=list)
    exist_conf: list[np.ndarray] = field(default_factory=list)
    radar_t_ns: list[int] = field(default_factory=list)
    radar_xy: list[np.ndarray] = field(default_factory=list)


def truth_at(frames: TrackingFrames, t_ns: int, max_gap_s: float = 0.5) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ids, xy, v) of the truth at ``t_ns``: nearest sample moved by its velocity; nothing
    if the nearest sample is more than ``max_gap_s`` away."""
    tt = np.asarray(frames.truth_t_ns, np.int64)
    empty = (np.zeros(0, np.int64), np.zeros((0, 2)), np.zeros((0, 2)))
    if len(tt) == 0:
        return empty
    i = int(np.argmin(np.abs(tt - t_ns)))
    dt = (t_ns - tt[i]) * 1e-9
    if abs(dt) > max_gap_s:
        return empty
    return frames.truth_ids[i], frames.truth_xy[i] + dt * frames.truth_v[i], frames.truth_v[i]


def _radar_at(frames: TrackingFrames, t_ns: int) -> np.ndarray:
    if not frames.radar_t_ns:
        return np.zeros(2)
    tt = np.asarray(frames.radar_t_ns, np.int64)
    xy = np.asarray(frames.radar_xy)
    return np.array([np.interp(t_ns, tt, xy[:, 0]), np.interp(t_ns, tt, xy[:, 1])])


def _distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.hypot(a[:, None, 0] - b[None, :, 0], a[:, None, 1] - b[None, :, 1])


def tracking_metrics(frames: TrackingFrames, match_m: float = 3.0, range_m: tuple[float, float] = (3.0, 100.0),
                     turn_s: float = 1.0) -> dict[str, Any]:
    """Every figure of the tracking report (see the module doc); units in the key names."""
    import motmetrics as mm

    acc = mm.MOTAccumulator(auto_id=True)
    per_track: dict[int, dict[str, list]] = {}
    truth_paths: dict[int, list] = {}
    kept: list[tuple] = []
    for t, ids, xy, v in zip(frames.t_ns, frames.track_ids, frames.track_xy, frames.track_v, strict=True):
        gid, gxy, gv = truth_at(frames, t)
        rng = np.hypot(*(gxy - _radar_at(frames, t)).T) if len(gid) else np.zeros(0)
        seen = (rng >= range_m[0]) & (rng <= range_m[1])
        gid, gxy, gv = gid[seen], gxy[seen], gv[seen]
        for k, g in enumerate(gid):
            truth_paths.setdefault(int(g), []).append((t, *gxy[k]))
        d = _distances(gxy, xy)
        acc.update(list(map(int, gid)), list(map(int, ids)), np.where(d <= match_m, d, np.nan))
        kept.append((gid, gxy, gv, ids, xy, v))
    ev = acc.mot_events
    if len(ev):  # per-track errors against the mover each frame matched it to
        m = ev[ev["Type"].isin(["MATCH", "SWITCH"])]
        for fid, oid, hid in zip(m.index.get_level_values(0), m["OId"], m["HId"], strict=True):
            gid, gxy, gv, ids, xy, v = kept[int(fid)]
            i = int(np.nonzero(ids == int(hid))[0][0])
            g = int(np.nonzero(gid == int(oid))[0][0])
            rec = per_track.setdefault(int(hid), {"pos": [], "speed": [], "vel": [], "truth": []})
            rec["pos"].append(float(np.hypot(*(xy[i] - gxy[g]))))
            rec["speed"].append(abs(float(np.hypot(*v[i]) - np.hypot(*gv[g]))))
            rec["vel"].append(float(np.hypot(*(v[i] - gv[g]))))
            rec["truth"].append(int(oid))
    mh = mm.metrics.create()
    names = ["mota", "motp", "idf1", "idp", "idr", "num_switches", "num_fragmentations", "num_false_positives",
             "num_misses", "num_objects", "num_matches", "mostly_tracked", "num_unique_objects"]
    summary = mh.compute(acc, metrics=names, name="all") if frames.t_ns else None
    out: dict[str, Any] = {"frames": len(frames.t_ns)}
    if summary is not None:
        row = summary.loc["all"]
        for k, key in [("mota", "mota"), ("motp", "motp_m"), ("idf1", "idf1"), ("idp", "idp"), ("idr", "idr")]:
            val = float(row[k])
            out[key] = round(val, 4) if np.isfinite(val) else None
        for k, key in [("num_switches", "id_switches"), ("num_fragmentations", "fragmentations"),
                       ("num_false_positives", "false_positives"), ("num_misses", "misses"),
                       ("num_objects", "truth_objects"), ("num_matches", "matches"),
                       ("mostly_tracked", "mostly_tracked"), ("num_unique_objects", "truth_movers")]:
            out[key] = int(row[k])
    tracks = []
    for hid, rec in sorted(per_track.items()):
        vals, counts = np.unique(rec["truth"], return_counts=True)
        tracks.append({"id": hid, "mover": int(vals[np.argmax(counts)]), "frames": len(rec["pos"]),
                       "pos_err_m": round(float(np.mean(rec["pos"])), 3),
                       "speed_err_mps": round(float(np.mean(rec["speed"])), 3),
                       "vel_err_mps": round(float(np.mean(rec["vel"])), 3)})
    out["tracks"] = tracks
    if tracks:
        longest = max(tracks, key=lambda r: r["frames"])
        out["longest_track_id"] = longest["id"]
        out["pos_err_m"] = longest["pos_err_m"]
        out["speed_err_mps"] = longest["speed_err_mps"]
        pos = np.concatenate([per_track[r["id"]]["pos"] for r in tracks])
        spd = np.concatenate([per_track[r["id"]]["speed"] for r in tracks])
        out["pos_err_all_m"] = round(float(np.mean(pos)), 3)
        out["speed_err_all_mps"] = round(float(np.mean(spd)), 3)
    out.update(_false_tracks(frames, match_m, turn_s))
    out["truth_paths"] = {str(k): v for k, v in truth_paths.items()}
    return out


def _false_tracks(frames: TrackingFrames, match_m: float, turn_s: float) -> dict[str, Any]:
    """Every track the tracker launched (tentative or confirmed, from the existence stream):
    those never within ``match_m`` of a mover are false; their lifetime in turns."""
    first: dict[int, int] = {}
    last: dict[int, int] = {}
    true_ids: set[int] = set()
    confirmed: set[int] = set()
    for t, ids, xy, conf in zip(frames.exist_t_ns, frames.exist_ids, frames.exist_xy, frames.exist_conf,
                                strict=True):
        gid, gxy, _ = truth_at(frames, t)
        d = _distances(xy, gxy) if len(gid) else np.full((len(ids), 0), np.inf)
        for k, i in enumerate(map(int, ids)):
            first.setdefault(i, t)
            last[i] = t
            if d.shape[1] and d[k].min() <= match_m:
                true_ids.add(i)
            if conf[k]:
                confirmed.add(i)
    false = sorted(set(first) - true_ids)
    life = [int(round((last[i] - first[i]) * 1e-9 / turn_s)) + 1 for i in false]
    conf_life = [lt for i, lt in zip(false, life, strict=True) if i in confirmed]
    return {"tracks_launched": len(first), "false_tracks": len(false),
            "false_tracks_confirmed": len(conf_life),
            "false_track_max_turns": max(life) if life else 0,
            "false_track_mean_turns": round(float(np.mean(life)), 3) if life else 0.0,
            "false_confirmed_max_turns": max(conf_life) if conf_life else 0}
