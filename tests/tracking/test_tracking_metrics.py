"""eval.TrackingEvaluator through the component runner on scripted tracks and truth whose
CLEAR-MOT figures are counted by hand (MOTA = 1 - (FN + FP + IDSW) / GT, MOTP = mean matched
distance, IDF1 = 2 IDTP / (GT + hypotheses)); false-track lifetimes in turns."""

from __future__ import annotations

import json

import numpy as np

from impala_eval.tracking.component import TrackingEvaluator
from impala_flow.msgs import Pose2D
from impala_flow.testing import ScriptedSource, run_components
from impala_msgs import ObjectStates, TrackExistence

S = 1_000_000_000


def _states(ids, xy, v):
    xy = np.asarray(xy, float).reshape(-1, 2)
    return ObjectStates(np.asarray(ids, np.int64), xy, np.broadcast_to(np.asarray(v, float), xy.shape).copy())


def test_clear_mot_identity_metrics_and_false_track_lifetimes_by_hand(tmp_path):
    # one mover along y = 20 at 5 m/s for 10 frames; truth at 10 Hz
    script = [(k * S // 10, "truth", _states([1], [[-25 + 0.5 * k, 20.0]], [5.0, 0.0])) for k in range(0, 101)]
    script.append((0, "pose", Pose2D(0.0, 0.0, 0.0)))
    for k in range(1, 11):
        x = -25 + 5.0 * k
        if k <= 2:
            ids, xy = [], []                       # frames 1-2: not yet confirmed -> 2 FN
        elif k <= 6:
            ids, xy = [7], [[x + 1.0, 20.0]]       # frames 3-6: track 7, 1 m off -> 4 matches
        elif k == 7:
            ids, xy = [7, 9], [[x, 20.0], [x + 40.0, -30.0]]  # + a false track 9 -> 1 FP
        else:
            ids, xy = [8], [[x + 0.5, 20.0]]       # frames 8-10: new id 8 -> 1 switch, 3 matches
        script.append((k * S, "tracks", _states(ids, xy, [5.0, 0.0])))
        e_ids = ids + ([11] if k in (4, 5) else [])  # a tentative false track 11 lives 2 turns
        e_xy = xy + ([[0.0, 80.0]] if k in (4, 5) else [])
        script.append((k * S, "existence", TrackExistence(np.asarray(e_ids, np.int64),
                                                          np.asarray(e_xy, float).reshape(-1, 2),
                                                          np.full(len(e_ids), 0.5), np.ones(len(e_ids), bool))))
    script.sort(key=lambda s: s[0])
    ev = TrackingEvaluator("eval", report=str(tmp_path))
    run_components(ScriptedSource("src", script), ev,
                   connections=["src.truth -> eval.truth", "src.tracks -> eval.tracks",
                                "src.existence -> eval.existence", "src.pose -> eval.pose"])
    f = json.loads((tmp_path / "metrics.json").read_text())
    gt, fn, fp, idsw = 10, 2, 1, 1
    assert f["truth_objects"] == gt and f["misses"] == fn and f["false_positives"] == fp
    assert f["id_switches"] == idsw
    assert abs(f["mota"] - (1 - (fn + fp + idsw) / gt)) < 5e-5  # figures are rounded to 4 decimals
    assert abs(f["motp_m"] - (4 * 1.0 + 1 * 0.0 + 3 * 0.5) / 8) < 5e-5  # figures are rounded to 4 decimals
    # IDF1: the best one-to-one id map gives mover 1 to track 7 (5 frames) -> IDTP 5,
    # hypotheses 5 (track 7) + 1 (track 9) + 3 (track 8) = 9 -> 2 * 5 / (10 + 9)
    assert abs(f["idf1"] - 2 * 5 / (gt + 9)) < 5e-5  # figures are rounded to 4 decimals
    by_id = {r["id"]: r for r in f["tracks"]}
    assert by_id[7]["pos_err_m"] == (4 * 1.0 + 0.0) / 5 and by_id[8]["pos_err_m"] == 0.5
    assert f["longest_track_id"] == 7 and f["speed_err_mps"] == 0.0
    # false tracks: 9 (1 turn, confirmed) and 11 (2 turns)
    assert f["false_tracks"] == 2 and f["false_track_max_turns"] == 2 and f["false_tracks_confirmed"] == 2
    assert (tmp_path / "tracks.png").stat().st_size > 0 and (tmp_path / "existence.png").stat().st_size > 0
