"""Config sections of the metric: the kinetic-energy metric and its shaping terms.

Each term section stands for its `geosyn.metrics.shaping` class and takes its defaults
from that class's constructor.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from geosyn.experiments.schema.section import Section, Strict, python_defaults
from geosyn.experiments.schema.values import NonNegFloat, PositiveFloat, Vec3
from geosyn.metrics.shaping import JointLimitTerm, LoadTerm, ObstacleTerm

# frame None: the robot's end effector; mass None: the payload's (exactly one source)
_LOAD = python_defaults(LoadTerm, frame=None, mass=None)
_OBSTACLE = python_defaults(ObstacleTerm)
_JOINT_LIMIT = python_defaults(JointLimitTerm)


class LoadTermConfig(Section):
    """`LoadTerm`: either ``payload`` (index into ``scene.payloads``) or ``frame``+``mass``.

    ``inertia`` is the (3, 3) inertia about the centre of mass [kg m^2]; None: a solid
    ball of ``radius`` [m] (a point mass for radius 0).
    """

    builds = (LoadTerm,)
    type: Literal["load"]
    payload: Annotated[int, Field(ge=0)] | None = None
    frame: str | None = _LOAD["frame"]
    mass: PositiveFloat | None = _LOAD["mass"]
    com: Vec3 = _LOAD["com"]
    inertia: Annotated[list[Vec3], Field(min_length=3, max_length=3)] | None = _LOAD["inertia"]
    radius: NonNegFloat = _LOAD["radius"]

    @model_validator(mode="after")
    def _one_source(self) -> LoadTermConfig:
        if self.payload is None and self.mass is None:
            raise ValueError("give either payload (an index into scene.payloads) or mass [kg]")
        fields = type(self).model_fields
        own = ("frame", "mass", "com", "inertia", "radius")
        if self.payload is not None and any(
            getattr(self, n) != fields[n].get_default(call_default_factory=True) for n in own
        ):
            raise ValueError("give either payload or frame/mass/com/inertia/radius, not both")
        return self


class ObstacleTermConfig(Section):
    """`ObstacleTerm` over the scene's obstacles (one slot per obstacle). ``spheres``: null
    (the robot's collision spheres, along its capsules) or ``file`` (spheres covering its
    file's collision geometry, more of them). ``length``/``epsilon`` shape the ``rmp`` profile, ``gate_speed``
    the ``approach`` gate; ``distance`` picks the signed distance (``exact``: C1,
    ``smooth``: C-infinity)."""

    builds = (ObstacleTerm,)
    type: Literal["obstacle"]
    profile: Literal["inverse_square", "rmp"] = _OBSTACLE["profile"]
    gain: PositiveFloat = _OBSTACLE["gain"]
    cutoff: PositiveFloat = _OBSTACLE["cutoff"]
    d_min: PositiveFloat = _OBSTACLE["d_min"]
    length: PositiveFloat = _OBSTACLE["length"]
    epsilon: PositiveFloat = _OBSTACLE["epsilon"]
    gate: Literal["none", "approach"] = _OBSTACLE["gate"]
    gate_speed: PositiveFloat = _OBSTACLE["gate_speed"]
    distance: Literal["exact", "smooth"] = _OBSTACLE["distance"]
    spheres: Literal["file"] | None = _OBSTACLE["spheres"]


class JointLimitTermConfig(Section):
    """`JointLimitTerm`."""

    builds = (JointLimitTerm,)
    type: Literal["joint_limit"]
    margin: PositiveFloat = _JOINT_LIMIT["margin"]
    gain: PositiveFloat = _JOINT_LIMIT["gain"]
    d_min: PositiveFloat = _JOINT_LIMIT["d_min"]


TermConfig = Annotated[
    LoadTermConfig | ObstacleTermConfig | JointLimitTermConfig, Field(discriminator="type")
]


class MetricConfig(Strict):
    """Kinetic-energy metric of the robot plus shaping terms."""

    terms: list[TermConfig] = []


__all__ = [
    "JointLimitTermConfig",
    "LoadTermConfig",
    "MetricConfig",
    "ObstacleTermConfig",
    "TermConfig",
]
