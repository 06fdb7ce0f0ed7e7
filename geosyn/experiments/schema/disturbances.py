"""Config sections of the disturbances; each stands for its `geosyn.sim` class and takes
its defaults from that class's constructor."""

from __future__ import annotations

import math
from typing import Annotated, Literal

from pydantic import Field, model_validator

from geosyn.experiments.schema.section import Section, python_defaults
from geosyn.experiments.schema.values import (
    MAX_Q_STD,
    MAX_TAU_STD,
    MAX_V_STD,
    NonNegFloat,
    PositiveFloat,
    Vec3,
    bounded_gain,
)
from geosyn.sim import Latency, PayloadChange, Push, SensorNoise, TorqueNoise, Wrench

_PUSH = python_defaults(Push)
_WRENCH = python_defaults(Wrench)
_PAYLOAD_CHANGE = python_defaults(PayloadChange)
_SENSOR_NOISE = python_defaults(SensorNoise)
_LATENCY = python_defaults(Latency)


def _stop_time(stop: float | None) -> float:
    """A wrench's stop time [s]: None (never) is ``inf``, which a config value cannot be."""
    return math.inf if stop is None else stop


class PushConfig(Section):
    """`Push`: ``force`` [N] on ``body`` from ``start`` for ``duration`` [s]."""

    builds = (Push,)
    type: Literal["push"]
    body: str
    force: Vec3
    start: NonNegFloat
    duration: PositiveFloat
    point: Vec3 | None = _PUSH["point"]


class WrenchConfig(Section):
    """`Wrench`: ``force`` [N] and ``torque`` [N m] on ``body``, constant or a sine of
    ``period`` [s], from ``start`` to ``stop`` [s] (None: it never stops)."""

    builds = (Wrench,)
    to_python = {"stop": _stop_time}
    type: Literal["wrench"]
    body: str
    force: Vec3 = _WRENCH["force"]
    torque: Vec3 = _WRENCH["torque"]
    period: PositiveFloat | None = _WRENCH["period"]
    start: NonNegFloat = _WRENCH["start"]
    stop: PositiveFloat | None = None  # to_python: None -> Wrench's default, inf
    point: Vec3 | None = _WRENCH["point"]


class PayloadChangeConfig(Section):
    """`PayloadChange`: at ``time`` [s] the payload (index or name) gets ``mass`` [kg]."""

    builds = (PayloadChange,)
    type: Literal["payload_change"]
    time: NonNegFloat
    mass: NonNegFloat
    payload: Annotated[int, Field(ge=0)] | str = _PAYLOAD_CHANGE["payload"]


class TorqueNoiseConfig(Section):
    """`TorqueNoise`: standard deviation ``std`` [N m], one or per joint (at most
    `MAX_TAU_STD`)."""

    builds = (TorqueNoise,)
    type: Literal["torque_noise"]
    std: bounded_gain(MAX_TAU_STD)  # type: ignore[valid-type]


class SensorNoiseConfig(Section):
    """`SensorNoise`: standard deviations ``q_std`` [rad] and ``v_std`` [rad/s] (at most
    `MAX_Q_STD` and `MAX_V_STD`)."""

    builds = (SensorNoise,)
    type: Literal["sensor_noise"]
    q_std: bounded_gain(MAX_Q_STD) = _SENSOR_NOISE["q_std"]  # type: ignore[valid-type]
    v_std: bounded_gain(MAX_V_STD) = _SENSOR_NOISE["v_std"]  # type: ignore[valid-type]


class LatencyConfig(Section):
    """`Latency`: the controller sees the state ``ticks`` ticks or ``seconds`` [s] late."""

    builds = (Latency,)
    type: Literal["latency"]
    ticks: Annotated[int, Field(ge=0)] | None = _LATENCY["ticks"]
    seconds: NonNegFloat | None = _LATENCY["seconds"]

    @model_validator(mode="after")
    def _exactly_one(self) -> LatencyConfig:
        if (self.ticks is None) == (self.seconds is None):
            raise ValueError("give exactly one of ticks or seconds")
        return self


DisturbanceConfig = Annotated[
    PushConfig
    | WrenchConfig
    | PayloadChangeConfig
    | TorqueNoiseConfig
    | SensorNoiseConfig
    | LatencyConfig,
    Field(discriminator="type"),
]

__all__ = [
    "DisturbanceConfig",
    "LatencyConfig",
    "PayloadChangeConfig",
    "PushConfig",
    "SensorNoiseConfig",
    "TorqueNoiseConfig",
    "WrenchConfig",
]
