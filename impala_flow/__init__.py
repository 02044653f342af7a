"""impala-flow: timestamped robotics dataflow, recorded to MCAP, replayed deterministically.

The public API. A plugin imports only these modules (a contract in pyproject.toml checks it):

- ``impala_flow``: components, ports, parameters, samples, networks, executors, clocks (and ``ClockSync``, a
  device clock mapped to mission time), the
  session (which also checks a graph without running it: ``Session.problems``,
  ``Session.graph_files``), errors, located YAML for a plugin's own files, the
  ``closest``/``did_you_mean`` hints of every one-line error;
- :mod:`impala_flow.msgs`: the message contract and the domain-free geometry types;
- :mod:`impala_flow.io`: recording and replay (MCAP readers, writers, codecs, JSON views);
- :mod:`impala_flow.plugins`: ``hookimpl`` and the hooks (:mod:`impala_flow.hookspecs`);
- :mod:`impala_flow.cli` and :mod:`impala_flow.cli.helpers`: what a plugin's command needs;
- :mod:`impala_flow.testing`: the test kit (also a pytest plugin).

Every other module is private (its name starts with ``_``). The engine knows nothing about
radar: the radar chain lives in plugins registered through the ``impala_flow`` entry point group.
"""

from typing import TYPE_CHECKING

from ._clock import FakeClock, MissionClock, ReplayClock
from ._component import REQUIRED, Component, Input, Output, Param, ParamError, Periodic, Source
from ._network import Connection, CycleError, Network
from ._offline import OfflineExecutor, run_offline
from ._paths import output_clash
from ._ports import EmptyInput, InputPort, OutOfHistory, OutputPort
from ._sample import Sample
from ._session import Session
from ._spec import GraphError, GraphSpec, closest, did_you_mean
from ._summary import ComponentError, RunSummary
from ._version import __version__
from ._yamlloc import YamlError, load_yaml, location

if TYPE_CHECKING:  # imported on first use (__getattr__ below)
    from ._clocksync import ClockSync
    from ._realtime import RealTimeExecutor

#: the modules a plugin may import; every other module of the engine is private (its name
#: starts with ``_``): the ``private_modules`` import contract and tests/test_public_api.py keep it so
PUBLIC_MODULES = (
    "impala_flow", "impala_flow.msgs", "impala_flow.io", "impala_flow.plugins", "impala_flow.hookspecs",
    "impala_flow.cli", "impala_flow.cli.helpers", "impala_flow.testing",
)

__all__ = [
    "Sample", "Component", "Source", "Input", "Output", "Param", "Periodic", "REQUIRED",
    "ParamError", "Network", "Connection", "CycleError", "OfflineExecutor", "run_offline",
    "ReplayClock", "MissionClock", "FakeClock", "ClockSync", "RunSummary", "ComponentError",
    "InputPort", "OutputPort", "EmptyInput", "OutOfHistory", "RealTimeExecutor", "Session", "GraphError",
    "YamlError", "load_yaml", "location", "output_clash", "GraphSpec", "closest", "did_you_mean",
    "PUBLIC_MODULES", "__version__",
]

#: public names whose modules are imported when first used (a command that runs no live graph never compiles them)
_LAZY = {"ClockSync": "._clocksync", "RealTimeExecutor": "._realtime"}


def __getattr__(name: str) -> object:
    where = _LAZY.get(name)
    if where is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(where, __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_LAZY))
