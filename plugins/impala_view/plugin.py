"""Entry point of the view plugin: registers view.FoxgloveBridge, the Foxglove mirrors every
recording writes beside its streams (``registry.add_mirror``) and the ``view`` command.

Nothing Foxglove is imported here: the mirror factories import :mod:`impala_view.mirrors`
(protobuf) when a recording first needs them, the bridge imports the SDK when it starts, so
loading the plugin (e.g. to build the command line) stays cheap.
"""

from __future__ import annotations

from typing import Any

import impala_msgs
from impala_flow import msgs
from impala_flow.io import TRANSFORMS, Mirror
from impala_flow.plugins import hookimpl, require

#: the libraries of this plugin's extra (pip install 'impala-flow[view]'), checked before any hook runs
REQUIRES = ("foxglove", "foxglove_schemas_protobuf")  # the latter brings protobuf

__all__ = ["MIRRORED"]

#: the types with a Foxglove schema (:mod:`impala_view.mirrors`); every other one gets the JSON view
MIRRORED: tuple[type, ...] = (msgs.Pose2D, msgs.Trajectory2D, msgs.Grid, msgs.Points2D, impala_msgs.ObjectStates,
                              impala_msgs.RadarDetections, impala_msgs.RadarScan)


def _schema_mirror(t: type) -> Mirror | None:
    from .mirrors import mirror_for

    return mirror_for(t)


def _json_mirror(t: type) -> Mirror | None:
    from .mirrors import json_mirror

    return json_mirror(t)


def _tf_mirror(key: Any) -> Mirror:
    from .mirrors import tf_mirror

    return tf_mirror(key)


@hookimpl
def impala_flow_register(registry: Any) -> None:
    require(*REQUIRES)
    registry.add_component(f"{__package__}.bridge:FoxgloveBridge")  # imported when a graph uses it
    for t in MIRRORED:
        registry.add_mirror(t, _schema_mirror)
    registry.add_mirror(object, _json_mirror)
    registry.add_mirror(TRANSFORMS, _tf_mirror)


@hookimpl
def impala_flow_add_commands(subparsers: Any) -> None:
    require(*REQUIRES)
    from .commands import add_commands

    add_commands(subparsers)
