"""eval.TrackingEvaluator never scores tracks against a truth in another frame (issue 24 item 8):
tracks in ``radar`` (a tracker without a pose), truth in ``map``: the turns are left out,
counted and named in one ERROR line, and no MOTA is computed from them."""

from __future__ import annotations

import json
import logging

import numpy as np
import pytest

from impala_eval.tracking.component import TrackingEvaluator
from impala_flow.msgs import Pose2D
from impala_flow.testing import ScriptedSource, run_components
from impala_msgs import ObjectStates, TrackExistence

S = 1_000_000_000
RADAR = np.array([30.0, -10.0])  # the radar's position in the map (heading 0)


def _script(track_frame: str, tracks_first: bool = False):
    """One mover along y = 20 at 5 m/s; the tracker follows it exactly, in ``track_frame``
    (``radar``: the mover's position minus the radar's)."""
    script = []
    for k in range(0, 101):
        xy = np.array([[-25 + 0.5 * k, 20.0]])
        script.append((k * S // 10 + (1 if tracks_first else 0), "truth",
                       ObjectStates(np.array([1]), xy, np.array([[5.0, 0.0]]), frame="map")))
    script.append((0, "pose", Pose2D(*RADAR, 0.0, frame="map")))
    for k in range(1, 11):
        xy = np.array([[-25 + 5.0 * k, 20.0]]) - (RADAR if track_frame == "radar" else 0.0)
        script.append((k * S, "tracks", ObjectStates(np.array([7]), xy, np.array([[5.0, 0.0]]), frame=track_frame)))
        script.append((k * S, "existence", TrackExistence(np.array([7]), xy, np.array([0.9]), np.array([True]),
                                                          frame=track_frame)))
    script.sort(key=lambda s: s[0])
    return script


def _run(tmp_path, script):
    ev = TrackingEvaluator("eval", report=str(tmp_path), range_max_m=200.0)
    summary = run_components(ScriptedSource("src", script), ev,
                             connections=["src.truth -> eval.truth", "src.tracks -> eval.tracks",
                                          "src.existence -> eval.existence", "src.pose -> eval.pose"])
    return summary, json.loads((tmp_path / "metrics.json").read_text())


def test_tracks_in_the_truth_frame_score_perfectly(tmp_path):
    summary, f = _run(tmp_path, _script("map"))
    assert f["mota"] == 1.0 and f["misses"] == 0 and f["false_positives"] == 0  # by construction
    assert "unscored_turns" not in f and "frame_errors" not in f
    assert "unscored_turns" not in summary.extra["eval"]


@pytest.mark.parametrize("tracks_first", [False, True])
def test_tracks_in_another_frame_are_not_scored_and_say_so(tmp_path, caplog, tracks_first):
    with caplog.at_level(logging.ERROR):
        summary, f = _run(tmp_path, _script("radar", tracks_first))
    # before: MOTA -0.75 computed silently from radar-frame tracks against map-frame truth
    assert "mota" not in f
    assert f["unscored_turns"] == 10 and f["unscored_existence"] == 10 and f["false_tracks"] == 0
    assert summary.extra["eval"]["unscored_turns"] == 10
    errors = [r.getMessage() for r in caplog.records if r.levelno >= logging.ERROR]
    assert len(errors) == 2  # one line per input (tracks, existence), not one per turn
    line = next(e for e in errors if "input 'tracks'" in e)
    assert "'radar'" in line and "'map'" in line and f"t={S} ns" in line and "\n" not in line
    assert f["frame_errors"]["tracks"] == line
