"""Simulated missions for the DATMO tests: scenario files derived from the shipped ones
(graphs/scenarios/datmo.yaml, traffic.yaml), simulated once per session with the command a
user runs, then replayed through graphs/datmo.yaml (Session) like ``impala-flow run``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from impala_flow._session import Session
from impala_flow.cli import main
from impala_flow.io import MissionReader
from impala_radar.simulator.scenario import scenario_path

from ..conftest import built_once

GRAPH = Path(__file__).resolve().parents[2] / "graphs" / "datmo.yaml"


def simulate(tmp: Path, scenario: str, name: str, seed: int, duration_s: float, **changes) -> Path:
    """``impala-flow simulate`` of ``scenario`` with top-level keys changed (start_t_ns, speed_mps...)."""
    spec = yaml.safe_load(scenario_path(scenario).read_text())
    spec.update(changes)
    path = tmp / f"{name}.yaml"
    path.write_text(yaml.safe_dump(spec))
    out = tmp / f"{name}.mcap"
    assert main(["simulate", str(path), "-o", str(out), "--seed", str(seed), "--duration", f"{duration_s}s"]) == 0
    return out


def run_datmo(mission: Path, out: Path, overrides: tuple[str, ...] = ()) -> dict:
    """graphs/datmo.yaml on a mission; the evaluator's metrics.json."""
    session = Session()
    spec = session.load(GRAPH, overrides=list(overrides), variables={"mission": str(mission), "out": str(out)})
    session.run(spec)
    return json.loads((out / "metrics.json").read_text())


def read(path: Path, topic: str) -> list[tuple[int, object]]:
    from impala_flow.io import CodecRegistry
    from impala_tracking.types import MoverDetections

    codecs = CodecRegistry.with_standard_types()
    codecs.add_type(MoverDetections, plugin="tracking")
    with MissionReader(path, codecs=codecs) as reader:
        return [(m.t_ns, m.data) for m in reader.messages([topic])]


def truth_of(mission: Path, mover: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t_ns, xy, v) of one mover from the recorded simulator truth (movers/states)."""
    rows = [(t, s.xy_m[list(s.ids).index(mover)], s.v_xy_mps[list(s.ids).index(mover)])
            for t, s in read(mission, "movers/states") if mover in s.ids]
    return (np.array([r[0] for r in rows], np.int64), np.array([r[1] for r in rows]), np.array([r[2] for r in rows]))


@pytest.fixture(scope="session")
def missions(tmp_path_factory):
    """The failure-mode missions (seeds not used for tuning), simulated once per test run."""

    def build(tmp: Path) -> None:
        made = {
            # mover 1 (20 km/h, y = 23.25) passes abeam of the static radar at t = 25.4 s: zero radial speed
            "tangential": simulate(tmp, "datmo", "tangential", 7, 32.0),
            # two cars reach the crossroads (33.25, 23.25) together at t ~ 131.6 s: one beam, two Dopplers
            "crossing": simulate(tmp, "datmo", "crossing", 7, 18.0, start_t_ns=120_000_000_000),
            # the radar at 7 m/s followed 35 m behind by a car at 7 m/s: zero relative Doppler (Fig. 17, A)
            "follower": simulate(tmp, "traffic", "follower", 7, 16.0, start_t_ns=15_000_000_000, speed_mps=7.0,
                                 vehicle={"rest_at_ends": False}),
        }
        assert all(path == tmp / f"{name}.mcap" for name, path in made.items())

    tmp = built_once(tmp_path_factory, "datmo-missions", build)
    return {name: tmp / f"{name}.mcap" for name in ("tangential", "crossing", "follower")}
