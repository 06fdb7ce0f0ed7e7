"""Disturbances of a closed-loop simulation: pushes, wrenches, payload changes, noise, latency.

A `Disturbance` has small hooks that `geosyn.sim.Simulation` calls once per control tick
(a zero-order hold: what a disturbance sets holds for the ``substeps`` physics steps of the
tick):

1. `Disturbance.modify_measurement` (in list order) turns the true ``(q, v)`` into what
   the controller measures: `SensorNoise`, `Latency`.
2. `Disturbance.modify_tau` (in list order) turns the controller's torque into the torque
   sent to the motors, before it is clipped to the torque limits: `TorqueNoise`.
3. `Disturbance.before_tick` changes the model before the tick's dynamics are computed:
   `PayloadChange` (so the new mass acts from the tick at which it is logged).
4. `Disturbance.on_tick` acts on the MuJoCo data once the tick's kinematics are known:
   external wrenches are added to ``data.xfrc_applied`` (zeroed by the simulation before
   the hooks run): `Push`, `Wrench`.

Order within a tick: ``before_tick``, kinematics and dynamics of the state,
``modify_measurement``, the controller, ``modify_tau``, ``on_tick``, physics.

The simulation deep-copies its disturbances, binds them to its scene once
(`Disturbance.bind`: names resolved, buffers allocated) and resets them at the start of each
run with a generator seeded from the simulation's seed (`Disturbance.reset`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import mujoco
import numpy as np

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_float, check_int, check_vec3, check_vector
from geosyn.sim.errors import UnknownBody
from geosyn.sim.scene import Scene

#: Tolerance on event times [s]: an event at ``t0`` fires on the first tick with t >= t0 - eps.
_TIME_EPS = 1e-9


def _std(x: object, name: str) -> np.ndarray:
    """A standard deviation >= 0: a scalar, or a (n,) vector with one per joint."""
    try:
        n = len(x)  # type: ignore[arg-type]
    except TypeError:  # a scalar, or not a number at all (check_float says which)
        return np.asarray(check_float(x, name, low=0.0))
    arr = check_vector(x, n, name)
    if np.any(arr < 0):
        raise InvalidArgument(f"{name} must be >= 0 on every joint, got {x!r}")
    return arr


def _time(x: object, name: str, *, positive: bool = False) -> float:
    """A time [s]: finite and >= 0 (> 0 with ``positive``)."""
    return check_float(x, name, low=0.0, low_open=positive, unit="s")


def _check_sized(std: np.ndarray, n: int, name: str) -> None:
    if std.ndim == 1 and std.shape != (n,):
        raise InvalidArgument(
            f"{name} must be a scalar or have shape ({n},), got shape {std.shape}"
        )


class Disturbance:
    """Base class: hooks called once per control tick; all default to doing nothing.

    Subclasses override only the hooks they need; the simulation calls only overridden ones.
    """

    #: Whether `on_tick` writes ``data.xfrc_applied`` (the simulation zeroes it first).
    applies_wrench: bool = False

    def bind(self, scene: Scene, control_dt: float) -> None:
        """Resolve names and allocate buffers for one simulation (called once).

        Args:
            scene: the simulation's scene (its model is the one simulated).
            control_dt: control period [s].

        Raises:
            UnknownBody: a body or payload name does not resolve.
            InvalidArgument: a parameter does not fit the scene (wrong size, ...).
        """

    def reset(self, rng: np.random.Generator) -> None:
        """Start of a run: restore any model change and reseed.

        Args:
            rng: this disturbance's generator, seeded from the simulation's seed.
        """

    def modify_measurement(self, t: float, q: Vector, v: Vector) -> tuple[Vector, Vector]:
        """What the controller measures.

        Args:
            t: time of the tick [s].
            q: (nq,) joint positions after the previous measurement hooks [rad]; do not
                modify in place.
            v: (nv,) joint velocities [rad/s]; do not modify in place.

        Returns:
            (q, v) passed on to the next hook, then to the controller.
        """
        return q, v

    def modify_tau(self, t: float, tau: Vector) -> Vector:
        """The torque sent to the motors, before clipping to the torque limits.

        Args:
            t: time of the tick [s].
            tau: (nv,) torque [N m]; do not modify in place.

        Returns:
            (nv,) torque [N m].
        """
        return tau

    def before_tick(self, t: float, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Change the model before the tick's dynamics are computed (payload masses).

        Args:
            t: time of the tick [s].
            model: the simulated model.
            data: the simulation data (the tick's state; nothing computed yet).
        """

    def on_tick(self, t: float, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Act on the MuJoCo model or data (kinematics of the tick's state are computed).

        Args:
            t: time of the tick [s].
            model: the simulated model (may be modified: payload masses).
            data: the simulation data; add external wrenches to ``data.xfrc_applied``.
        """


def overrides(d: Disturbance, hook: str) -> bool:
    """Whether the class of ``d`` overrides the hook ``hook`` (the simulation calls only those)."""
    return getattr(type(d), hook) is not getattr(Disturbance, hook)


# -- external wrenches ------------------------------------------------------------------
class _BodyWrench(Disturbance):
    """A force (and torque) on a body, applied at a point fixed in a named frame."""

    applies_wrench = True

    def __init__(self, body: str, force: object, torque: object, point: object) -> None:
        if not isinstance(body, str):
            raise InvalidArgument(f"body must be a body, link or frame name, got {body!r}")
        self.body = body
        self.force = check_vector(force, 3, "force [N]")
        self.torque = check_vector(torque, 3, "torque [N m]")
        self.point = None if point is None else check_vec3(point, "point [m]")
        self._bid = -1
        self._point_body: Vector | None = None

    def bind(self, scene: Scene, control_dt: float) -> None:
        self._bid = scene.resolve_body(self.body)
        if self._bid == 0:
            raise UnknownBody(
                f"body {self.body!r} is fixed to the world; a wrench on it does nothing"
            )
        self._point_body = (
            None if self.point is None else scene.frame_point_in_body(self.body, self.point)
        )

    def _add(self, data: mujoco.MjData, scale: float) -> None:
        """Add ``scale`` times the wrench to ``data.xfrc_applied`` (expressed at the CoM)."""
        f = scale * self.force
        tq = scale * self.torque
        if self._point_body is not None:
            R = data.xmat[self._bid].reshape(3, 3)
            p_world = data.xpos[self._bid] + R @ self._point_body
            tq = tq + np.cross(p_world - data.xipos[self._bid], f)
        data.xfrc_applied[self._bid, :3] += f
        data.xfrc_applied[self._bid, 3:] += tq


class Push(_BodyWrench):
    """A constant force on a body during a time window.

    Args:
        body: MuJoCo body, Pinocchio link/frame/joint name, or payload name.
        force: (3,) force in the world frame [N].
        start: start time [s], >= 0.
        duration: length of the window [s], > 0; active for ``start <= t < start + duration``.
        point: (3,) point of application in the named frame [m]; ``None`` applies the force
            at the body's centre of mass (no torque).
    """

    def __init__(
        self,
        body: str,
        force: Sequence[float],
        start: float,
        duration: float,
        point: Sequence[float] | None = None,
    ) -> None:
        super().__init__(body, force, (0.0, 0.0, 0.0), point)
        self.start = _time(start, "start")
        self.duration = _time(duration, "duration", positive=True)

    def active(self, t: float) -> bool:
        """Whether the push acts at time ``t`` [s]."""
        return self.start - _TIME_EPS <= t < self.start + self.duration - _TIME_EPS

    def on_tick(self, t: float, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        if self.active(t):
            self._add(data, 1.0)

    def __repr__(self) -> str:
        return f"Push({self.body!r}, force={self.force.tolist()}, start={self.start}, duration={self.duration})"


class Wrench(_BodyWrench):
    """A constant or sinusoidal force and torque on a body.

    .. math:: w(t) = w_0 \\, s(t), \\quad s(t) = 1 \\text{ or } \\sin(2 \\pi (t - t_0) / T)

    Args:
        body: MuJoCo body, Pinocchio link/frame/joint name, or payload name.
        force: (3,) force amplitude in the world frame [N].
        torque: (3,) torque amplitude in the world frame [N m].
        period: period T [s] of the sine; ``None`` for a constant wrench.
        start: time t0 [s] from which the wrench acts.
        stop: time [s] from which it stops (default: never).
        point: (3,) point of application of the force in the named frame [m]; ``None``:
            the body's centre of mass.
    """

    def __init__(
        self,
        body: str,
        force: Sequence[float] = (0.0, 0.0, 0.0),
        torque: Sequence[float] = (0.0, 0.0, 0.0),
        period: float | None = None,
        start: float = 0.0,
        stop: float = math.inf,
        point: Sequence[float] | None = None,
    ) -> None:
        super().__init__(body, force, torque, point)
        self.period = None if period is None else _time(period, "period", positive=True)
        self.start = _time(start, "start")
        if not (float(stop) > self.start):
            raise InvalidArgument(f"stop must be > start={self.start} [s], got {stop!r}")
        self.stop = float(stop)

    def scale(self, t: float) -> float:
        """The factor s(t) of the amplitude at time ``t`` [s] (0 outside [start, stop))."""
        if not (self.start - _TIME_EPS <= t < self.stop - _TIME_EPS):
            return 0.0
        if self.period is None:
            return 1.0
        return math.sin(2.0 * math.pi * (t - self.start) / self.period)

    def on_tick(self, t: float, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        s = self.scale(t)
        if s != 0.0:
            self._add(data, s)


# -- payload ----------------------------------------------------------------------------
class PayloadChange(Disturbance):
    """Set a payload's mass during a run; the controller is not told.

    The payload body's mass and its principal moments of inertia (those of the same shape
    at the new mass: `geosyn.world.Payload.principal_inertia`) are written into the
    simulated model, then ``mujoco.mj_setConst`` recomputes the derived constants (subtree
    masses, inverse weights, actuator acc0) on a scratch MjData, so the simulation's state is
    untouched. The next `reset` restores the initial mass.

    Args:
        time: when the mass changes [s], >= 0 (first tick with t >= time).
        mass: new mass [kg], >= 0.
        payload: index or name of the payload in the simulation's payloads.
    """

    def __init__(self, time: float, mass: float, payload: int | str = 0) -> None:
        self.time = _time(time, "time")
        self.mass = check_float(mass, "mass", low=0.0, unit="kg")
        self.payload = payload
        self._bid = -1
        self._done = False

    def bind(self, scene: Scene, control_dt: float) -> None:
        names = [p.name or f"payload{i}" for i, p in enumerate(scene.payloads)]
        if isinstance(self.payload, str) and self.payload in names:
            index = names.index(self.payload)
        elif isinstance(self.payload, (int, np.integer)) and 0 <= int(self.payload) < len(names):
            index = int(self.payload)
        else:
            raise UnknownBody(
                f"payload {self.payload!r} is not in the simulation; available: "
                f"{', '.join(f'{i}/{n}' for i, n in enumerate(names)) or 'none (pass payloads=...)'}"
            )
        self._payload = scene.payloads[index]
        self._bid = int(scene.payload_body_ids[index])
        self._model = scene.model
        self._scratch = mujoco.MjData(scene.model)
        self._mass0 = float(scene.model.body_mass[self._bid])
        self._inertia0 = np.array(scene.model.body_inertia[self._bid])

    def _set(self, mass: float, inertia: np.ndarray) -> None:
        self._model.body_mass[self._bid] = mass
        self._model.body_inertia[self._bid] = inertia
        mujoco.mj_setConst(self._model, self._scratch)

    def reset(self, rng: np.random.Generator) -> None:
        self._done = False
        if float(self._model.body_mass[self._bid]) != self._mass0:
            self._set(self._mass0, self._inertia0)

    def before_tick(self, t: float, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        if not self._done and t >= self.time - _TIME_EPS:
            self._set(self.mass, self._payload.principal_inertia(self.mass)[0])
            self._done = True

    def __repr__(self) -> str:
        return f"PayloadChange(time={self.time}, mass={self.mass}, payload={self.payload!r})"


# -- noise and latency ------------------------------------------------------------------
class TorqueNoise(Disturbance):
    """Zero-mean Gaussian noise added to the commanded torque, drawn each tick (seeded).

    Args:
        std: standard deviation [N m], a scalar or (nv,) per joint, >= 0.
    """

    def __init__(self, std: float | Sequence[float] | np.ndarray) -> None:
        self.std = _std(std, "std [N m]")

    def bind(self, scene: Scene, control_dt: float) -> None:
        _check_sized(self.std, scene.robot.nv, "std [N m]")
        self._std = np.broadcast_to(self.std, (scene.robot.nv,)).copy()

    def reset(self, rng: np.random.Generator) -> None:
        self._rng = rng

    def modify_tau(self, t: float, tau: Vector) -> Vector:
        return tau + self._std * self._rng.standard_normal(len(tau))


class SensorNoise(Disturbance):
    """Zero-mean Gaussian noise on the measured positions and velocities (seeded).

    Args:
        q_std: position noise standard deviation [rad], scalar or (nq,), >= 0.
        v_std: velocity noise standard deviation [rad/s], scalar or (nv,), >= 0.
    """

    def __init__(
        self,
        q_std: float | Sequence[float] | np.ndarray = 0.0,
        v_std: float | Sequence[float] | np.ndarray = 0.0,
    ) -> None:
        self.q_std = _std(q_std, "q_std [rad]")
        self.v_std = _std(v_std, "v_std [rad/s]")

    def bind(self, scene: Scene, control_dt: float) -> None:
        n = scene.robot.nv
        _check_sized(self.q_std, n, "q_std [rad]")
        _check_sized(self.v_std, n, "v_std [rad/s]")
        self._q_std = np.broadcast_to(self.q_std, (n,)).copy()
        self._v_std = np.broadcast_to(self.v_std, (n,)).copy()

    def reset(self, rng: np.random.Generator) -> None:
        self._rng = rng

    def modify_measurement(self, t: float, q: Vector, v: Vector) -> tuple[Vector, Vector]:
        noise = self._rng.standard_normal(2 * len(q))
        return q + self._q_std * noise[: len(q)], v + self._v_std * noise[len(q) :]


class Latency(Disturbance):
    """The controller measures the state of exactly ``ticks`` control ticks ago.

    During the first ``ticks`` ticks it measures the initial state.

    Args:
        ticks: delay in control ticks, >= 0.
        seconds: delay [s], >= 0, rounded to a whole number of ticks at binding; it must be
            a multiple of the control period within 1e-6 of a tick. Give exactly one.
    """

    def __init__(self, ticks: int | None = None, seconds: float | None = None) -> None:
        if (ticks is None) == (seconds is None):
            raise InvalidArgument(
                f"give exactly one of ticks or seconds, got ticks={ticks!r}, seconds={seconds!r}"
            )
        self.ticks_arg = None if ticks is None else check_int(ticks, "ticks", low=0)
        self.seconds = None if seconds is None else _time(seconds, "seconds")
        self.ticks = self.ticks_arg if self.ticks_arg is not None else -1

    def bind(self, scene: Scene, control_dt: float) -> None:
        if self.seconds is not None:
            k = round(self.seconds / control_dt)
            if abs(k * control_dt - self.seconds) > 1e-6 * control_dt + 1e-12:
                raise InvalidArgument(
                    f"seconds={self.seconds} is not a multiple of control_dt={control_dt} [s]"
                )
            self.ticks = int(k)
        n = scene.robot.nv
        self._q = np.zeros((self.ticks + 1, n))
        self._v = np.zeros((self.ticks + 1, n))

    def reset(self, rng: np.random.Generator) -> None:
        self._count = 0

    def modify_measurement(self, t: float, q: Vector, v: Vector) -> tuple[Vector, Vector]:
        size = self.ticks + 1
        if self._count == 0:
            self._q[:] = q
            self._v[:] = v
        slot = self._count % size
        self._q[slot] = q
        self._v[slot] = v
        self._count += 1
        old = self._count % size  # the slot written `ticks` ticks ago
        return self._q[old].copy(), self._v[old].copy()

    def __repr__(self) -> str:
        return f"Latency(ticks={self.ticks})"


__all__ = [
    "Disturbance",
    "Latency",
    "PayloadChange",
    "Push",
    "SensorNoise",
    "TorqueNoise",
    "Wrench",
]
