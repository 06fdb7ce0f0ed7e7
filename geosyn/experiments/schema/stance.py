"""Config sections of a floating-base robot standing on the ground: the ``stance`` (the
contact frames held fixed, their contact points, the friction the controllers assume) and
the ``stance_synergy`` reference (the ``whole_body`` controller is in `controllers`).

The stance is built once per run (`geosyn.metrics.stance.Stance`) and handed to the
reference and the controllers; the simulation puts a contact sphere at every point.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field

from geosyn.controllers.whole_body import WholeBodyController
from geosyn.controllers.whole_body_reference import StanceSynergyReference
from geosyn.experiments.schema.section import Section, Strict, python_defaults
from geosyn.experiments.schema.values import FiniteFloat, NonNegFloat, PositiveFloat
from geosyn.metrics.stance_synergy import StanceSynergy

_WHOLE_BODY = python_defaults(WholeBodyController)
_REFERENCE = python_defaults(StanceSynergyReference, StanceSynergy)

Point = Annotated[list[FiniteFloat], Field(min_length=3, max_length=3)]


class StanceConfig(Strict):
    """The contact frames held on the ground and their contact points.

    ``points`` (P, 3) [m] are in each frame; three or more make soles (the frames' 6-D
    motion is held), one a point foot (3-D). ``mu`` (friction coefficient, keep a margin
    below the floor's 1.0) and ``f_min`` [N] (smallest normal force per point) are the
    whole-body controllers' friction cone and loading.
    """

    frames: Annotated[list[str], Field(min_length=1)]
    points: Annotated[list[Point], Field(min_length=1, max_length=8)] = [[0.0, 0.0, 0.0]]
    mu: PositiveFloat = _WHOLE_BODY["mu"]
    f_min: NonNegFloat = _WHOLE_BODY["f_min"]

    @property
    def point_feet(self) -> bool:
        """One contact point per frame: the frames hold positions only."""
        return len(self.points) == 1


class SynergyDirection(Strict):
    """A whole-body wish (nv,): the base twist (6,) [m/s, rad/s, base frame] and joint
    rates by name [rad/s] (others 0); projected onto the stance (`StanceSynergy`)."""

    base: Annotated[list[FiniteFloat], Field(min_length=6, max_length=6)] = [0.0] * 6
    joints: dict[str, FiniteFloat] = {}


class StanceSynergyReferenceConfig(Section):
    """`StanceSynergyReference`: the stance synergy from the standing start along
    ``direction``, played over ``duration`` [s] from ``t0`` [s] with a minimum-jerk timing."""

    builds = (StanceSynergyReference, StanceSynergy)
    type: Literal["stance_synergy"]
    direction: SynergyDirection
    duration: PositiveFloat
    t0: NonNegFloat = _REFERENCE["t0"]
    steps: Annotated[int, Field(ge=1, le=10_000)] = _REFERENCE["steps"]


__all__ = [
    "StanceConfig",
    "StanceSynergyReferenceConfig",
    "SynergyDirection",
]
