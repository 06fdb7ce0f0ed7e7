"""`NlpSlots`: a planner's collocation NLPs, one set per obstacle slot count.

Every obstacle slot of an NLP costs its clearance constraints and their derivatives at
every constrained point, filled or not (2.3-2.7x CPU time on 1-2 obstacle scenes with 8
slots rather than 1-2, measured), so a query solves the NLPs of its own slot count
(`NlpSlots.slots`: the smallest power of two not below its obstacle count, at most the
planner's capacity), each made on first use and then kept
(`geosyn.metrics.planning.planner.Planner`: with the planner, ``prebuild``, or on the
first query that collocates with a budget over `geosyn.metrics.planning.query.
MIN_COLLOCATION`, or `Planner.prepare`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from geosyn.metrics.geodesic.collocation import Collocation
from geosyn.metrics.shaping.obstacle import ObstacleTerm
from geosyn.robots.robot import CollisionSphere, Robot

if TYPE_CHECKING:
    from geosyn.metrics.base import Metric

__all__ = ["NlpSlots"]


class NlpSlots:
    """The obstacle terms and collocations of one planner, per slot count.

    Args:
        metric: the planner's metric.
        robot: its robot (binds the terms).
        full: the planner's term with all ``capacity`` slots.
        spheres: the terms' collision spheres.
        distance: the terms' signed distance (`ObstacleTerm`).
        margin, compile, hessian, tol, softmin: the collocations' (`Collocation`).
    """

    def __init__(self, metric: Metric, robot: Robot, full: ObstacleTerm,
                 spheres: Sequence[CollisionSphere], distance: str, *, margin: float,
                 compile: bool | str, hessian: str, tol: float,
                 softmin: float | None) -> None:  # fmt: skip
        self.metric, self.robot, self.full = metric, robot, full
        self._spheres, self._distance = spheres, distance
        self._margin, self._compile, self._hessian = margin, compile, hessian
        self._tol, self._softmin = tol, softmin
        self._terms: dict[int, ObstacleTerm] = {full.capacity: full}
        self._collocations: dict[tuple[int, int, int], Collocation] = {}

    def slots(self, count: int) -> int:
        """Obstacle slots of the NLPs a query with ``count`` obstacles solves (module
        docstring): the smallest power of two >= ``count`` (at least 1), at most the
        full term's capacity."""
        cap = self.full.capacity
        return cap if count >= cap else min(cap, 1 << max(count - 1, 0).bit_length())

    def term(self, count: int) -> ObstacleTerm:
        """The obstacle term of ``slots(count)`` slots (made and bound on first use)."""
        cap = self.slots(count)
        if cap not in self._terms:
            term = ObstacleTerm((), capacity=cap, spheres=self._spheres, distance=self._distance)
            term.bind(self.robot)
            self._terms[cap] = term
        return self._terms[cap]

    def built(self) -> int:
        """How many collocations exist (any slot count)."""
        return len(self._collocations)

    def has(self, capacity: int) -> bool:
        """Whether a collocation of ``capacity`` slots exists."""
        return any(key[0] == capacity for key in self._collocations)

    def collocation(self, term: ObstacleTerm, nodes: int, subdivisions: int = 1) -> Collocation:
        """The collocation on ``term`` (one of `term`'s) with ``nodes`` segments and
        ``subdivisions`` constrained points inside each (built on first use, then kept)."""
        key = (term.capacity, nodes, subdivisions)
        if key not in self._collocations:
            self._collocations[key] = Collocation(
                self.metric, nodes=nodes, clearance=term, margin=self._margin,
                compile=self._compile, hessian=self._hessian, tol=self._tol,
                softmin=self._softmin, subdivisions=subdivisions,
            )  # fmt: skip
        return self._collocations[key]
