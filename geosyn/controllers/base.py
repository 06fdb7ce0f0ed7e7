"""The `Controller` base: ``compute(t, q, v) -> tau`` behind one interface.

A controller receives the measured state as numpy arrays and returns joint torques of
shape (nv,) [N m]. It never imports a simulator. The public `Controller.compute`
validates the state, times the call, clips the torque to the robot's limits (flagging
the clipped joints) and records everything in `Controller.diagnostics`; subclasses only
implement `Controller._compute`.
"""

from __future__ import annotations

import math
import time
import warnings
from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from geosyn.controllers.errors import ControllerError, NoReference
from geosyn.controllers.reference import Reference
from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_float, check_scalar_or_vector, check_vector
from geosyn.metrics.base import Metric
from geosyn.robots.robot import Robot

FRICTION_VELOCITY = 0.01
"""Reference velocity [rad/s or m/s] over which every controller's dry-friction
feed-forward goes smoothly from 0 to the file's ``frictionloss`` ``f_c``
(``f_c tanh(v_r / FRICTION_VELOCITY)``): the default of each controller's
``friction_velocity`` and the MPC's stage friction."""


@dataclass
class ControllerDiagnostics:
    """What happened in the last `Controller.compute` (mutable, updated every call).

    `Controller.compute` resets ``solver_status`` to ``"ok"``, ``iterations`` to 0,
    ``fallback_used`` to False and ``extra`` to empty before calling `_compute`; a
    subclass sets them when it runs a solver or takes a fallback. ``fallback_count`` is
    incremented by `compute` whenever ``fallback_used`` ends up True, and reset by
    `Controller.reset`. ``notes`` records settings a controller changed when it was
    built (e.g. a solver option it could not honour); neither `compute` nor `reset`
    clears it.

    Attributes:
        compute_time: wall-clock duration of the last `compute` [s].
        solver_status: ``"ok"``, ``"infeasible"``, ``"max_iter"``, ``"failed"``, ...
        iterations: solver iterations of the last call (0 without a solver).
        saturated: (nv,) bool, True where the torque was clipped at ``tau_max``.
        fallback_used: the last torque came from a fallback law.
        fallback_count: number of calls that used the fallback since the last reset.
        extra: controller-specific scalars (e.g. a Lyapunov value, a cost).
        notes: ``{setting: what was used instead and why}`` for build-time changes.
    """

    compute_time: float = 0.0
    solver_status: str = "ok"
    iterations: int = 0
    saturated: np.ndarray | None = None
    fallback_used: bool = False
    fallback_count: int = 0
    extra: dict[str, float] = field(default_factory=dict)
    notes: dict[str, str] = field(default_factory=dict)


def check_gain(x: object, n: int, name: str) -> Vector:
    """A feedback gain as a float64 (n,) array of non-negative finite values.

    Args:
        x: scalar or (n,) array.
        n: number of joints.
        name: argument name for the error message.

    Returns:
        (n,) gain (a scalar is broadcast).

    Raises:
        InvalidArgument: wrong shape, non-finite or negative entries, complex or boolean
            values (never cast: an imaginary part would be dropped).
    """
    return check_scalar_or_vector(x, n, name, low=0.0)


