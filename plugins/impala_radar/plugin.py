"""Entry point of the radar plugin: radar sources (simulator, dataset readers, the live
``NavtechRadar``), front-end components, the ``simulate`` mission source, CLI commands.

Layout: docs/plugins.md, "Layout of a plugin" (``<algorithm>/component.py`` + ``core.py``);
components are registered by where they live (``module:Class``), imported when a graph uses them,
so loading the plugin stays cheap.
"""

from __future__ import annotations

from typing import Any

from impala_flow.plugins import hookimpl, require

#: the libraries of this plugin's extra (pip install 'impala-flow[radar]'), checked before any hook runs
REQUIRES = ("scipy", "cv2", "PIL", "matplotlib", "numba")


@hookimpl
def impala_flow_register(registry: Any) -> None:
    require(*REQUIRES)
    for where in ("simulator.component:Simulator", "datasets.component:OxfordScans",
                  "datasets.component:BoreasScans", "datasets.component:RadiateScans",
                  "navtech.component:NavtechRadar", "pairer.component:FuzzyPairer",
                  "ego_velocity.component:EgoVelocity", "panoramic.component:PanoramicBuilder",
                  "speckle.component:SpeckleFilter", "extractor.component:PeakExtractor",
                  "report.component:FrontendReport"):
        registry.add_component(f"{__package__}.{where}")  # imported when a graph uses it
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
