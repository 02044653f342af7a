"""impala-flow: timestamped robotics dataflow, recorded to MCAP, replayed deterministically.

The public API of the engine. The engine knows nothing about radar: the radar chain
lives in plugins registered through the ``impala_flow`` entry point group.
"""

from importlib.metadata import PackageNotFoundError, version

from .clock import FakeClock, MissionClock, ReplayClock
from .component import REQUIRED, Component, Input, Output, Param, ParamError, Periodic, Source
from .executor import OfflineExecutor, run_offline
from .graph import GraphError
from .network import Connection, CycleError, Network
from .ports import EmptyInput, InputPort, OutOfHistory, OutputPort
from .runtime import RealTimeExecutor
from .sample import Sample
from .session import Session
from .summary import ComponentError, RunSummary

try:
    __version__ = version("impala-flow")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0"

__all__ = [
    "Sample", "Component", "Source", "Input", "Output", "Param", "Periodic", "REQUIRED",
    "ParamError", "Network", "Connection", "CycleError", "OfflineExecutor", "run_offline",
    "ReplayClock", "MissionClock", "FakeClock", "RunSummary", "ComponentError",
    "InputPort", "OutputPort", "EmptyInput", "OutOfHistory", "RealTimeExecutor", "Session", "GraphError",
    "__version__",
]
