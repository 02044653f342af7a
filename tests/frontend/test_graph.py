"""The front-end chain wired as in graphs/frontend.yaml, and the report's figures."""

from collections import Counter
from pathlib import Path

import numpy as np

from impala_flow._session import Session
from impala_flow.cli import main
from impala_flow.io import MissionReader
from impala_flow.testing import ScriptedSource, run_components
from impala_msgs import RadarBeam, Speed
from impala_radar.ego_velocity.component import EgoVelocity
from impala_radar.pairer.component import FuzzyPairer
from impala_radar.panoramic.component import PanoramicBuilder
from impala_radar.report.component import FrontendReport
from impala_radar.simulator.presets import IMPALA
from impala_radar.speckle.component import SpeckleFilter

from ._scenes import target_beams

GRAPH = Path(__file__).resolve().parents[2] / "graphs" / "frontend.yaml"


def test_frontend_graph_on_a_recorded_mission(tmp_path):
    """graphs/frontend.yaml as the evaluation graphs are run (``mission`` and ``out``): one panoramic
    image and one filtered image per antenna turn of the mission, recorded under ``out``, and the figures."""
    mission, out = tmp_path / "beynes.mcap", tmp_path / "fe"
    assert main(["simulate", "beynes", "-o", str(mission), "--duration", "3s", "--no-progress"]) == 0
    spec = Session().load(str(GRAPH), variables={"mission": str(mission), "out": str(out)})
    assert {c.type for c in spec.components.values()} >= {
        "radar.FuzzyPairer", "radar.EgoVelocity", "radar.PanoramicBuilder", "radar.SpeckleFilter",
        "radar.FrontendReport"}
    assert main(["run", str(GRAPH), "--var", f"mission={mission}", "--var", f"out={out}", "--no-progress"]) == 0
    with MissionReader(mission) as r:
        turns = {m.data.turn for m in r.messages(["radar/beams"])}
    with MissionReader(out / "frontend.mcap") as r:
        counts = Counter(m.topic for m in r.messages())
    assert len(turns) >= 2
    assert counts["panoramic/scan"] == counts["speckle/filtered"] == counts["ego/speed"] == len(turns)
    for name in ("ppi.png", "doppler.png", "pairs.png"):
        assert (out / name).stat().st_size > 10_000


def test_chain_and_report(tmp_path):
    rng = np.random.default_rng(21)
    samples = []
    for turn in range(2):
        up, down, az, _ = target_beams(rng, n_beams=360, speed_mps=3.0, n_static=(2, 3), n_movers=(0, 1),
                                       snr_db=(15.0, 30.0))
        t_ns = 10_000_000 + (turn * 360 + np.arange(360)) * 2_777_778
        samples += [(int(t_ns[i]), "beams", RadarBeam(float(az[i]), turn, i, up[i], down[i], IMPALA))
                    for i in range(360)]
    samples += [(t, "odo", Speed(3.0)) for t in range(0, 2_020_000_000, 20_000_000)]
    samples.sort(key=lambda s: s[0])
    report = FrontendReport("report", path=str(tmp_path))
    ego = EgoVelocity("ego")
    run_components(ScriptedSource("src", samples), FuzzyPairer("pairer"), ego, PanoramicBuilder("pano"),
                   SpeckleFilter("speckle", looks=2), report,
                   connections=["src.beams -> pairer.beams", "src.odo -> pairer.speed",
                                "pairer.detections -> ego.detections", "src.beams -> pano.beams",
                                "ego.speed -> pano.odometer", "pano.image -> speckle.image",
                                "src.beams -> report.beams", "pairer.detections -> report.detections",
                                "ego.speed -> report.speed", "pano.image -> report.image",
                                "speckle.filtered -> report.filtered"])
    assert abs(ego.last_fit.speed_mps - 3.0) < 0.1
    for name in ("ppi.png", "doppler.png", "pairs.png"):
        assert (tmp_path / name).stat().st_size > 10_000
