"""Replanning after a disturbance: a new geodesic from the measured state to the goal."""

from __future__ import annotations

from typing import Any

import numpy as np

from geosyn.controllers.reference import GeodesicReference
from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_int, check_positive, check_vector
from geosyn.metrics.base import Metric


def replan_geodesic(
    metric: Metric,
    q: Vector,
    v: Vector,
    goal: Vector,
    duration: float = 1.0,
    steps: int = 100,
    *,
    t0: float = 0.0,
    rest_to_rest: bool = True,
    exact_acceleration: bool = True,
    **log_options: Any,
) -> GeodesicReference:
    """A geodesic reference from the measured configuration to the goal.

    Solves the log map ``v0 = log(metric, q, goal)`` (the initial velocity of the
    unit-time geodesic from ``q`` to ``goal``), integrates it with ``exp`` and returns it
    as a `GeodesicReference` traversed in ``duration`` seconds from controller time
    ``t0`` (time scale ``duration``), by default with the rest-to-rest time law (the path
    is the geodesic; the reference starts and ends at rest, so reaching the goal involves
    no velocity step). The measured velocity ``v`` does not enter the geodesic (a
    geodesic is fixed by its end points); the tracking controller's feedback absorbs the
    velocity mismatch. Works with every controller, since it is an ordinary reference.

    Args:
        metric: the metric (kinetic-energy or shaped).
        q: (n,) measured joint positions [rad].
        v: (n,) measured joint velocities [rad/s] (validated only).
        goal: (n,) goal configuration [rad].
        duration: time to reach the goal [s], > 0.
        steps: integration steps of the geodesic, >= 1.
        t0: controller time at which the new reference starts [s].
        rest_to_rest: quintic rest-to-rest timing (True) or the geodesic's own constant
            speed ``|v0| / duration`` (False).
        exact_acceleration: see `GeodesicReference` (False for slow, e.g. shaped,
            metrics: the acceleration is then interpolated from the geodesic samples).
        **log_options: passed to `geosyn.metrics.geodesic.log` (e.g. tolerances).

    Returns:
        The new reference; ``sample(t0)`` is ``q`` and ``goal()`` is ``goal`` (up to the
        log map's tolerance).

    Raises:
        InvalidArgument: wrong shapes or values.
        GeodesicNotFound: the log map did not converge.
    """
    from geosyn.metrics.geodesic import exp, log

    if not isinstance(metric, Metric):
        raise InvalidArgument(f"metric must be a geosyn Metric, got {type(metric).__name__}")
    n = metric.n
    q = check_vector(q, n, "q")
    check_vector(v, n, "v")
    goal = check_vector(goal, n, "goal")
    duration = check_positive(duration, "duration", "s")
    steps = check_int(steps, "steps", low=1)
    v0 = log(metric, q, goal, steps=steps, **log_options)
    geodesic = exp(metric, q, np.asarray(v0, dtype=np.float64), duration=1.0, steps=steps)
    return GeodesicReference(
        geodesic,
        metric,
        time_scale=duration,
        t0=t0,
        rest_to_rest=rest_to_rest,
        exact_acceleration=exact_acceleration,
    )
