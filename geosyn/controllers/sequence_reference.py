"""`SequenceReference`: references played one after the other (e.g. geodesics through a
sequence of goals)."""

from __future__ import annotations

from collections.abc import Sequence

from geosyn.controllers.reference import Reference, ReferenceSample
from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector

__all__ = ["SequenceReference"]


class SequenceReference(Reference):
    """References played one after the other: segment ``i`` runs from its ``t0`` until the
    next one's; before the first it holds the first's start, after the last its goal.

    Args:
        segments: the references, in order, each with ``t0`` at the end of the previous
            one (``t0 + duration``), all of dimension ``n``.

    Raises:
        InvalidArgument: no segment, dimensions that differ, or a segment that does not
            start where the previous one ends (to 1e-9 s).
    """

    def __init__(self, segments: Sequence[Reference]) -> None:
        self.segments = list(segments)
        if not self.segments:
            raise InvalidArgument("segments must hold at least one reference, got none")
        self.n = self.segments[0].n
        for i, (prev, seg) in enumerate(zip(self.segments, self.segments[1:], strict=False)):
            if seg.n != self.n:
                raise InvalidArgument(f"segments[{i + 1}] has n={seg.n}, segments[0] has {self.n}")
            end = prev.t0 + prev.duration
            if abs(seg.t0 - end) > 1e-9:
                raise InvalidArgument(
                    f"segments[{i + 1}].t0={seg.t0} [s] must equal the end of segments[{i}],"
                    f" {end} [s]"
                )
        self.t0 = self.segments[0].t0
        last = self.segments[-1]
        self.duration = last.t0 + last.duration - self.t0

    def sample(self, t: float) -> ReferenceSample:
        """Reference ``(q, v, a)`` at controller time ``t`` [s] (that of the segment
        running at ``t``; the goal at rest after the last)."""
        for seg in self.segments:
            if t < seg.t0 + seg.duration:
                return seg.sample(t)
        return self.segments[-1].sample(t)

    def goal(self) -> Vector:
        """(n,) the last goal [rad]."""
        return self.segments[-1].goal()
