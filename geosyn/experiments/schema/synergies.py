"""Config sections of the synergies (explicit, designed, extracted by PGA) and of the
reference a controller tracks (a synergy combination, the geodesic to a goal, or a
sequence of geodesics through goals).

Reference defaults come from the calls they configure: `GeodesicSynergy.trajectory` and
`combine` (combination) or `geosyn.metrics.exp` and `log` (log) for ``duration``,
``steps`` and ``q_start``, `GeodesicReference` for ``time_scale`` and ``rest_to_rest``
(True: the quintic rest-to-rest time law, so the reference starts and ends at rest; False:
the geodesic's constant speed, which steps to rest at the end).
"""

from __future__ import annotations

from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from geosyn.controllers import GeodesicReference
from geosyn.experiments.schema.section import Section, Strict, python_defaults
from geosyn.experiments.schema.stance import StanceSynergyReferenceConfig
from geosyn.experiments.schema.values import FiniteFloat, JointVector, PositiveFloat, Vec3
from geosyn.metrics import exp, log
from geosyn.metrics.planning import EndEffectorGoal, Planner
from geosyn.synergies import GeodesicSynergy, combine, orthonormal_synergies

Count = Annotated[int, Field(ge=1)]
Steps = Annotated[int, Field(ge=2, le=100_000)]


class ExplicitSynergy(Strict):
    q0: JointVector
    v0: JointVector


class ExplicitSynergies(Strict):
    """Synergies given by their base configuration and initial velocity."""

    type: Literal["explicit"]
    items: Annotated[list[ExplicitSynergy], Field(min_length=1)]


class DesignedSynergies(Section):
    """``orthonormal_synergies(metric, q0, k)``: G-orthonormal, ordered by hand motion."""

    builds = (orthonormal_synergies,)
    type: Literal["designed"]
    q0: JointVector
    k: Count
    frame: str | None = python_defaults(orthonormal_synergies)["frame"]


class PGASynergies(Strict):
    """PGA of demonstrations: recorded trajectories read from ``demonstrations`` (an NPZ
    or CSV file, `geosyn.synergies.human.load_demonstrations`), or generated ones:
    ``n_demos`` endpoints of geodesics from ``q0`` with random G-orthonormal-basis
    velocities of standard deviation ``spread`` over the first ``latent`` designed
    directions (the config's own generator: its defaults are the config's). Give exactly
    one of ``q0`` and ``demonstrations``."""

    type: Literal["pga"]
    q0: JointVector | None = None
    demonstrations: str | None = Field(
        None,
        description="NPZ, CSV or Parquet file of recorded trajectories (relative to the working"
        " directory); CSV columns q[<joint>] or <joint>, an optional trajectory column",
    )
    key: str | None = Field(None, description="the NPZ array to read (default: every 2-D one)")
    k: Count
    n_demos: Annotated[int, Field(ge=2, le=500)] = 20
    spread: PositiveFloat = 0.5
    latent: Count = 2

    @model_validator(mode="after")
    def _one_source(self) -> PGASynergies:
        if (self.q0 is None) == (self.demonstrations is None):
            raise ValueError("give exactly one of q0 (generated demonstrations) or demonstrations")
        return self


SynergyConfig = Annotated[
    ExplicitSynergies | DesignedSynergies | PGASynergies, Field(discriminator="type")
]

_COMBINATION = python_defaults(GeodesicSynergy.trajectory, combine, GeodesicReference)
_LOG = python_defaults(exp, log, GeodesicReference)


class CombinationReference(Section):
    """``combine(synergies, weights, q_start)`` traversed over ``duration * time_scale``."""

    builds = (GeodesicSynergy.trajectory, combine, GeodesicReference)
    type: Literal["combination"]
    weights: Annotated[list[FiniteFloat], Field(min_length=1)]
    q_start: JointVector | None = _COMBINATION["q_start"]
    duration: PositiveFloat = _COMBINATION["duration"]
    time_scale: PositiveFloat = _COMBINATION["time_scale"]
    steps: Steps = _COMBINATION["steps"]
    rest_to_rest: bool = _COMBINATION["rest_to_rest"]


class LogReference(Section):
    """The geodesic from ``q_start`` to ``goal`` (``log`` then ``exp``)."""

    builds = (exp, log, GeodesicReference)
    type: Literal["log"]
    q_start: JointVector
    goal: JointVector
    duration: PositiveFloat = _LOG["duration"]
    time_scale: PositiveFloat = _LOG["time_scale"]
    steps: Steps = _LOG["steps"]
    rest_to_rest: bool = _LOG["rest_to_rest"]


