"""Closed-loop tracking of a floating-base robot standing on the ground (``kind:
tracking`` with a floating robot): the stance, its synergy reference, whole-body
controllers, and MuJoCo with the base free.

The ``stance`` section is built once (`geosyn.metrics.stance.Stance` at the robot's
standing start, `geosyn.sim.floating_scene`) and handed to the ``stance_synergy``
reference and to every ``whole_body`` controller; the plant
(`geosyn.sim.floating_plant.FloatingPlant`) puts a contact sphere at each stance point.
Each run is logged like a fixed-base run (``t``, ``q``, ``v``, ``q_ref``,
``tracking_error``, ``tau_applied``, ``fallback_used``, ``status``, ``wall_time``), the
error taken on the group (``pinocchio.difference(q, q_ref)``, (nv,) [m, rad]), plus the
feet's ``feet_slip`` and ``feet_sink`` [m] and the ``min_base_height`` [m]. A push acts
on the base body (its ``body`` must be ``base`` or the robot's root link); a run whose
base drops below `FALL_FRACTION` of its start height ends with status ``fell``.
`floating_videos` films each run in the same standing scene.
"""

from __future__ import annotations

import difflib
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from geosyn.controllers.whole_body import WholeBodyController
from geosyn.controllers.whole_body_reference import StanceSynergyReference
from geosyn.core.errors import GeosynError
from geosyn.experiments import schema as S
from geosyn.experiments.errors import ProcedureFailed
from geosyn.metrics import FloatingKineticEnergyMetric
from geosyn.metrics.stance import Stance
from geosyn.metrics.stance_synergy import StanceSynergy
from geosyn.robots import Robot
from geosyn.sim.floating_plant import FloatingPlant
from geosyn.sim.floating_scene import STANDING, FloatingScene, build_floating_scene
from geosyn.sim.floating_video import render_floating_video

__all__ = [
    "FALL_FRACTION",
    "FLOATING_CONTROLLERS",
    "FloatingSetup",
    "build_floating_setup",
    "floating_videos",
    "floating_problems",
    "run_floating",
    "track_floating",
]

_BODY = pin.FrameType.BODY

FALL_FRACTION = 0.5
"""A run falls when its base height drops below this fraction of the start height."""


class FloatingSetup:
    """What a floating run builds once: the MuJoCo scene, the stance, the reference.

    Attributes:
        scene: the standing scene (`FloatingScene`; its ``q0`` is the start).
        stance: the stance at the start (`Stance`).
        reference: the ``stance_synergy`` reference.
    """

    def __init__(self, scene: FloatingScene, stance: Stance, reference: StanceSynergyReference):
        self.scene = scene
        self.stance = stance
        self.reference = reference


def floating_problems(cfg: S.ExperimentConfig, robot: Robot) -> list[tuple[str, str]]:
    """Config problems of a floating robot's run, or of floating-only sections on a fixed
    robot, as ``(field path, reason)`` pairs."""
    errors: list[tuple[str, str]] = []
    wb = [i for i, c in enumerate(cfg.controllers) if c.type == "whole_body"]
    ref_type = None if cfg.reference is None else cfg.reference.type
    if not robot.floating:
        if cfg.stance is not None:
            errors.append(("stance", f"robot {robot.name!r} has a fixed base: nothing stands"))
        for i in wb:
            errors.append((f"controllers.{i}", "whole_body needs a floating-base robot"))
        if ref_type == "stance_synergy":
            errors.append(("reference", "stance_synergy needs a floating-base robot"))
        return errors
    if robot.name not in STANDING:
        reason = f"{robot.name!r} has no standing pose; robots that stand: {', '.join(STANDING)}"
        errors.append(("robot.name", reason + " (or fixed_base: true)"))
    if cfg.stance is None:
        errors.append(("stance", f"floating-base robot {robot.name!r} needs a stance section"))
    else:
        frames = {str(f.name) for f in robot.model.frames}
        for i, name in enumerate(cfg.stance.frames):
            if name not in frames:
                close = difflib.get_close_matches(name, sorted(frames), n=3)
                hint = f"; closest: {', '.join(close)}" if close else ""
                reason = f"{name!r} is not a frame of {robot.name!r}{hint}"
                errors.append((f"stance.frames.{i}", reason))
    ref = cfg.reference
    if isinstance(ref, S.StanceSynergyReferenceConfig):
        joints = list(robot.joint_names)
        for name in ref.direction.joints:
            if name not in joints:
                reason = f"{name!r} is not a joint of {robot.name!r}; joints: {', '.join(joints)}"
                errors.append(("reference.direction.joints", reason))
    if ref_type != "stance_synergy":
        errors.append(("reference", "a floating-base robot tracks a stance_synergy reference"))
    for i, c in enumerate(cfg.controllers):
        if c.type != "whole_body":
            errors.append(
                (f"controllers.{i}", f"{c.type} needs a fixed-base robot; use whole_body")
            )
    root = [str(f.name) for f in robot.model.frames if f.parentJoint == 1 and f.type == _BODY]
    bases = ("base", *root[:1])  # the root link: the free flyer's body
    for i, d in enumerate(cfg.disturbances):
        if d.type != "push":
            errors.append((f"disturbances.{i}", f"{d.type} is not simulated on a floating robot"))
        elif d.body not in bases:
            reason = f"a push acts on the base: body {' or '.join(map(repr, bases))}"
            errors.append((f"disturbances.{i}.body", reason))
        elif d.point is not None:
            errors.append((f"disturbances.{i}.point", "a push on the base acts at its origin"))
    if cfg.robot.plant != "model":
        errors.append(("robot.plant", "a floating robot is simulated on geosyn's model"))
    if cfg.scene.has_obstacles or cfg.scene.payloads or cfg.metric.terms:
        errors.append(
            ("scene", "a floating robot stands on a flat floor: no obstacles, payloads or terms")
        )
    return errors


