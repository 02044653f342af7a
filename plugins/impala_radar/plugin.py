"""Entry point of the radar plugin: radar sources (simulator, dataset readers, the live
``NavtechRadar``), front-end components, the ``simulate`` mission source, CLI commands.

Layout: docs/plugins.md, "Layout of a plugin" (``<algorithm>/component.py`` + ``core.py``);
component modules are imported inside the hooks, so loading the plugin stays cheap.
"""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl, require

#: the libraries of this plugin's extra (pip install 'impala-flow[radar]'), checked before any hook runs
REQUIRES = ("scipy", "cv2", "PIL", "matplotlib", "numba")


@hookimpl
def impala_flow_register(registry: Any) -> None:
    require(*REQUIRES)
    from .datasets.component import BoreasScans, OxfordScans, RadiateScans
    from .simulator.component import Simulator

    registry.add_component(Simulator)
    registry.add_component(OxfordScans)
    registry.add_component(BoreasScans)
    registry.add_component(RadiateScans)
    from .navtech.component import NavtechRadar

    registry.add_component(NavtechRadar)
    from .ego_velocity.component import EgoVelocity
    from .extractor.component import PeakExtractor
    from .pairer.component import FuzzyPairer
    from .panoramic.component import PanoramicBuilder
    from .report.component import FrontendReport
    from .speckle.component import SpeckleFilter

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
    require(*REQUIRES)
    from .commands import add_commands

    add_commands(subparsers)
