"""When a simulation run counts as diverged.

The state reached by a tick diverged when it is not finite, when a joint moves faster than
`SPEED_FACTOR` times its speed limit, or when MuJoCo reported an unstable simulation (bad
qpos/qvel/qacc; MuJoCo then resets its state). The run stops there with a status
``"diverged: ..."`` and keeps the ticks run so far.
"""

from __future__ import annotations

import mujoco
import numpy as np

from geosyn.core.types import Vector
from geosyn.robots.robot import Robot

#: A joint speed beyond this multiple of its limit counts as divergence.
SPEED_FACTOR = 3.0

_INSTABILITY_WARNINGS = (
    mujoco.mjtWarning.mjWARN_BADQPOS,
    mujoco.mjtWarning.mjWARN_BADQVEL,
    mujoco.mjtWarning.mjWARN_BADQACC,
)


class DivergenceCheck:
    """Decides whether the state reached by a tick diverged.

    The simulation tests finiteness and `speed_limit` itself at every tick (cheap) and
    calls `status` only when that test fails or MuJoCo may have reset its state.

    Args:
        robot: the robot (joint names and speed limits).
        data: the simulation's MuJoCo data (its warning counters are read).

    Attributes:
        speed_limit: (nv,) `SPEED_FACTOR` times the joint speed limits [rad/s]; ``inf``
            where the robot has no finite limit.
    """

    def __init__(self, robot: Robot, data: mujoco.MjData) -> None:
        self.robot = robot
        self.data = data
        v_max = np.asarray(robot.v_max, dtype=np.float64)
        self.speed_limit = np.where(np.isfinite(v_max) & (v_max > 0), SPEED_FACTOR * v_max, np.inf)
        self._warn0 = 0

    def warnings(self) -> int:
        """Number of instability warnings MuJoCo has counted in ``data``."""
        return sum(int(self.data.warning[w].number) for w in _INSTABILITY_WARNINGS)

    def start(self) -> None:
        """Start of a run (after ``mj_resetData``): later warnings count as divergence."""
        self._warn0 = self.warnings()

    def status(self, t: float, q: Vector, v: Vector) -> str | None:
        """The status message if the state diverged, else None.

        Args:
            t: time of the state [s].
            q: (nq,) joint positions [rad].
            v: (nv,) joint velocities [rad/s].
        """
        if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
            return f"diverged: non-finite state at t={t:.6g} s"
        if self.warnings() != self._warn0:
            return (
                "diverged: MuJoCo reported an unstable simulation (bad qpos/qvel/qacc) and"
                f" reset its state at t={t:.6g} s"
            )
        if np.any(np.abs(v) > self.speed_limit):
            j = int(np.argmax(np.abs(v) / self.speed_limit))
            return (
                f"diverged: joint {self.robot.joint_names[j]} speed {abs(v[j]):.4g} rad/s"
                f" exceeds {SPEED_FACTOR:g}x its limit {self.robot.v_max[j]:.4g} rad/s"
                f" at t={t:.6g} s"
            )
        return None


__all__ = ["SPEED_FACTOR", "DivergenceCheck"]