class GoalsReference(Section):
    """A sequence of geodesics: ``q_start`` to ``goals[0]``, then to ``goals[1]``, ...; each
    segment takes ``duration`` [s] (one value, or one per goal) times ``time_scale``
    (``kind: tracking`` only)."""

    builds = (exp, log, GeodesicReference)
    type: Literal["goals"]
    q_start: JointVector
    goals: Annotated[list[JointVector], Field(min_length=1)]
    duration: PositiveFloat | Annotated[list[PositiveFloat], Field(min_length=1)] = _LOG["duration"]
    time_scale: PositiveFloat = _LOG["time_scale"]
    steps: Steps = _LOG["steps"]
    rest_to_rest: bool = _LOG["rest_to_rest"]

    def durations(self) -> list[float]:
        """Geodesic duration of each segment [s] (before time scaling)."""
        if isinstance(self.duration, list):
            return list(self.duration)
        return [self.duration] * len(self.goals)


_PLANNED = python_defaults(Planner, Planner.plan, GeodesicReference)
_EE_GOAL = python_defaults(EndEffectorGoal)


class EndEffectorGoalConfig(Strict):
    """An end-effector goal (`geosyn.metrics.planning.EndEffectorGoal`): where a frame's
    origin should be, optionally with its orientation (roll-pitch-yaw, as URDF), each
    within a tolerance. The planner solves it by inverse kinematics within the joint
    limits and clear of the scene, plans to ``solutions`` distinct solutions and keeps
    the lowest-energy plan."""

    position: Vec3
    rpy: Vec3 | None = None
    frame: str | None = _EE_GOAL["frame"]
    position_tolerance: PositiveFloat = _EE_GOAL["position_tolerance"]
    orientation_tolerance: PositiveFloat = _EE_GOAL["orientation_tolerance"]
    solutions: Annotated[int, Field(ge=1, le=64)] = _EE_GOAL["solutions"]

    def to_goal(self) -> EndEffectorGoal:
        """The planner's goal."""
        options = {"frame": self.frame, "position_tolerance": self.position_tolerance,
                   "orientation_tolerance": self.orientation_tolerance,
                   "solutions": self.solutions}  # fmt: skip
        if self.rpy is None:
            return EndEffectorGoal(tuple(self.position), **options)  # type: ignore[arg-type]
        return EndEffectorGoal.from_rpy(self.position, self.rpy, **options)


class PlannedReference(Strict):
    """A collision-free minimum-energy path from ``q_start`` to ``goal`` around the scene's
    obstacles (`geosyn.metrics.planning.Planner`: collocation, RRT-Connect fallback),
    traversed in ``duration * time_scale`` (``kind: tracking`` only). The goal is a
    joint configuration or an end-effector goal (``{position: [x, y, z], rpy: ...}``)."""

    type: Literal["planned"]
    q_start: JointVector
    goal: JointVector | EndEffectorGoalConfig
    duration: PositiveFloat = _LOG["duration"]
    time_scale: PositiveFloat = _PLANNED["time_scale"]
    rest_to_rest: bool = _PLANNED["rest_to_rest"]
    margin: Annotated[float, Field(ge=0.0, allow_inf_nan=False)] = _PLANNED["margin"]
    nodes: Annotated[int, Field(ge=2, le=1000)] = _PLANNED["nodes"]
    budget: PositiveFloat = _PLANNED["budget"]

    def planner_goal(self) -> np.ndarray | EndEffectorGoal:
        """The goal as `Planner.plan` takes it: (nv,) joint positions [rad] or an
        `EndEffectorGoal`."""
        if isinstance(self.goal, EndEffectorGoalConfig):
            return self.goal.to_goal()
        return np.array(self.goal, dtype=np.float64)


ReferenceConfig = Annotated[
    CombinationReference
    | LogReference
    | GoalsReference
    | PlannedReference
    | StanceSynergyReferenceConfig,
    Field(discriminator="type"),
]

__all__ = [
    "CombinationReference",
    "DesignedSynergies",
    "EndEffectorGoalConfig",
    "ExplicitSynergies",
    "ExplicitSynergy",
    "GoalsReference",
    "LogReference",
    "PGASynergies",
    "PlannedReference",
    "ReferenceConfig",
    "SynergyConfig",
]
