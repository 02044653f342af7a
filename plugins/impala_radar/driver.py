"""Interface of a live rotating radar (:class:`RadarDriver`).

A live radar implements :class:`RadarDriver`: a :class:`~impala_flow.Source` with
``live = True`` whose ``generate()`` blocks on the hardware and yields one
``(t_ns, "beams", RadarBeam)`` per beam, stamped with ``self.now_ns()`` at acquisition
(the engine maps the monotonic clock to mission time; a receiver with its own clock sets
``clock_offset_ns``). Offline sources (simulator, dataset readers) yield the same messages
in time order, so every downstream graph runs unchanged on live, simulated or real data.
"""

from __future__ import annotations

from impala_flow import Output, Param, Source
from impala_msgs import RadarBeam

__all__ = ["RadarDriver"]


class RadarDriver(Source):
    """Interface of a live rotating radar: subclass, open the device in ``start()``, and
    yield ``(self.now_ns(), "beams", RadarBeam(...))`` per beam from ``generate()``."""

    live = True
    beams = Output(RadarBeam, doc="one beam per modulation period, stamped at acquisition")
    clock_offset_ns = Param(int, default=0, doc="added to the device's timestamps (its clock vs the mission clock)")
