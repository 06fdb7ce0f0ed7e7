"""The `Robot` description: one Pinocchio model plus limits and collision geometry.

Everything downstream (metrics, controllers, the MuJoCo plant) is built from a `Robot`, so
the kinetic-energy metric and the simulated dynamics come from the same parameters.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_int, check_vector
from geosyn.robots.couplings import Coupling
from geosyn.robots.errors import FloatingBaseError, UnknownFrame
from geosyn.robots.floating import check_floating_q, is_floating, neutral_base, random_base
from geosyn.robots.limits import ActuatorInfo

if TYPE_CHECKING:
    import mujoco


@dataclass(frozen=True)
class CollisionCapsule:
    """A capsule rigidly attached to a joint's body (the link moved by that joint).

    Attributes:
        joint: name of the Pinocchio joint whose body carries the capsule.
        p0: (3,) first end point in the joint frame [m].
        p1: (3,) second end point in the joint frame [m]; equal to `p0` for a sphere.
        radius: capsule radius [m].
    """

    joint: str
    p0: tuple[float, float, float]
    p1: tuple[float, float, float]
    radius: float


@dataclass(frozen=True)
class CollisionSphere:
    """A sphere rigidly attached to a joint's body, used by obstacle shaping terms.

    Attributes:
        joint: name of the Pinocchio joint whose body carries the sphere.
        center: (3,) centre in the joint frame [m].
        radius: sphere radius [m].
    """

    joint: str
    center: tuple[float, float, float]
    radius: float


@dataclass(frozen=True)
class Robot:
    """A robot: Pinocchio model, limits and simple collision geometry.

    Fixed base: ``nq == nv`` (continuous joints are loaded as plain revolute joints).
    Floating base (`floating`): joint 1 is a free flyer and the configuration lives on
    SE(3) x R^n, ``nq = n + 7``, ``nv = n + 6`` (Pinocchio's conventions, see
    `geosyn.robots.floating`); per-coordinate arrays cover the base too (``q_min``,
    ``q_max`` (nq,) infinite on the base; ``v_max``, ``tau_max`` (nv,), ``tau_max`` 0 on
    the unactuated base) while ``joint_names`` lists the n joints. ``model.armature``
    holds the reflected rotor inertia added to the mass matrix on both the Pinocchio and
    the MuJoCo side.

    Attributes:
        name: robot name.
        model: Pinocchio model. Treat as read-only.
        joint_names: names of the actuated joints, in configuration order: (nv,) for a
            fixed base, (nv - 6,) for a floating one.
        q_min: (nq,) lower position limits [rad or m]; ``-inf`` where unlimited.
        q_max: (nq,) upper position limits [rad or m]; ``+inf`` where unlimited.
        v_max: (nv,) velocity limits [rad/s or m/s].
        tau_max: (nv,) torque limits [N m or N].
        ee_frame: name of the end-effector frame in ``model``.
        capsules: collision capsules per link.
        gravity: (3,) gravity vector in the world frame [m/s^2].
        damping: (nv,) viscous joint damping stated by the file [N m s/rad or N s/m];
            zeros when none. Not in M(q): the inverse-dynamics controllers can compensate it.
        frictionloss: (nv,) dry joint friction stated by the file [N m or N]; zeros when none.
        tau_max_source: (nv,) where each torque limit came from (``file: ...``, ``user``,
            ``default ...``, ``built-in``).
        actuators: the actuators the file declares (geosyn commands joint torques instead).
        base: ``fixed``, how a floating base was fixed (``fixed_base=True``), or
            ``floating: ...`` for a free-flyer base.
        source_file: the robot file loaded, or None for a robot built in code.
        coupling: linear joint couplings of the file (``q = S z + c``), or None; the
            model itself is the uncoupled tree.
    """

    name: str
    model: pin.Model
    joint_names: tuple[str, ...]
    q_min: Vector
    q_max: Vector
    v_max: Vector
    tau_max: Vector
    ee_frame: str
    capsules: tuple[CollisionCapsule, ...] = ()
    gravity: tuple[float, float, float] = (0.0, 0.0, -9.81)
    _spheres: tuple[CollisionSphere, ...] = field(default=(), repr=False)
    damping: Vector = field(default_factory=lambda: np.zeros(0))
    frictionloss: Vector = field(default_factory=lambda: np.zeros(0))
    tau_max_source: tuple[str, ...] = ()
    actuators: tuple[ActuatorInfo, ...] = ()
    base: str = "fixed"
    source_file: str | None = None
    coupling: Coupling | None = None

    def __post_init__(self) -> None:
        n = int(self.model.nv)
        for name in ("damping", "frictionloss"):
            value = getattr(self, name)
            empty = value is None or np.size(value) == 0
            arr = np.zeros(n) if empty else np.array(check_vector(value, n, name))
            if np.any(arr < 0):
                raise InvalidArgument(f"{name} must be >= 0, got {arr.tolist()}")
            arr.flags.writeable = False
            object.__setattr__(self, name, arr)
        if not self.tau_max_source:
            object.__setattr__(self, "tau_max_source", ("given",) * n)

    @property
    def has_joint_friction(self) -> bool:
        """Whether any joint has viscous damping or dry friction."""
        return bool(np.any(self.damping) or np.any(self.frictionloss))

    # -- sizes ------------------------------------------------------------------------
    @property
    def nq(self) -> int:
        """Number of configuration coordinates."""
        return int(self.model.nq)

    @property
    def nv(self) -> int:
        """Number of velocity coordinates (``nq`` for a fixed base, ``nq - 1`` floating)."""
        return int(self.model.nv)

    @property
    def floating(self) -> bool:
        """Whether the base is floating (a free-flyer joint 1; q on SE(3) x R^n)."""
        return is_floating(self.model)

    def require_fixed_base(self, what: str) -> None:
        """Raise `FloatingBaseError` if the base is floating.

        Args:
            what: the feature that needs a fixed base, for the message.
        """
        if self.floating:
            raise FloatingBaseError(
                f"{what} needs a fixed-base robot; {self.name!r} has a floating base (q on"
                f" SE(3) x R^{self.nv - 6}, nq={self.nq}, nv={self.nv}): load it with"
                " fixed_base=True to weld its root body to the world"
            )

    @property
    def armature(self) -> Vector:
        """(nv,) reflected rotor inertia on each joint [kg m^2 or kg]."""
        return np.array(self.model.armature, dtype=np.float64)

    @property
    def total_mass(self) -> float:
        """Total mass of the moving bodies [kg]."""
        return float(sum(self.model.inertias[j].mass for j in range(1, self.model.njoints)))

    # -- lookups ----------------------------------------------------------------------
    def frame_id(self, name: str) -> int:
        """Index of a Pinocchio frame.

        Args:
            name: frame name.

        Raises:
            UnknownFrame: the name is not a frame of the model; the message lists them.
        """
        if not isinstance(name, str) or not self.model.existFrame(name):
            names = [f.name for f in self.model.frames]
            raise UnknownFrame(
                f"frame {name!r} is not in robot {self.name!r}; available: {', '.join(names)}",
                name,
                names,
            )
        try:
            return int(self.model.getFrameId(name))
        except ValueError:  # several frames of that name (a joint and its link): prefer
            rank = {pin.FrameType.OP_FRAME: 0, pin.FrameType.BODY: 1}  # the tool, the body
            same = [i for i, f in enumerate(self.model.frames) if f.name == name]
            return min(same, key=lambda i: (rank.get(self.model.frames[i].type, 2), i))

    def joint_id(self, name: str) -> int:
        """Index of a Pinocchio joint (1-based; 0 is the universe).

        Raises:
            UnknownFrame: the name is not a joint of the model; the message lists them.
        """
        if not isinstance(name, str) or not self.model.existJointName(name):
            names = list(self.model.names[1:])
            raise UnknownFrame(
                f"joint {name!r} is not in robot {self.name!r}; available: {', '.join(names)}",
                name,
                names,
            )
        return int(self.model.getJointId(name))

    def collision_spheres(self, per_capsule: int = 3) -> tuple[CollisionSphere, ...]:
        """Spheres covering each collision capsule, for obstacle terms.

        Args:
            per_capsule: spheres per capsule, evenly spaced between its end points (>= 1).

        Returns:
            The spheres, each with the radius of its capsule.
        """
        if self._spheres:
            return self._spheres
        per_capsule = check_int(per_capsule, "per_capsule", low=1)
        spheres = []
        for c in self.capsules:
            p0, p1 = np.asarray(c.p0), np.asarray(c.p1)
            same = np.allclose(p0, p1)
            for s in [0.5] if same else np.linspace(0.0, 1.0, per_capsule):
                ctr = (1.0 - s) * p0 + s * p1
                spheres.append(
                    CollisionSphere(
                        c.joint, (float(ctr[0]), float(ctr[1]), float(ctr[2])), c.radius
                    )
                )
        return tuple(spheres)

    # -- validation -------------------------------------------------------------------
    def check_q(self, q: object, name: str = "q") -> Vector:
        """Return ``q`` as a float64 (nq,) array, or raise `InvalidArgument`.

        Args:
            q: candidate joint positions, shape (nq,) [rad or m].
            name: argument name used in the error message.

        Raises:
            InvalidArgument: wrong shape or non-finite values.
            FloatingBaseError: a floating base's quaternion ``q[3:7]`` is not unit.
        """
        if self.floating:
            return check_floating_q(q, self.nq, name, self.name)
        return check_vector(q, self.nq, name)

    def random_q(self, rng: np.random.Generator, margin: float = 0.0) -> Vector:
        """A uniformly random configuration inside the position limits.

        Unlimited joints are drawn in [-pi, pi]; a floating base's position uniformly in
        [-1, 1]^3 m and its orientation uniformly on SO(3).

        Args:
            rng: seeded random generator.
            margin: distance kept from each limit [rad or m].

        Returns:
            (nq,) joint positions.
        """
        k = 7 if self.floating else 0
        base = random_base(rng) if self.floating else np.zeros(0)
        lo = np.where(np.isfinite(self.q_min[k:]), self.q_min[k:] + margin, -np.pi)
        hi = np.where(np.isfinite(self.q_max[k:]), self.q_max[k:] - margin, np.pi)
        return np.concatenate([base, rng.uniform(lo, hi)])

    def neutral(self) -> Vector:
        """(nq,) a configuration inside the limits: zero, clipped to the limits' middle.

        A floating base is at the world origin, not rotated.
        """
        k = 7 if self.floating else 0
        q_min, q_max = self.q_min[k:], self.q_max[k:]
        bounded = np.isfinite(q_min) & np.isfinite(q_max)
        mid = np.zeros(q_min.shape)
        mid[bounded] = 0.5 * (q_min[bounded] + q_max[bounded])
        q = np.zeros(q_min.shape)
        outside = (q < q_min) | (q > q_max)
        base = neutral_base() if self.floating else np.zeros(0)
        return np.concatenate([base, np.where(outside, mid, q)])

    # -- MuJoCo -----------------------------------------------------------------------
    def mjcf(self, **options: object) -> str:
        """MJCF text of a MuJoCo model with the same dynamics; see `geosyn.robots.mjcf`.

        Raises:
            FloatingBaseError: a floating base (the MuJoCo twin is fixed-base).
        """
        self.require_fixed_base("the MuJoCo twin (Robot.mjcf, Robot.mj_model)")
        from geosyn.robots.mjcf import robot_to_mjcf

        return robot_to_mjcf(self, **options)  # type: ignore[arg-type]

    def mj_model(self, **options: object) -> mujoco.MjModel:
        """A compiled `mujoco.MjModel` with the same dynamics; see `geosyn.robots.mjcf`."""
        import mujoco

        return mujoco.MjModel.from_xml_string(self.mjcf(**options))
