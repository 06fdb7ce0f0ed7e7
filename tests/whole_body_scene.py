"""Whole-body closed loops of floating-base robots standing in MuJoCo, for the tests and
benchmarks (tests/test_whole_body*.py, benchmarks/floating_whole_body.py).

The scene (geosyn's twin under a free joint, floor, contact spheres, elliptic cones) is
`geosyn.sim.floating_scene`; the loop steps `geosyn.sim.floating_plant.FloatingPlant`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from geosyn.sim.floating_scene import SPHERE, build_floating_scene
from geosyn.sim.floating_scene import FloatingScene as Scene

__all__ = ["SPHERE", "Scene", "StandingRun", "build_scene", "run_standing", "standing_synergy"]

build_scene = build_floating_scene


@dataclass(frozen=True)
class StandingRun:
    """What a closed-loop standing run measured."""

    rms: float  # RMS over the run of |q - q_ref| on the group (all coordinates) [m, rad]
    rms_base_legs: float  # the same over the base twist and the first 12 joints
    max_error: float  # largest |q - q_ref| [m, rad]
    slip: float  # largest horizontal displacement of a contact frame [m]
    lift: float  # largest vertical displacement of a contact frame [m]
    min_base_height: float  # lowest base height over the run [m]
    qp_failures: int  # ticks whose QP proxsuite did not solve
    cpu: float  # CPU time of the loop [s]


def run_standing(
    scene: Scene,
    controller: object,
    reference: object,
    duration: float,
    push: tuple[float, float, float] = (0.0, 0.0, 0.0),
    push_window: tuple[float, float] = (0.8, 1.0),
    control_dt: float = 1e-3,
) -> StandingRun:
    """Run ``controller`` on the scene in MuJoCo (base free) and measure it.

    The controller is called at ``control_dt`` with Pinocchio's ``(q, v)``
    (`geosyn.robots.floating.from_mujoco`); its torques (nv,) drive the joint motors
    (entries 6:). ``push`` [N] acts on the base body, world axes, during ``push_window``.
    """
    import time

    from geosyn.sim.floating_plant import FloatingPlant

    robot = scene.robot
    plant = FloatingPlant(scene, control_dt)
    controller.reset(scene.q0, np.zeros(robot.nv))  # type: ignore[attr-defined]
    errors, legs, fails = [], [], 0
    start = time.process_time()
    for k in range(int(round(duration / control_dt))):
        t = k * control_dt
        tau = controller.compute(t, plant.q, plant.v)  # type: ignore[attr-defined]
        fails += bool(controller.diagnostics.fallback_used)  # type: ignore[attr-defined]
        plant.step(tau, np.array(push) if push_window[0] <= t < push_window[1] else None)
        e = pin.difference(robot.model, plant.q, reference.sample(t + control_dt).q)  # type: ignore[attr-defined]
        errors.append(float(np.linalg.norm(e)))
        legs.append(float(np.linalg.norm(e[:18])))
    err = np.array(errors)
    return StandingRun(
        rms=float(np.sqrt(np.mean(err**2))),
        rms_base_legs=float(np.sqrt(np.mean(np.square(legs)))),
        max_error=float(err.max()),
        slip=plant.feet.slip,
        lift=plant.feet.sink,
        min_base_height=plant.feet.min_base_height,
        qp_failures=fails,
        cpu=time.process_time() - start,
    )


def standing_synergy(scene: Scene, duration: float = 1.5, t0: float = 0.2):  # type: ignore[no-untyped-def]
    """The stance, synergy and reference of the scene's built-in motion.

    TALOS: lower the base by 6 cm and shift it 6 cm sideways while the right arm lifts
    (shoulder and elbow at -0.8 rad), both soles held. Quadruped: lower the base by 4 cm,
    shift it 5 cm sideways and roll it by 0.1 rad, four point feet held. The wish is
    projected onto the stance (`StanceSynergy`).
    """
    from geosyn.controllers.whole_body_reference import StanceSynergyReference
    from geosyn.metrics import FloatingKineticEnergyMetric
    from geosyn.metrics.stance import Stance
    from geosyn.metrics.stance_synergy import StanceSynergy

    robot = scene.robot
    metric = FloatingKineticEnergyMetric(robot)
    direction = np.zeros(robot.nv)
    if scene.corners.shape[0] > 1:  # a humanoid on its soles
        stance = Stance(metric, scene.feet, scene.q0)
        direction[1], direction[2] = 0.06, -0.06
        for joint in ("arm_right_2_joint", "arm_right_4_joint"):
            direction[robot.model.joints[robot.joint_id(joint)].idx_v] = -0.8
    else:
        stance = Stance(metric, scene.feet, scene.q0, points=True)
        direction[1], direction[2], direction[3] = 0.05, -0.04, 0.1
    synergy = StanceSynergy(stance, scene.q0, direction, steps=50)
    return stance, synergy, StanceSynergyReference(synergy, duration=duration, t0=t0)
