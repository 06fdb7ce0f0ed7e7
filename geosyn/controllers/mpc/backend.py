"""The contract between `GeodesicMPC` and a solver family: what a backend is built from
(`TrackingProblem`) and what it must do (`TrackingBackend`).

A backend solves the tracking OCP described by `geosyn.controllers.mpc.ocp` (settings,
dynamics, costs, obstacle slots) from a measured state and returns the plan record
`geosyn.controllers.mpc.ocp.plan.MPCPlan`; the controller times it, keeps the plan,
follows it between solves and falls back when a solve fails. The two families,
`geosyn.controllers.mpc.nlp` (fatrop, IPOPT) and `geosyn.controllers.mpc.ddp`
(box-DDP), implement this file and never import each other. A third one needs: an
options class (frozen dataclass), a class with `TrackingBackend`'s members, a function
``(TrackingProblem, options) -> backend``, and one line in
`geosyn.controllers.mpc.controller.BACKENDS`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np

from geosyn.controllers.mpc.ocp.obstacles import ObstacleSlots
from geosyn.controllers.mpc.ocp.plan import MPCPlan, ReferenceSamples
from geosyn.controllers.mpc.ocp.settings import OCPSettings
from geosyn.core.types import Vector
from geosyn.metrics.base import Metric
from geosyn.robots.robot import Robot

__all__ = ["TrackingBackend", "TrackingProblem"]


class TrackingProblem(NamedTuple):
    """What a backend is built from: the OCP's description and the controller's context.

    Attributes:
        robot: the robot (dynamics and limits).
        metric: the metric (its ``"metric"`` effort).
        settings: horizon, control, effort, weights, clearance margin (validated).
        hessian: ``"gauss-newton"`` or ``"exact"``, as asked for.
        obstacles: the obstacle slots (with ``settings.clearance_margin``), or None.
        kp: (nv,) the controller's stiffness [1/s^2] (a DDP cold solve rolls its first
            guess out with it).
        kd: (nv,) the controller's damping [1/s].
        max_solve_time: wall-time budget of one solve [s].
        progress: receives a line before and after each slow step of a first build.
    """

    robot: Robot
    metric: Metric
    settings: OCPSettings
    hessian: str
    obstacles: ObstacleSlots | None
    kp: Vector
    kd: Vector
    max_solve_time: float
    progress: Callable[[str], None]


@runtime_checkable
class TrackingBackend(Protocol):
    """A built solver of the tracking OCP (construction allocates; `solve` evaluates).

    Attributes:
        hessian: the Hessian in use (``"gauss-newton"`` or ``"exact"``).
        notes: settings not honoured at build time, ``{argument: what instead and
            why}`` (the controller warns and records them in its diagnostics).
    """

    hessian: str
    notes: dict[str, str]

    def solve(
        self, t: float, x_init: np.ndarray, ref: ReferenceSamples, previous: MPCPlan | None
    ) -> MPCPlan:
        """Solve from the measured state ``x_init`` (2 nv,) [rad, rad/s] at time ``t``
        [s] for the reference samples ``ref`` at ``t + k dt``; warm-start from
        ``previous`` (the last successful plan, or None) when it covers ``t``. Never
        raises for a failed solve: the plan says ``success=False`` and why
        (``solve_time`` NaN: the controller times the call)."""
        ...

    def forget(self) -> None:
        """Drop any warm start kept inside (the next solve is cold)."""
        ...
