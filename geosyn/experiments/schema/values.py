"""Value types of config fields: finite numbers, 3-vectors, joint-space vectors and gains.

Joint-space vectors are checked against the robot's number of degrees of freedom when the
validation context gives it (``{"nv": robot.nv}``, see `geosyn.experiments.config.loader`).
"""

from __future__ import annotations

from typing import Annotated

from pydantic import AfterValidator, Field, ValidationInfo

FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
NonNegFloat = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]
PositiveFloat = Annotated[float, Field(gt=0.0, allow_inf_nan=False)]
Vec3 = Annotated[list[FiniteFloat], Field(min_length=3, max_length=3)]


def _check_nv(value: list[float], info: ValidationInfo) -> list[float]:
    """Length check of a joint-space vector against ``context["nv"]`` (when given)."""
    nv = (info.context or {}).get("nv")
    if nv is not None and len(value) != nv:
        raise ValueError(f"expected {nv} values (the robot's DoF), got {len(value)}")
    return value


#: (nv,) joint-space vector [rad, rad/s, ...], length checked against the robot.
JointVector = Annotated[list[FiniteFloat], AfterValidator(_check_nv)]
#: A gain: one number for all joints, or one per joint, all >= 0.
Gain = NonNegFloat | Annotated[list[NonNegFloat], AfterValidator(_check_nv)]


__all__ = ["FiniteFloat", "Gain", "JointVector", "NonNegFloat", "PositiveFloat", "Vec3"]