def _direction(ref: S.StanceSynergyReferenceConfig, robot: Robot) -> np.ndarray:
    direction = np.zeros(robot.nv)
    direction[:6] = ref.direction.base
    for name, rate in ref.direction.joints.items():
        joint = robot.model.joints[robot.joint_id(name)]  # UnknownJoint lists them
        direction[joint.idx_v] = rate
    return direction


def build_floating_setup(cfg: S.ExperimentConfig, robot: Robot) -> FloatingSetup:
    """The scene, stance and reference of a floating run (built once per run).

    Cost: one MJCF (no compile), the stance's SVD, the synergy's integration.

    Raises:
        ProcedureFailed: the config lacks a stance or a stance_synergy reference.
        SimError: the robot has no standing pose (`geosyn.sim.floating_scene.STANDING`).
    """
    st, ref = cfg.stance, cfg.reference
    if st is None or not isinstance(ref, S.StanceSynergyReferenceConfig):
        raise ProcedureFailed(
            f"{cfg.name}: a floating robot needs stance and a stance_synergy reference"
        )
    scene = build_floating_scene(
        robot.name,
        timestep=cfg.simulation.control_dt / cfg.simulation.substeps,
        feet=st.frames,
        points=np.array(st.points),
    )
    metric = FloatingKineticEnergyMetric(scene.robot)
    stance = Stance(metric, st.frames, scene.q0, points=st.point_feet)
    synergy = StanceSynergy(stance, scene.q0, _direction(ref, scene.robot), steps=ref.steps)
    return FloatingSetup(scene, stance, StanceSynergyReference(synergy, ref.duration, ref.t0))


FLOATING_CONTROLLERS: dict[
    str, Callable[[Any, S.StanceConfig, FloatingSetup], WholeBodyController]
] = {
    "whole_body": lambda c, st, setup: WholeBodyController(
        setup.scene.robot,
        st.frames,
        np.array(st.points),
        setup.reference,
        mu=st.mu,
        f_min=st.f_min,
        **c.kwargs(),
    ),
}
"""Registry of floating-base controller builders ``(section, stance, setup) -> controller``."""