class Controller(ABC):
    """Base class of torque controllers.

    Args:
        robot: the controlled robot; its dynamics parameters are the controller's model
            of the plant and ``robot.tau_max`` the torque limits.
        reference: optional reference to track (can be set later by `set_reference`).

    Attributes:
        robot: the robot.
        nv: number of joints (torque dimension).
        diagnostics: `ControllerDiagnostics` of the last `compute`.
        saturation_tol: a torque counts as saturated when it exceeds ``tau_max`` by more
            than this [N m] (so a solver answer lying on the bound is not flagged).
    """

    saturation_tol: float = 1e-6
    #: Whether the controller handles a floating base (nq = nv + 1, torque 0 on the base
    #: twist); the fixed-base controllers refuse one by name.
    accepts_floating_base: ClassVar[bool] = False

    def __init__(
        self, robot: Robot, reference: Reference | None = None, metric: Metric | None = None
    ) -> None:
        if not isinstance(robot, Robot):
            raise InvalidArgument(f"robot must be a geosyn Robot, got {type(robot).__name__}")
        if not self.accepts_floating_base:
            robot.require_fixed_base(f"{type(self).__name__} (joint torques, q + v dt references)")
        self.robot = robot
        self.nv = robot.nv
        if metric is not None and getattr(metric, "n", None) != self.nv:
            raise InvalidArgument(
                f"metric must have dimension nv={self.nv}, got {getattr(metric, 'n', metric)!r}"
            )
        #: Metric of the references (shaping, replanning); None when not given.
        self.metric = metric
        # The controller's model of the plant and its own Pinocchio workspace.
        self._model = robot.model
        self._data = robot.model.createData()
        self._tau_max = np.asarray(robot.tau_max, dtype=np.float64).copy()
        self._tau_min = -self._tau_max
        self._tau_raw = np.zeros(self.nv)
        self.diagnostics = ControllerDiagnostics(saturated=np.zeros(self.nv, dtype=bool))
        self._reference: Reference | None = None
        if reference is not None:
            self.set_reference(reference)

    # -- reference --------------------------------------------------------------------
    @property
    def reference(self) -> Reference | None:
        """The reference being tracked (None before `set_reference`)."""
        return self._reference

    def set_reference(self, ref: Reference) -> None:
        """Track a new reference from the next `compute` on.

        Args:
            ref: a `Reference` with ``ref.n == robot.nv``.

        Raises:
            InvalidArgument: not a `Reference`, or of the wrong dimension.
        """
        if not isinstance(ref, Reference):
            raise InvalidArgument(f"ref must be a geosyn Reference, got {type(ref).__name__}")
        if ref.n != self.nv:
            raise InvalidArgument(
                f"ref has dimension {ref.n}, but robot {self.robot.name!r} has nv={self.nv}; "
                f"a reference of dimension {self.nv} is required"
            )
        self._reference = ref
        self._on_reference_changed()

    def _on_reference_changed(self) -> None:  # noqa: B027 (optional hook)
        """Hook called after `set_reference` (default: nothing)."""

    def _note(self, setting: str, message: str) -> None:
        """Record a setting changed at build time in ``diagnostics.notes``, and warn.

        Args:
            setting: the argument that was not honoured, e.g. ``"hessian"``.
            message: what is used instead and why.
        """
        self.diagnostics.notes[setting] = message
        warnings.warn(f"{type(self).__name__}: {setting}: {message}", RuntimeWarning, stacklevel=3)

    # -- state ------------------------------------------------------------------------
    def reset(self, q: Vector, v: Vector, t: float = 0.0) -> None:
        """Reset internal state (warm starts, counters) at the measured state.

        Args:
            q: (nq,) joint positions [rad].
            v: (nv,) joint velocities [rad/s].
            t: time [s].
        """
        q = check_vector(q, self.robot.nq, "q")
        v = check_vector(v, self.nv, "v")
        if not math.isfinite(float(t)):
            raise InvalidArgument(f"t must be a finite time [s], got {t!r}")
        d = self.diagnostics
        d.compute_time = 0.0
        d.solver_status = "ok"
        d.iterations = 0
        d.fallback_used = False
        d.fallback_count = 0
        d.extra = {}
        d.saturated = np.zeros(self.nv, dtype=bool)
        self._on_reset(q, v, float(t))

    def _on_reset(self, q: Vector, v: Vector, t: float) -> None:  # noqa: B027 (optional hook)
        """Hook for subclasses with internal state (default: nothing)."""

    # -- control ----------------------------------------------------------------------
    def compute(self, t: float, q: Vector, v: Vector) -> Vector:
        """Joint torques for the measured state.

        Validates the inputs, calls `_compute`, clips the result to ``[-tau_max, tau_max]``
        and updates `diagnostics`. Allocates only the returned array (plus what the
        subclass allocates).

        Args:
            t: time [s].
            q: (nq,) measured joint positions [rad].
            v: (nv,) measured joint velocities [rad/s].

        Returns:
            (nv,) joint torques [N m], within the torque limits.

        Raises:
            InvalidArgument: wrong shapes or non-finite inputs.
            NoReference: no reference was set.
            ControllerError: the control law produced a non-finite torque.
        """
        start = time.perf_counter()
        nv = self.nv
        if not (
            q.__class__ is np.ndarray
            and v.__class__ is np.ndarray
            and q.shape == (nv,)
            and v.shape == (nv,)
            and q.dtype == np.float64
            and v.dtype == np.float64
            and math.isfinite(np.dot(q, q) + np.dot(v, v))
        ):
            q = check_vector(q, self.robot.nq, "q")
            v = check_vector(v, nv, "v")
        if t.__class__ is not float or not math.isfinite(t):
            t = check_float(t, "t", unit="s")  # refuses strings, complex, bools, None, NaN
        if self._reference is None:
            raise NoReference(
                f"{type(self).__name__}.compute called before set_reference; set a reference first"
            )
        d = self.diagnostics
        d.solver_status = "ok"
        d.iterations = 0
        d.fallback_used = False
        if d.extra:
            d.extra = {}
        tau_raw = self._compute(t, q, v)
        if not math.isfinite(float(np.dot(tau_raw, tau_raw))):
            raise ControllerError(
                f"{type(self).__name__} produced a non-finite torque {tau_raw} at t={t}"
            )
        np.copyto(self._tau_raw, tau_raw)
        tau = np.minimum(np.maximum(tau_raw, self._tau_min), self._tau_max)  # np.clip: 3x slower
        sat = d.saturated
        if sat is None or sat.shape != (nv,):
            sat = d.saturated = np.zeros(nv, dtype=bool)
        np.greater(np.abs(tau_raw), self._tau_max + self.saturation_tol, out=sat)
        if d.fallback_used:
            d.fallback_count += 1
        d.compute_time = time.perf_counter() - start
        return tau

    @property
    def last_unclipped_torque(self) -> Vector:
        """(nv,) torque of the last `compute` before clipping [N m] (a copy)."""
        return self._tau_raw.copy()

    @abstractmethod
    def _compute(self, t: float, q: Vector, v: Vector) -> Vector:
        """The control law, on validated inputs and with a reference set.

        Args:
            t: time [s].
            q: (nq,) joint positions [rad], float64, finite.
            v: (nv,) joint velocities [rad/s], float64, finite.

        Returns:
            (nv,) joint torques [N m], before clipping to the limits.
        """
