"""The exact clearance of a run: the robot file's own collision geometry against the
scene's obstacles, along the motion the simulation logged.

The clearance a run logs at each tick (``SimResult.clearance``) is that of the robot's
collision spheres, an approximation that may miss part of the robot (on the Panda, the
capsule spheres miss 1-2 cm of its collision meshes). After a run, `RunClearance`
measures the same motion on the file's collision objects (URDF meshes and primitives,
MJCF geoms; `geosyn.world.exact_clearance.ExactClearance`, coal's signed distances) at
the logged configurations, taken so that every logged configuration lies within
``resolution`` [rad] (joint-space max-norm) of a checked one. The result says how it was
measured, or why it was not (a robot built in code has no file geometry): it is never
left out silently. Payloads are in neither clearance.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from geosyn.core.validation import check_positive
from geosyn.robots.errors import RobotFileError
from geosyn.robots.robot import Robot
from geosyn.sim.blocks import row_blocks
from geosyn.world.exact_clearance import ExactClearance
from geosyn.world.shapes import Shape

__all__ = ["MESH_NEAR", "MESH_RESOLUTION", "MeshClearance", "RunClearance", "checked_ticks"]

MESH_RESOLUTION = 0.005
"""Default joint-space step [rad] (max-norm) between the checked configurations of a
run, the planner's own ``exact_resolution``."""

MESH_NEAR = 1.0
"""Distance [m] up to which the clearance is exact; a run that keeps every collision
object farther from every obstacle reports this value (the clearance is at least it)."""


class MeshClearance(NamedTuple):
    """The smallest exact clearance of a run.

    Attributes:
        clearance: smallest signed distance [m] between a collision object of the robot's
            file and an obstacle over the checked ticks (negative: penetration; at most
            `MESH_NEAR`); NaN when not measured.
        time: time of that tick [s] (NaN when not measured).
        link: the robot link of the closest pair ("" if none).
        obstacle: index of the obstacle of the closest pair (-1 if none).
        checked: number of ticks checked.
        note: how it was measured, or why not.
    """

    clearance: float
    time: float
    link: str
    obstacle: int
    checked: int
    note: str


def checked_ticks(q: np.ndarray, resolution: float) -> np.ndarray:
    """(K,) indices of the rows of ``q`` (T, n) [rad] to check: the first, the last, and
    each row where the joint-space path length (sum of max-norm steps) since the first
    passes another multiple of ``resolution`` [rad]. Every row then lies within
    ``resolution`` (max-norm) of the checked row before it. Read a block of rows at a
    time (a spooled log's pages are released after each)."""
    n = len(q)
    path = np.zeros(n)  # joint-space path length at each row [rad]
    prev = None
    for rows in row_blocks(n, q):
        block = np.asarray(q[rows], dtype=np.float64)
        ahead = block if prev is None else np.vstack([prev, block])
        step = np.abs(np.diff(ahead, axis=0)).max(axis=1) if len(ahead) > 1 else np.zeros(0)
        # a step to or from a diverged (NaN) row counts as a full one: the next is checked
        path[rows.stop - len(step) : rows.stop] = np.where(np.isfinite(step), step, resolution)
        prev = block[-1:]
    if n == 0:
        return np.zeros(0, dtype=np.int64)
    passes = np.flatnonzero(np.diff(np.floor(np.cumsum(path) / resolution)) > 0) + 1
    return np.unique(np.concatenate([[0], passes, [n - 1]])).astype(np.int64)


class RunClearance:
    """Measures runs on the robot file's collision geometry (see the module doc).

    The coal shapes are built on the first `measure` (then kept for the next runs).

    Args:
        robot: the simulated robot.
        obstacles: the scene's obstacles (`geosyn.world` shapes), which do not move; none:
            every run's clearance is ``inf``.
        resolution: joint-space step [rad] between checked configurations, > 0; None:
            runs are not measured (NaN, and the note says so).

    Raises:
        InvalidArgument: ``resolution`` is neither None nor a finite number > 0.
    """

    def __init__(
        self,
        robot: Robot,
        obstacles: Sequence[Shape],
        resolution: float | None = MESH_RESOLUTION,
    ) -> None:
        self.robot = robot
        self.obstacles = tuple(obstacles)
        self.resolution = (
            None if resolution is None else check_positive(resolution, "mesh_resolution", "rad")
        )
        self._exact: ExactClearance | None = None
        self._why = "not measured: mesh_resolution=None" if resolution is None else ""

    def _clearance(self) -> ExactClearance | None:
        if self._exact is None and not self._why:
            try:
                self._exact = ExactClearance(self.robot, near=MESH_NEAR)
            except RobotFileError as err:
                self._why = f"not measured: {err}"
            else:
                self._exact.set_obstacles(self.obstacles)
        return self._exact

    def measure(self, t: np.ndarray, q: np.ndarray) -> MeshClearance:
        """The smallest exact clearance of a run's logged motion.

        Args:
            t: (T,) tick times [s].
            q: (T, nq) logged joint positions [rad] (a spooled log's map is fine).

        Returns:
            The smallest clearance, ``inf`` without obstacles, NaN when not measured.
        """
        if not self.obstacles:
            return MeshClearance(math.inf, math.nan, "", -1, 0, "no obstacles")
        exact = self._clearance()
        if exact is None or self.resolution is None:
            return MeshClearance(math.nan, math.nan, "", -1, 0, self._why)
        ticks = checked_ticks(q, self.resolution)
        best, at, link, which = math.inf, math.nan, "", -1
        for k in ticks:
            row = np.asarray(q[k], dtype=np.float64)
            if not np.all(np.isfinite(row)):
                continue  # a diverged tick: the run's status says so
            c, ln, o = exact.clearance(row)
            if c < best:
                best, at, link, which = c, float(t[k]), ln, o
        if not math.isfinite(best):
            return MeshClearance(math.nan, math.nan, "", -1, 0, "not measured: no finite tick")
        note = (
            f"{len(ticks)} ticks <= {self.resolution:g} rad apart checked on the file's "
            f"{len(exact.objects)} collision objects (coal; exact to {MESH_NEAR:g} m)"
        )
        return MeshClearance(best, at, link, which, len(ticks), note)
