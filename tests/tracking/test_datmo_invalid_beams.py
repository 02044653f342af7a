"""graphs/datmo.yaml on a mission with 10 % of its beams NaN (issue 24 item 10): before, the NaN
beams went through the pairer and the detector and launched 34 false tracks on the crossing
mission (2 on the clean one), nothing counted. Now they are dropped where they enter the pairer,
counted in the run summary, and the tracks are those of the clean mission's."""

from __future__ import annotations

import dataclasses
import json

import numpy as np

from impala_flow._session import Session
from impala_flow.io import MissionReader, MissionWriter, run_codecs

from .conftest import GRAPH


def _with_nan_beams(src, dst, fraction=0.1, seed=1) -> int:
    """A copy of the mission ``src`` with every bin of ``fraction`` of its beams NaN; how many."""
    rng = np.random.default_rng(seed)
    n = 0
    with MissionReader(src) as r, MissionWriter(dst, codecs=run_codecs()) as w:
        for topic in r.topics:
            w.add_topic(topic, r.topic_type(topic))
        for m in r.messages():
            d = m.data
            if m.topic == "radar/beams" and rng.random() < fraction:
                d = dataclasses.replace(d, up=np.full_like(d.up, np.nan))
                n += 1
            w.write(m.topic, m.t_ns, d)
    return n


def _run(mission, out):
    session = Session()
    summary = session.run(session.load(GRAPH, variables={"mission": str(mission), "out": str(out)}))
    return summary, json.loads((out / "metrics.json").read_text())


def test_nan_beams_are_dropped_and_counted_not_turned_into_false_tracks(missions, tmp_path):
    bad = tmp_path / "nan10.mcap"
    n_bad = _with_nan_beams(missions["crossing"], bad)
    _, clean = _run(missions["crossing"], tmp_path / "clean")
    summary, f = _run(bad, tmp_path / "nan10")
    assert summary.invalid() == {"pairer.beams": {"non-finite up": n_bad}} and n_bad > 500
    assert "INVALID at pairer.beams" in summary.format()
    assert summary.extra["pairer"]["partial_turns"] > 0  # the turns short of beams say so
    assert f["false_tracks"] <= clean["false_tracks"] + 1
    assert f["mota"] >= clean["mota"] - 0.1
