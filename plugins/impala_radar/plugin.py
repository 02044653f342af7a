"""Entry point of the radar plugin: radar sources, front-end components, the ``simulate``
mission source, CLI commands."""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl


@hookimpl
def impala_flow_register(registry: Any) -> None:
    from .sources import BoreasScans, OxfordScans, RadiateScans, Simulator

    registry.add_component(Simulator)
    registry.add_component(OxfordScans)
    registry.add_component(BoreasScans)
    registry.add_component(RadiateScans)
    from .frontend import EgoVelocity, FuzzyPairer, PanoramicBuilder, PeakExtractor, SpeckleFilter
    from .frontend.report import FrontendReport

    registry.add_component(FuzzyPairer)
    registry.add_component(EgoVelocity)
    registry.add_component(PanoramicBuilder)
    registry.add_component(SpeckleFilter)
    registry.add_component(PeakExtractor)
    registry.add_component(FrontendReport)
    registry.add_mission_source("simulate", _simulate_mission,
                                help="simulate a scenario (name or YAML file) with a seed, for a duration")


def _simulate_mission(session: Any, scenario: str, path: str, *, seed: int | None = None,
                      duration_s: float | None = None) -> None:
    from .commands import simulate_mission  # the command's own code: same bytes as `impala-flow simulate`

    simulate_mission(session, scenario, path, seed=seed, duration_s=duration_s)


@hookimpl
def impala_flow_add_commands(subparsers: Any) -> None:
    from .commands import add_commands

    add_commands(subparsers)
