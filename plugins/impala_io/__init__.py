"""Recording and replay of missions (MCAP): io.Recorder, io.Replayer."""

from .recorder import Recorder
from .replayer import TIME_JUMP, Replayer

__all__ = ["Recorder", "Replayer", "TIME_JUMP"]
