"""Value types of config fields: finite numbers, 3-vectors, joint-space vectors and gains.

Joint-space vectors are checked against the robot's number of degrees of freedom when the
validation context gives it (``{"nv": robot.nv}``, see `geosyn.experiments.config.loader`).
"""

from __future__ import annotations

from typing import Annotated, Any

from pydantic import AfterValidator, Field, ValidationInfo

FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]
NonNegFloat = Annotated[float, Field(ge=0.0, allow_inf_nan=False)]
PositiveFloat = Annotated[float, Field(gt=0.0, allow_inf_nan=False)]
#: Largest magnitude of a 3-vector component (positions [m], forces [N], torques [N m],
#: gravity [m/s^2]). Generous on purpose: a 10 MN push is a legitimate way to make a run
#: diverge (tests do), but 1e300 is a typo or an attack that MuJoCo would turn into noise.
MAX_VEC3 = 1e8


def _check_vec3(value: list[float]) -> list[float]:
    """Refuse a component beyond `MAX_VEC3` in magnitude."""
    for i, x in enumerate(value):
        if abs(x) > MAX_VEC3:
            raise ValueError(
                f"component {i} is {x:g}; a 3-vector component is at most {MAX_VEC3:g}"
                " in magnitude (positions [m], forces [N], torques [N m], gravity [m/s^2])"
            )
    return value


Vec3 = Annotated[list[FiniteFloat], Field(min_length=3, max_length=3), AfterValidator(_check_vec3)]


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


def bounded_gain(limit: float) -> Any:
    """A `Gain` whose values are also at most ``limit`` (one number or one per joint),
    for standard deviations and other settings with a physical ceiling."""
    value = Annotated[float, Field(ge=0.0, le=limit, allow_inf_nan=False)]
    return value | Annotated[list[value], AfterValidator(_check_nv)]


#: Largest sensor-noise standard deviations: ``q_std`` [rad] (a half turn: noise beyond it
#: is not a measurement of the angle) and ``v_std`` [rad/s] (faster than any joint moves).
MAX_Q_STD = 3.14
MAX_V_STD = 1000.0
#: Largest torque-noise standard deviation [N m] (beyond any arm's joint torque limit).
MAX_TAU_STD = 1e4


__all__ = [
    "MAX_Q_STD",
    "MAX_TAU_STD",
    "MAX_VEC3",
    "MAX_V_STD",
    "FiniteFloat",
    "Gain",
    "JointVector",
    "NonNegFloat",
    "PositiveFloat",
    "Vec3",
    "bounded_gain",
]