def run_floating(
    setup: FloatingSetup,
    controller: WholeBodyController,
    duration: float,
    control_dt: float,
    pushes: list[tuple[float, float, np.ndarray]],
) -> dict[str, np.ndarray]:
    """One closed-loop run in MuJoCo with the base free.

    Args:
        setup: the run's scene, stance and reference.
        controller: the whole-body controller (its reference set).
        duration: simulated time [s].
        control_dt: control period [s].
        pushes: ``(start [s], stop [s], force (3,) [N])`` on the base body, world axes.

    Returns:
        The per-tick log by field name (see the module doc); rows after a fall or a
        controller failure are NaN.
    """
    scene, ref = setup.scene, setup.reference
    robot = scene.robot
    plant = FloatingPlant(scene, control_dt)
    n = int(round(duration / control_dt))
    log = {
        "t": np.arange(n) * control_dt,
        "q": np.full((n, robot.nq), np.nan),
        "v": np.full((n, robot.nv), np.nan),
        "q_ref": np.full((n, robot.nq), np.nan),
        "tracking_error": np.full((n, robot.nv), np.nan),
        "tau_applied": np.full((n, robot.nv), np.nan),
        "fallback_used": np.zeros(n, dtype=bool),
    }
    controller.reset(scene.q0, np.zeros(robot.nv))
    status, z0 = "ok", float(scene.q0[2])
    wall = time.perf_counter()
    for k in range(n):
        t = k * control_dt
        q, v = plant.q, plant.v
        q_ref = ref.sample(t).q
        log["q"][k], log["v"][k], log["q_ref"][k] = q, v, q_ref
        log["tracking_error"][k] = pin.difference(robot.model, q, q_ref)
        try:
            tau = controller.compute(t, q, v)
        except GeosynError as err:
            status = f"controller failed at t = {t:.3f} s: {err}"
            break
        log["tau_applied"][k] = tau
        log["fallback_used"][k] = controller.diagnostics.fallback_used
        force = sum((f for a, b, f in pushes if a <= t < b), np.zeros(3))
        plant.step(tau, force)
        if plant.q[2] < FALL_FRACTION * z0 or not np.all(np.isfinite(plant.q)):
            status = f"fell at t = {t + control_dt:.3f} s (base height {plant.q[2]:.3f} m)"
            break
    log["status"] = np.array(status)
    log["wall_time"] = np.array(time.perf_counter() - wall)
    log["feet_slip"] = np.array(plant.feet.slip)
    log["feet_sink"] = np.array(plant.feet.sink)
    log["min_base_height"] = np.array(plant.feet.min_base_height)
    return log


def track_floating(
    cfg: S.ExperimentConfig, robot: Robot, advance: Callable[[], None]
) -> dict[str, np.ndarray]:
    """Every configured controller on the floating robot: ``{label}__{field}`` arrays
    (`run_floating`'s fields), plus the reference's ``reference__t``/``reference__q``."""
    setup = build_floating_setup(cfg, robot)
    st = cfg.stance
    if st is None:  # build_floating_setup refused it already
        raise ProcedureFailed(f"{cfg.name}: a floating robot needs a stance section")
    sim = cfg.simulation
    pushes = [
        (d.start, d.start + d.duration, np.array(d.force))
        for d in cfg.disturbances
        if isinstance(d, S.PushConfig)  # floating_problems refused the others
    ]
    t = np.arange(int(round(sim.duration / sim.control_dt))) * sim.control_dt
    out: dict[str, np.ndarray] = {
        "reference__t": t,
        "reference__q": np.array([setup.reference.sample(s).q for s in t]),
        "reference__end": np.array(setup.reference.t0 + setup.reference.duration),
    }
    for label, c in zip(cfg.controller_labels(), cfg.controllers, strict=True):
        ctrl = FLOATING_CONTROLLERS[c.type](c, st, setup)
        run = run_floating(setup, ctrl, sim.duration, sim.control_dt, pushes)
        out |= {f"{label}__{k}": v for k, v in run.items()}
        advance()
    return out


def floating_videos(
    cfg: S.ExperimentConfig, robot: Robot, results: dict[str, np.ndarray], out_dir: Path
) -> list[str]:
    """Write ``video_{label}.{gif|mp4}`` of every controller's run in the standing scene
    (`geosyn.sim.floating_video`), sized and timed by ``outputs``; returns the file names.

    Raises:
        RenderError: no OpenGL context, or the video could not be written.
    """
    st = cfg.stance
    if st is None:
        raise ProcedureFailed(f"{cfg.name}: a floating robot needs a stance section")
    o = cfg.outputs
    scene = build_floating_scene(robot.name, feet=st.frames, points=np.array(st.points))
    files = []
    for label in cfg.controller_labels():
        name = f"video_{label}.{o.video_format}"
        t, q = results[f"{label}__t"], results[f"{label}__q"]
        size = (min(o.width, 1280), min(o.height, 960))
        render_floating_video(scene, t, q, out_dir / name, o.fps, *size, label=label)
        files.append(name)
    return files
