"""Assembling the beams of a rotating radar into antenna turns."""

from __future__ import annotations

from impala_msgs import RadarBeam

__all__ = ["TurnBuffer"]

Turn = list[tuple[int, RadarBeam]]


class TurnBuffer:
    """Collects ``(t_ns, beam)`` until a turn is complete: at its last beam, or when a beam
    of the next turn arrives first (a turn with missing beams is still returned)."""

    def __init__(self) -> None:
        self._beams: Turn = []

    def add(self, t_ns: int, beam: RadarBeam) -> list[Turn]:
        """Add one beam; return the turns it completed (none, one, or two)."""
        done: list[Turn] = []
        if self._beams and beam.turn != self._beams[-1][1].turn:
            done.append(self.take())
        self._beams.append((t_ns, beam))
        if beam.index == beam.config.beams_per_turn - 1:
            done.append(self.take())
        return done

    def take(self) -> Turn:
        """The beams collected so far (a partial turn), emptying the buffer."""
        beams, self._beams = self._beams, []
        return beams
