"""geosyn's side of `benchmarks/planning.py` (and of `planning_anytime.py`,
`planning_startup.py`): the benchmark's Panda (`benchmark_robot`, the gripper as
geodex's), the scenes' obstacles as geosyn shapes (`to_geosyn`), the default `Planner`
a user gets (`GeosynSetup`) and one query within a budget (`solve_geosyn`)."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import NamedTuple

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import planning_scenes as ps  # noqa: E402

from geosyn import world as shapes  # noqa: E402
from geosyn.metrics import KineticEnergyMetric  # noqa: E402
from geosyn.robots import CollisionSphere, Robot, load_robot  # noqa: E402


class PlannerRun(NamedTuple):
    """One planner on one scene.

    Attributes:
        solved: the planner reports a path from start to goal.
        wall_time: wall-clock time of the query [s] (geosyn: without the first-use build).
        path: (T, 7) joint path [rad], None when not solved.
        message: how it was solved, or why not.
        extra: planner-specific numbers (geodex's own cost, geosyn's residual, ...).
    """

    solved: bool
    wall_time: float
    path: np.ndarray | None
    message: str
    extra: dict


def to_geosyn(ob: ps.Obstacle) -> object:
    """The geosyn shape (`geosyn.world`) of a scene obstacle.

    A `Cylinder` becomes the `Capsule` on its axis with its radius and length: a superset
    of the cylinder (hemispherical caps of one radius at both ends) until geosyn has a
    cylinder shape.
    """
    if isinstance(ob, ps.Box):
        return shapes.Box(ob.center, ob.half_extents, ps.rpy_matrix(ob.rpy))
    if isinstance(ob, ps.Sphere):
        return shapes.Sphere(ob.center, ob.radius)
    if isinstance(ob, ps.Capsule):
        return shapes.Capsule(ob.p0, ob.p1, ob.radius)
    if isinstance(ob, ps.Cylinder):
        axis = ps.rpy_matrix(ob.rpy)[:, 2] * ob.half_length
        c = np.asarray(ob.center)
        return shapes.Capsule(c - axis, c + axis, ob.radius)
    if isinstance(ob, ps.HalfSpace):
        return shapes.HalfSpace(ob.normal, ob.offset)
    raise TypeError(f"unknown obstacle type {type(ob).__name__}")


CAPACITY = max(len(s.obstacles) for s in ps.SCENES)
"""Obstacle slots of the shaped metric: one build serves every scene (parameter writes)."""


class GeosynSetup:
    """The geosyn `Planner` a user gets: ``Planner(KineticEnergyMetric(robot))`` with
    every default (8 obstacle slots; spheres fitted to the Panda URDF's collision
    meshes, cached on disk; per-node functions cached on disk; no C compile; every plan
    verified against the URDF meshes by coal). ``build_time`` [s] is the planner's
    creation; ``spheres`` / ``margin`` / ``coarse_nodes`` / ``alternatives`` override the
    defaults only when given (the tuned variants of earlier rounds)."""

    def __init__(
        self,
        robot: Robot,
        spheres: tuple[CollisionSphere, ...] | None = None,
        *,
        margin: float | None = None,
        alternatives: int | None = None,
        coarse_nodes: int | None = None,
    ) -> None:
        from geosyn.metrics.planning import Planner

        options: dict = {"spheres": spheres, "margin": margin, "alternatives": alternatives,
                         "coarse_nodes": coarse_nodes}  # fmt: skip
        t0 = time.perf_counter()
        self.robot = robot
        self.metric = KineticEnergyMetric(robot)
        self.planner = Planner(self.metric, **{k: v for k, v in options.items() if v is not None})
        self.build_time = time.perf_counter() - t0


# =====================================================================================
# solve_geosyn: THE geosyn SIDE OF THE BENCHMARK (issue 11, deliver 1): collocation of
# the kinetic energy with clearance constraints, RRT-Connect seed when it fails.
# =====================================================================================
def solve_geosyn(scene: ps.Scene, setup: GeosynSetup, budget: float) -> PlannerRun:
    """Solve ``scene`` with geosyn's `Planner` within ``budget`` seconds of wall time.

    The planner stops by itself at the budget (its IPOPT iteration callback and the
    sampler check the clock), so no child process is needed; a failure is reported with
    the planner's error message (which says why and what was tried).
    """
    from geosyn.metrics.planning import PlanningError

    t0 = time.perf_counter()
    try:
        plan = setup.planner.plan(
            np.array(scene.q_start), np.array(scene.q_goal),
            [to_geosyn(ob) for ob in scene.obstacles], budget=budget,
        )  # fmt: skip
    except PlanningError as err:
        return PlannerRun(False, time.perf_counter() - t0, None, f"{type(err).__name__}: {err}", {})
    wall = time.perf_counter() - t0
    res = plan.result
    return PlannerRun(
        True,
        wall,
        plan.q,
        f"{res.kind} (seed: {plan.seed}; {res.iterations} IPOPT iterations, {res.status})",
        {
            "kind": res.kind,
            "seed": plan.seed,
            "collocation_energy": res.energy,
            "geodesic_residual": res.geodesic_residual,
            "active_constraints": res.active,
            "check_clearance": plan.check_clearance,
            "exact_clearance": plan.exact_clearance,
            "first_feasible_time": plan.first_feasible_time,
            "attempts": list(plan.attempts),
        },
    )


GRIPPERS: dict[str, dict[str, float]] = {
    "open": {"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04},
    "closed": {},
}
"""Finger positions [m] at which the benchmark's Panda is locked (``--gripper``).
geodex's (VAMP's) Panda has its gripper open: its finger spheres sit 0.073-0.08 m off
the hand's axis, where geosyn's ``load_robot("panda")`` (fingers locked closed) has no
geometry, so a path clear of the closed gripper's meshes by centimetres "collides" for
geodex's checker (measured: the deepest of them, 5-15 mm into a box, were all finger
spheres). Both planners plan for the same robot by default: "open"."""


def benchmark_robot(gripper: str = "open") -> Robot:
    """The benchmark's Panda: ``load_robot("panda", armature=0.0)`` with its fingers
    locked at `GRIPPERS` ``[gripper]``."""
    lock = GRIPPERS[gripper]
    return load_robot("panda", armature=0.0, **({"lock_q": lock} if lock else {}))
