"""A floating-base robot standing in MuJoCo with its base free: state in Pinocchio's
conventions, joint torques out, pushes on the base, and what the feet did.

`FloatingPlant` steps a `geosyn.sim.floating_scene.FloatingScene`: each control tick it
converts MuJoCo's free-joint state to Pinocchio's (`geosyn.robots.floating.from_mujoco`),
takes the controller's torques (nv,) and sends ``tau[6:]`` to the joint motors (the base
is unactuated), holds an external force on the base body, and tracks the feet: their
largest horizontal displacement (slip), vertical displacement (sink or lift) and the
lowest base height.
"""

from __future__ import annotations

import mujoco
import numpy as np
import pinocchio as pin

from geosyn.core.errors import InvalidArgument
from geosyn.core.types import Vector
from geosyn.core.validation import check_positive, check_vector
from geosyn.robots.floating import check_floating_q, from_mujoco, to_mujoco
from geosyn.sim.floating_scene import FloatingScene

__all__ = ["FeetMotion", "FloatingPlant"]


class FeetMotion:
    """The contact frames' motion since the start (updated by `FloatingPlant.step`).

    Attributes:
        slip: largest horizontal displacement (x or y) of a contact frame [m].
        sink: largest vertical displacement of a contact frame (either sign) [m].
        min_base_height: lowest base height seen [m].
    """

    def __init__(self) -> None:
        self.slip = 0.0
        self.sink = 0.0
        self.min_base_height = np.inf


class FloatingPlant:
    """The scene in MuJoCo, stepped at a control period with Pinocchio's state.

    Args:
        scene: the floating scene (its MJCF holds the time step).
        control_dt: control period [s], a multiple of the scene's time step.

    Attributes:
        t: simulated time [s].
        q: (nq,) Pinocchio configuration (base pose, unit quaternion x, y, z, w; joints).
        v: (nv,) Pinocchio velocity (base twist in the base frame; joint rates).
        feet: the feet's motion so far (`FeetMotion`).

    ``step`` allocates nothing but the state copies; the MuJoCo model is compiled once.
    """

    def __init__(self, scene: FloatingScene, control_dt: float = 1e-3) -> None:
        self.scene = scene
        self.robot = scene.robot
        self.model = mujoco.MjModel.from_xml_string(scene.xml)
        self.data = mujoco.MjData(self.model)
        dt = check_positive(control_dt, "control_dt", "s")
        self.substeps = int(round(dt / self.model.opt.timestep))
        if self.substeps < 1 or abs(self.substeps * self.model.opt.timestep - dt) > 1e-12:
            raise InvalidArgument(
                f"control_dt = {dt!r} s must be a multiple of the scene's time step"
                f" {self.model.opt.timestep!r} s"
            )
        self.control_dt = dt
        self._base = self.model.body("base").id
        self._pin = self.robot.model.createData()
        self._ids = [self.robot.frame_id(f) for f in scene.feet]
        self.reset(scene.q0, np.zeros(self.robot.nv))

    def feet_positions(self, q: Vector) -> np.ndarray:
        """(F, 3) world positions of the contact frames at ``q`` [m]."""
        pin.framesForwardKinematics(self.robot.model, self._pin, q)
        return np.array([self._pin.oMf[i].translation for i in self._ids])

    def reset(self, q: Vector, v: Vector) -> None:
        """Start at ``q`` (nq,), ``v`` (nv,) at t = 0 (the feet measured from here)."""
        q = check_floating_q(q, self.robot.nq, "q", self.robot.name)
        v = check_vector(v, self.robot.nv, "v")
        mujoco.mj_resetData(self.model, self.data)
        self.data.qpos[:], self.data.qvel[:] = to_mujoco(q, v)
        mujoco.mj_forward(self.model, self.data)
        self.t = 0.0
        self.q, self.v = from_mujoco(self.data.qpos, self.data.qvel)
        self._p0 = self.feet_positions(self.q)
        self.feet = FeetMotion()
        self.feet.min_base_height = float(self.q[2])

    def step(self, tau: Vector, base_force: Vector | None = None) -> None:
        """Advance one control period.

        Args:
            tau: (nv,) generalised torques; ``tau[:6]`` (the base) is ignored, ``tau[6:]``
                drives the joints [N m or N].
            base_force: (3,) force on the base body, world axes [N] (None: none).
        """
        tau = check_vector(tau, self.robot.nv, "tau")
        self.data.ctrl[:] = tau[6:]
        self.data.xfrc_applied[self._base, :3] = 0.0 if base_force is None else base_force
        for _ in range(self.substeps):
            mujoco.mj_step(self.model, self.data)
        self.t += self.control_dt
        self.q, self.v = from_mujoco(self.data.qpos, self.data.qvel)
        moved = self.feet_positions(self.q) - self._p0
        self.feet.slip = max(self.feet.slip, float(np.abs(moved[:, :2]).max()))
        self.feet.sink = max(self.feet.sink, float(np.abs(moved[:, 2]).max()))
        self.feet.min_base_height = min(self.feet.min_base_height, float(self.q[2]))
